"""A benchmark run's exit status through pytest itself, on real Ubuntu containers: an agent's failed task is a
result (exit 0, recorded as failed); an error beside it, or any failure of the oracle or of the GUI oracle,
exits 1, and the GUI oracle skips a task it has no GUI solution for. The run also shows
that traj.jsonl keeps only the first CUT_TEXT_CHARS of a huge model answer and records its length."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from jarvis_pytest.report.rollup import load_results
from jarvis_pytest.results.model import CUT_TEXT_CHARS

pytestmark = pytest.mark.containers
REPO = Path(__file__).resolve().parents[1]
AGENTS = REPO / "tests" / "data" / "agents"

MAKE_FILE = {
    "id": "ubuntu-terminal-make_file", "platform": "ubuntu", "app": "Terminal",
    "instruction": "Create the file {{path}}.",
    "inputs": {"path": {"type": "txt_file", "choices": ["/home/user/made.txt"]}},
    "evaluate": [{"func": "file_exists", "args": {"path": "{{path}}"}}],
    "solution": [{"command": "touch '{{path}}'"}],
}
# the oracle's solution does not do what the task asks: the cheapest real oracle failure
WRONG_SOLUTION = dict(MAKE_FILE, id="ubuntu-terminal-wrong_solution", solution=[{"command": "true"}])
# set-up fails on the device: an infrastructure error, never the agent's
BROKEN_SETUP = dict(MAKE_FILE, id="ubuntu-terminal-broken_setup",
                    config=[{"type": "command", "command": "exit 7"}])
# a GUI solution that does nothing: the cheapest real failure of the GUI oracle
IDLE_GUI = dict(MAKE_FILE, id="ubuntu-terminal-idle_gui", gui_solution=[{"type": "WAIT", "seconds": 0.1}])


@pytest.fixture(scope="module")
def library(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("library")
    (root / "ubuntu").mkdir()
    for t in (MAKE_FILE, WRONG_SOLUTION, BROKEN_SETUP, IDLE_GUI):
        (root / "ubuntu" / f"{t['id'].rsplit('-', 1)[1]}.json").write_text(json.dumps(t))
    (root / "none.json").write_text('{"tasks": []}')
    return root


def bench(library: Path, run_dir: Path, select: str, *args: str, workers: int = 0) -> subprocess.CompletedProcess:
    """`pytest tasks` on `library`'s tasks that `select` names (`workers`: xdist workers, as `make bench`)."""
    xdist = ["-n", str(workers)] if workers else ["-p", "no:xdist"]
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", *xdist, str(REPO / "tasks"),
           "--library", str(library), "--dataset", str(library / "none.json"), "--instances", "1",
           "--results-dir", str(run_dir), "-k", select, *args]
    env = dict(os.environ, PYTHONPATH=str(AGENTS))
    return subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=400, env=env)


def test_an_agents_failure_is_a_result_not_a_failed_run(device_images, library, tmp_path):
    proc = bench(library, tmp_path, "make_file", "--agent", "verbose_agent:VerboseAgent", workers=2)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
    assert "1 failed" in proc.stdout.splitlines()[-1] and "not a failed run: exit 0" in proc.stdout
    assert json.loads((tmp_path / "run.json").read_text())["sessions"][-1]["exit"] == 0
    (result,) = load_results(tmp_path)[0]
    assert result.status == "failed" and result.end_reason == "fail"
    # the model's answer of a million characters: its first CUT_TEXT_CHARS kept, its length recorded
    traj = (tmp_path / "tasks" / "ubuntu-terminal-make_file_seed0" / "traj.jsonl")
    (step,) = [json.loads(line) for line in traj.read_text().splitlines()]
    assert len(step["raw_output"]) == CUT_TEXT_CHARS and step["cut"] == {"raw_output": 1_000_000}
    assert traj.stat().st_size < CUT_TEXT_CHARS + 10_000


def test_an_error_beside_the_agents_failure_exits_1(device_images, library, tmp_path):
    proc = bench(library, tmp_path, "make_file or broken_setup", "--agent", "verbose_agent:VerboseAgent")
    assert proc.returncode == 1, proc.stdout[-3000:]
    statuses = sorted(r.status for r in load_results(tmp_path)[0])
    assert statuses == ["error", "failed"] and "not a failed run" not in proc.stdout


def test_any_failure_of_the_oracle_exits_1(device_images, library, tmp_path):
    proc = bench(library, tmp_path, "make_file or wrong_solution", "--agent", "oracle")
    assert proc.returncode == 1, proc.stdout[-3000:]
    results = {r.task_id: r.status for r in load_results(tmp_path)[0]}
    assert results == {"ubuntu-terminal-make_file[seed0]": "passed", "ubuntu-terminal-wrong_solution[seed0]": "failed"}


def test_the_gui_oracle_skips_what_it_cannot_prove_and_its_failure_exits_1(device_images, library, tmp_path):
    proc = bench(library, tmp_path, "make_file or idle_gui", "--agent", "gui-oracle", "-rs")
    assert proc.returncode == 1, proc.stdout[-3000:]
    results = {r.task_id: r for r in load_results(tmp_path)[0]}
    assert {k: r.status for k, r in results.items()} == {"ubuntu-terminal-make_file[seed0]": "skipped",
                                                         "ubuntu-terminal-idle_gui[seed0]": "failed"}
    why = results["ubuntu-terminal-make_file[seed0]"].error
    assert "the GUI oracle has nothing to run" in why and "has no GUI solution yet" in why, why
    assert "has no GUI solution yet" in proc.stdout and "not a failed run" not in proc.stdout
