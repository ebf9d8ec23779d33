"""Composed tasks through the GUI (issue 39, item 2): a dataset's subtasks take their templates' GUI solutions; the
built-in transfer's GUI solution types the oracle's commands into a command line each device opens through its GUI
and passes only if that command line closes (it does only where the command succeeded); what an upstream subtask
made and set-up held back (`opens`) is opened the same way. The end-to-end runs at the bottom play two MD tasks of
the shipped dataset with `--agent gui-oracle` on real Ubuntu and Wine devices.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from jarvis_pytest.agents.gui_oracle import gui_plan
from jarvis_pytest.devices.platforms import SHELL_TITLE, spec
from jarvis_pytest.errors import ConfigError
from jarvis_pytest.report.rollup import load_results
from jarvis_pytest.tasks.dataset import load_tasks
from jarvis_pytest.tasks.instances import with_gui_solutions
from jarvis_pytest.tasks.library import load_library
from jarvis_pytest.tasks.model import GuiStep
from jarvis_pytest.tasks.transfer import transfer_template

REPO = Path(__file__).resolve().parents[1]
DATASET = REPO / "tasks" / "composed" / "jarvis_150.json"
BACKENDS = {"ubuntu": "ubuntu (docker)", "windows": "windows (wine)"}
# MD tasks of the shipped dataset whose every subtask is solved through the GUI: Notepad's CRLF or WordPad's bold on
# Windows, the transfer, then Thunar copying the received file on Ubuntu (opened from a terminal: `opens`)
PROVEN_MD = ("md-0141", "md-0144")


@pytest.fixture(scope="module")
def tasks():
    library = load_library(REPO / "tasks")
    return {t.id: with_gui_solutions(t, library) for t in load_tasks([DATASET])}


def typed(steps) -> list[str]:
    return [s.model_dump(exclude_none=True).get("text", "") for s in steps if s.type == "TYPING"]


@pytest.mark.parametrize("source,dest", [("ubuntu", "windows"), ("windows", "ubuntu")])
def test_the_transfer_is_solved_by_the_oracles_commands_typed_on_each_device(source, dest):
    template = transfer_template(source, dest)
    steps = template.gui_solution
    upload, download = (s.command for s in template.solution)
    on_source = [s for s in steps if s.platform == source]
    on_dest = [s for s in steps if s.platform == dest]
    assert on_source + on_dest == list(steps)  # all on the source first, then all on the destination
    assert f"{upload} && exit\n" in typed(on_source) and f"{download} && exit\n" in typed(on_dest)
    for side in (on_source, on_dest):  # the command line is titled first, and its window must go: it did its work
        last = side[-1]
        assert last.type == "WAIT_FOR" and last.gone and last.target.window == SHELL_TITLE and last.timeout >= 60
        assert any(SHELL_TITLE in t for t in typed(side))


def test_a_platform_without_a_gui_command_line_has_no_gui_transfer():
    assert not transfer_template("ubuntu", "android").gui_solution
    assert spec("android").gui_shell_steps("true", "x") == []


def test_a_step_names_a_platform_or_is_refused():
    assert GuiStep.model_validate({"type": "WAIT", "seconds": 1, "platform": "windows"}).platform == "windows"
    with pytest.raises(Exception, match="platform"):
        GuiStep.model_validate({"type": "WAIT", "seconds": 1, "platform": "macos"})


def test_dataset_subtasks_take_their_templates_gui_solutions_with_their_own_values(tasks):
    sub = tasks["md-0144"].formatted_subtasks[0]  # WordPad's bold title on the dataset's own document
    assert sub.template == "windows-wordpad-bold_title" and sub.gui_solution
    doc = sub.input["doc"].value
    assert any(s.target and s.target.window and s.target.window.startswith(doc.rsplit("\\", 1)[1])
               for s in sub.gui_solution)
    raw = json.loads(DATASET.read_text())
    assert not any("gui_solution" in s for t in raw["tasks"] for s in t["formatted_subtasks"])  # the file unchanged


def test_what_set_up_held_back_is_opened_from_a_command_line_first(tasks):
    plan, why = gui_plan(tasks["md-0144"].formatted_subtasks, BACKENDS)
    assert why is None
    opening = [i for i in plan if i.origin == "opens"]
    assert opening and {i.subtask for i in opening} == {2} and {i.platform for i in opening} == {"ubuntu"}
    (start,) = [t for t in typed(i.step for i in opening) if "thunar" in t]
    assert start.startswith("setsid -f thunar ") and start.endswith(" && exit\n")
    first_own = next(k for k, i in enumerate(plan) if i.subtask == 2 and i.origin == "gui_solution")
    assert all(plan.index(i) < first_own for i in opening)


def test_a_subtask_without_a_gui_solution_still_stops_the_plan(tasks):
    subs = list(tasks["md-0144"].formatted_subtasks)
    subs[2] = subs[2].model_copy(update={"gui_solution": None})
    plan, why = gui_plan(subs, BACKENDS)
    assert plan == [] and why == "subtask 2 (ubuntu-thunar-copy_file) has no GUI solution yet", why
    subs[2] = subs[2].model_copy(update={"gui_infeasible": {"docker": "no way"}})
    assert "cannot be solved through the GUI on docker: no way" in gui_plan(subs, BACKENDS)[1]


def test_a_template_missing_from_the_library_leaves_the_subtask_as_it_is(tmp_path, tasks):
    (tmp_path / "lib").mkdir()
    (task,) = [t for t in load_tasks([DATASET]) if t.id == "md-0144"]
    bare = with_gui_solutions(task, load_library(tmp_path / "lib"))
    assert [bool(s.gui_solution) for s in bare.formatted_subtasks] == [False, True, False]  # the transfer is built in


@pytest.mark.containers
def test_md_tasks_pass_through_the_gui_end_to_end(device_images, tmp_path):
    """The two tasks, each device driven only by the agent's actions: a document edited on Wine, carried through
    the drive from a command line on each side, opened and copied in Thunar on Ubuntu. The drive's ledger proves the
    transfer as for any agent."""
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist", "-q", str(REPO / "tasks"),
           "-k", " or ".join(PROVEN_MD), "--agent", "gui-oracle", "--results-dir", str(tmp_path)]
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=900)
    results = {r.task_id: r for r in load_results(tmp_path)[0]}
    assert proc.returncode == 0 and sorted(results) == sorted(PROVEN_MD), proc.stdout[-3000:]
    for result in results.values():
        assert result.status == "passed" and all(s.passed for s in result.subtasks), result.task_id
        transfer = next(s for s in result.subtasks if s.template.startswith("transfer-"))
        assert "carried through the drive" in transfer.evaluators[0].reason
