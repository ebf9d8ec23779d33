"""Listing and selecting tasks through pytest itself (no devices): markers select without an agent, and what
decides a run's exit status (the real runs are in test_plugin_exit_status.py)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from jarvis_pytest.plugin.cases import PROPERTY
from jarvis_pytest.plugin.exit_status import ExitStatus

REPO = Path(__file__).resolve().parents[1]


def collect(*args: str) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist", str(REPO / "tasks"),
           "--instances", "1", "-q", *args]
    return subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=120)


def listed(proc: subprocess.CompletedProcess) -> set[str]:
    return {line.split("[", 1)[1][:-1] for line in proc.stdout.splitlines() if "::" in line}


def test_markers_select_tasks_without_an_agent():
    every = listed(collect("--collect-only"))
    android = collect("-m", "android", "--collect-only")
    assert android.returncode == 0, android.stdout[-2000:] + android.stderr[-2000:]
    assert listed(android) == listed(collect("-m", "android", "--collect-only", "--agent", "oracle"))
    assert listed(android) and listed(android) < every
    atomic = [t for t in listed(android) if "-" in t and "[seed" in t]
    assert atomic and all(t.startswith("android-") for t in atomic)
    assert "choose an agent" not in android.stdout + android.stderr


def test_running_tasks_still_needs_an_agent():
    proc = collect("-m", "ubuntu and atomic", "-k", "seed0")
    assert proc.returncode == 4 and "choose an agent with --agent" in proc.stdout + proc.stderr


def test_running_tasks_on_xdist_workers_without_an_agent_is_one_usage_error():
    """Under xdist the workers collect: their usage error used to be xdist's INTERNALERROR (exit 3); now the
    controller stops the run with the same one line (exit 4)."""
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", str(REPO / "tasks"), "-n", "2", "-m", "android"]
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=120)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 4 and "choose an agent with --agent" in out and "INTERNALERROR" not in out, out[-2000:]


def report(when: str, outcome: str, status: str | None) -> pytest.TestReport:
    props = [(PROPERTY, {"status": status})] if status else []
    return pytest.TestReport("tasks/test_atomic.py::test_atomic[t]", ("tasks/test_atomic.py", 0, "t"), {},
                             outcome, None, when, user_properties=props)


FAILED, OK = int(pytest.ExitCode.TESTS_FAILED), int(pytest.ExitCode.OK)
# (oracle?, reports, pytest's status) → the run's status
TABLE = [
    (False, [report("call", "failed", "failed")], FAILED, OK),                        # the agent failed a task
    (False, [report("call", "passed", "passed"), report("call", "failed", "failed")], FAILED, OK),
    (True, [report("call", "failed", "failed")], FAILED, FAILED),                     # the oracle failed one
    (False, [report("call", "failed", "error")], FAILED, FAILED),                     # infrastructure error
    (False, [report("call", "failed", "failed"), report("call", "failed", "error")], FAILED, FAILED),
    (False, [report("call", "failed", "timeout")], FAILED, FAILED),                   # a task's time limit
    (False, [report("call", "failed", None)], FAILED, FAILED),                        # no result (not a task)
    (False, [report("setup", "failed", "failed")], FAILED, FAILED),                   # set-up, not the body
    (False, [report("call", "failed", "failed")], int(pytest.ExitCode.INTERRUPTED), int(pytest.ExitCode.INTERRUPTED)),
    (False, [], OK, OK),
]


@pytest.mark.parametrize("oracle,reports,pytest_status,expected", TABLE)
def test_exit_status_table(oracle, reports, pytest_status, expected):
    status = ExitStatus(oracle=oracle)
    for r in reports:
        status.pytest_runtest_logreport(r)
    assert status.final(pytest_status) == expected
