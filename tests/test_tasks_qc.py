"""`jarvis qc`, the quality gate: on real devices a sound task passes; a task already solved by its set-up, one
with an evaluator that holds before anything is done (while another fails), and one whose oracle does not solve
it are violations with their reasons, and the exit status says so."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.generators import generate
from jarvis_pytest.results.model import EvaluatorVerdict, GuiCheck, SubtaskVerdict, TaskResult
from jarvis_pytest.tasks.qc import gui_table, qc_row, render_table

REPO = Path(__file__).resolve().parents[1]
LIBRARY = REPO / "tests" / "data" / "qc_library"
GUI_LIBRARY = REPO / "tests" / "data" / "qc_gui_library"


def verdict(passed: bool, reason: str = "r") -> SubtaskVerdict:
    return SubtaskVerdict(index=0, template="t", platform="ubuntu", passed=passed,
                          evaluators=[EvaluatorVerdict(func="f", passed=passed, reason=reason)])


def result(status: str, before: bool, after: bool) -> TaskResult:
    return TaskResult(task_id="ubuntu-x[seed0]", category="atomic", platforms=["ubuntu"], instruction="i",
                      status=status, qc_initial=[verdict(before, "already there")],
                      subtasks=[verdict(after, "expected a, found b")])


def test_rows_name_the_violation():
    assert qc_row(result("passed", False, True))["gate"] == "ok"
    solved = qc_row(result("failed", True, True))
    assert (solved["fresh"], solved["gate"]) == ("PASS", "VIOLATED") and "passes untouched" in solved["reason"]
    broken = qc_row(result("failed", False, False))
    assert (broken["oracle"], broken["gate"]) == ("FAIL", "VIOLATED") and "expected a, found b" in broken["reason"]
    assert "1/3 instances pass" in render_table([qc_row(result("passed", False, True)), solved, broken])


def test_one_evaluator_holding_on_the_fresh_device_is_a_violation():
    fresh = SubtaskVerdict(index=0, template="t", platform="ubuntu", passed=False, evaluators=[
        EvaluatorVerdict(func="file_text_equals", passed=False, reason="expected hello, found no file"),
        EvaluatorVerdict(func="file_exists", passed=True, reason="expected a file at x, found it")])
    res = TaskResult(task_id="ubuntu-x[seed0]", category="atomic", platforms=["ubuntu"], instruction="i",
                     status="failed", qc_initial=[fresh], subtasks=[verdict(True)])
    row = qc_row(res)
    assert (row["fresh"], row["gate"]) == ("PASS", "VIOLATED")
    assert row["reason"].startswith("passes untouched: file_exists: expected a file at x")


def test_generators_make_files_and_reject_bad_input():
    assert generate("text_lines", {"lines": ["a", "b"]}) == b"a\nb\n"
    with pytest.raises(ConfigError, match="unknown file generator 'nope'"):
        generate("nope", {})
    with pytest.raises(ConfigError, match="text_lines"):
        generate("text_lines", {"rows": []})


@pytest.mark.containers
def test_qc_on_real_devices_finds_both_kinds_of_violation(device_images, tmp_path):
    proc = subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "qc", "--library", str(LIBRARY),
                           "--results-dir", str(tmp_path / "qc"),
                           "--instances", "2", "-n", "1", "--platform", "ubuntu"],
                          cwd=REPO, capture_output=True, text=True, timeout=600)
    out = proc.stdout
    assert proc.returncode == 1, out[-3000:] + proc.stderr[-2000:]
    rows = {line.split("|")[1].strip(): line for line in out.splitlines() if line.startswith("| ubuntu-qc-")}
    assert len(rows) == 10, out[-3000:]
    assert all("| fail | 2/2 fail | pass | pass | ok |" in rows[f"ubuntu-qc-good[seed{i}]"] for i in (0, 1))
    assert "| PASS | " in rows["ubuntu-qc-already_solved[seed0]"] and "passes untouched" in rows["ubuntu-qc-already_solved[seed0]"]
    assert "| FAIL | none yet | VIOLATED | oracle fails: file_text_equals" in rows["ubuntu-qc-oracle_fails[seed0]"]
    assert "| PASS | " in rows["ubuntu-qc-guard_holds[seed1]"] and "passes untouched: file_exists" in rows["ubuntu-qc-guard_holds[seed1]"]
    # a negative the evaluators accept is a violation, named with its note
    weak = rows["ubuntu-qc-negative_passes[seed0]"]
    assert "| fail | 2/2 PASS | pass | none yet | VIOLATED | negative 0 passes (artefact: an empty file where the " \
        "copy belongs)" in weak
    assert "2/10 instances pass the quality gate" in out
    assert (tmp_path / "qc" / "qc.md").read_text().count("VIOLATED") == 8


def gui_result(task: str, app: str, state: str, reason: str = "") -> TaskResult:
    res = result("passed" if state != "failed" else "failed", False, True)
    return res.model_copy(update={"task_id": task, "qc_gui": [
        GuiCheck(subtask=0, template=task.split("[")[0], app=app, backend="docker", state=state, reason=reason)]})


def test_the_gui_column_and_the_counts_per_application():
    """The fourth check: a failing GUI solution is a violation with its reason, and so is none on Ubuntu and
    Windows, whose every template has one; infeasible (with its reason) is not, nor none on Android."""
    rows = {s: qc_row(gui_result(f"ubuntu-{s}[seed0]", "Editor", s, "why")) for s in ("passed", "failed",
                                                                                      "infeasible", "none")}
    assert [rows[s]["gui"] for s in ("passed", "failed", "infeasible", "none")] == \
        ["pass", "FAIL", "infeasible", "none yet"]
    assert rows["failed"]["gate"] == "VIOLATED" and rows["failed"]["reason"] == "GUI solution fails: why"
    assert all(rows[s]["gate"] == "ok" for s in ("passed", "infeasible"))
    assert rows["none"]["gate"] == "VIOLATED" and rows["none"]["reason"].startswith(
        "no GUI solution: ubuntu-none needs a `gui_solution`, or `gui_infeasible` for docker")
    android = gui_result("android-none[seed0]", "Files", "none").model_copy(update={"platforms": ["android"]})
    assert (qc_row(android)["gui"], qc_row(android)["gate"]) == ("none yet", "ok")
    table = gui_table([gui_result("ubuntu-a[seed0]", "Editor", "passed"), gui_result("ubuntu-a[seed1]", "Editor",
                       "passed"), gui_result("ubuntu-b[seed0]", "Editor", "passed"),
                       gui_result("ubuntu-b[seed1]", "Editor", "failed", "lost"),  # one failing instance: failing
                       gui_result("ubuntu-c[seed0]", "Editor", "infeasible", "no dialog"),
                       gui_result("ubuntu-d[seed0]", "Viewer", "none")])
    assert "| ubuntu (docker) | Editor | 1 | 1 | 1 | 0 |" in table, table
    assert "| ubuntu (docker) | Viewer | 0 | 0 | 0 | 1 |" in table, table
    assert "- infeasible: ubuntu-c on ubuntu (docker): no dialog" in table, table
    assert gui_table([result("passed", False, True)]) == ""


@pytest.mark.containers
def test_qc_gui_check_on_real_devices(device_images, tmp_path):
    """A GUI solution that solves the task passes the fourth check; one whose target never shows is a violation
    naming the step; `gui_infeasible` shows its reason; an Ubuntu template with neither is "none yet", a violation."""
    proc = subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "qc", "--library", str(GUI_LIBRARY),
                           "--results-dir", str(tmp_path / "qc"), "--instances", "1", "-n", "1",
                           "--platform", "ubuntu"], cwd=REPO, capture_output=True, text=True, timeout=600)
    out = proc.stdout
    assert proc.returncode == 1, out[-3000:] + proc.stderr[-2000:]
    rows = {line.split("|")[1].strip(): line for line in out.splitlines() if line.startswith("| ubuntu-qcgui-")}
    assert "| fail | 2/2 fail | pass | pass | ok |" in rows["ubuntu-qcgui-gui_proven[seed0]"], out[-3000:]
    missing = rows["ubuntu-qcgui-gui_target_missing[seed0]"]
    assert "| pass | FAIL | VIOLATED | GUI solution fails: the GUI solution ended with fail: gui_solution[0]: " \
           "a control (role='push button' name='Type It For Me')" in missing and "within 2 s" in missing, missing
    assert "| pass | infeasible | ok |" in rows["ubuntu-qcgui-gui_infeasible[seed0]"], out[-3000:]
    assert "| pass | none yet | VIOLATED | no GUI solution: ubuntu-qcgui-gui_none needs a `gui_solution`" in \
        rows["ubuntu-qcgui-gui_none[seed0]"], out[-3000:]
    assert "2/4 instances pass the quality gate" in out
    assert "| ubuntu (docker) | Text Editor | 1 | 1 | 1 | 1 |" in out, out[-3000:]
    assert "- infeasible: ubuntu-qcgui-gui_infeasible on ubuntu (docker): this editor has no keyboard here" in out
    status = {name: json.loads((tmp_path / "qc" / "tasks" / f"ubuntu-qcgui-{name}_seed0" / "result.json")
                               .read_text())["status"] for name in ("gui_proven", "gui_target_missing", "gui_none")}
    assert status == {"gui_proven": "passed", "gui_target_missing": "failed", "gui_none": "passed"}, status
    assert "subtask 0 ubuntu-qcgui-gui_target_missing: the GUI solution does not solve it" in out, out[-3000:]
    traj = (tmp_path / "qc" / "tasks" / "ubuntu-qcgui-gui_proven_seed0" / "gui" / "traj.jsonl").read_text()
    assert '"type": "CLICK", "x": ' in traj and '"resolved"' in traj  # the plain action, and what it was aimed at
