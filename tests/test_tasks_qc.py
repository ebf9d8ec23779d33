"""`jarvis qc`, the quality gate: on real devices a sound task passes; a task already solved by its set-up, one
with an evaluator that holds before anything is done (while another fails), and one whose oracle does not solve
it are violations with their reasons, and the exit status says so."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.generators import generate
from jarvis_pytest.results.model import EvaluatorVerdict, SubtaskVerdict, TaskResult
from jarvis_pytest.tasks.qc import qc_row, render_table

REPO = Path(__file__).resolve().parents[1]
LIBRARY = REPO / "tests" / "data" / "qc_library"


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
    assert all("| fail | 2/2 fail | pass | ok |" in rows[f"ubuntu-qc-good[seed{i}]"] for i in (0, 1))
    assert "| PASS | " in rows["ubuntu-qc-already_solved[seed0]"] and "passes untouched" in rows["ubuntu-qc-already_solved[seed0]"]
    assert "| FAIL | VIOLATED | oracle fails: file_text_equals" in rows["ubuntu-qc-oracle_fails[seed0]"]
    assert "| PASS | " in rows["ubuntu-qc-guard_holds[seed1]"] and "passes untouched: file_exists" in rows["ubuntu-qc-guard_holds[seed1]"]
    # a negative the evaluators accept is a violation, named with its note
    weak = rows["ubuntu-qc-negative_passes[seed0]"]
    assert "| fail | 2/2 PASS | pass | VIOLATED | negative 0 passes (artefact: an empty file where the copy belongs)" in weak
    assert "2/10 instances pass the quality gate" in out
    assert (tmp_path / "qc" / "qc.md").read_text().count("VIOLATED") == 8
