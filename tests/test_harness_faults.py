"""Faults a long evaluation meets, provoked for real: a model endpoint that accepts the connection and never
answers, a run stopped with Ctrl-C or killed, a run resumed with a narrower selection. Real pytest processes,
real devices, a real loopback endpoint."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import docker
import pytest

from jarvis_pytest.agents.planner import render_step
from jarvis_pytest.dashboard.store import ResultsStore
from jarvis_pytest.llm.fake_server import FakeChatServer, stall
from jarvis_pytest.report.rollup import load_results
from jarvis_pytest.results.run_state import resource_id

pytestmark = pytest.mark.containers
REPO = Path(__file__).resolve().parents[1]


def bench_cmd(run_dir: Path, *args: str) -> list[str]:
    return [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", str(REPO / "tasks"), "--results-dir",
            str(run_dir), "--instances", "1", *args]


def leftovers(run_id: str) -> tuple[list, list]:
    """The containers and networks (names) the run still has."""
    api = docker.from_env().api
    label = {"label": f"org.jarvis.run={run_id}"}
    return ([c["Names"] for c in api.containers(all=True, filters=label)],
            [n["Name"] for n in api.networks(filters=label)])


def wait_for(predicate, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(0.3)
    raise AssertionError(f"timed out waiting for {what}")


def test_hanging_endpoint_is_an_error_within_the_deadline_and_pytest_exits(device_images, tmp_path):
    """The planner's endpoint accepts the request and never answers: the task ends as an infrastructure error
    (not an agent failure) within the step deadline, keeps the step it took, and the session exits at once."""
    with FakeChatServer(models=("planner", "grounder")) as fake:
        fake.script(stall(600), model="planner")
        t0 = time.monotonic()
        proc = subprocess.run(bench_cmd(tmp_path, "-p", "no:xdist", "-k", "thunar-rename_file", "--agent", "holo2",
                                        "--planner-base-url", fake.url, "--planner-model", "planner",
                                        "--grounder-base-url", fake.url, "--grounder-model", "grounder",
                                        "--step-timeout", "4"),
                              cwd=REPO, capture_output=True, text=True, timeout=300)
        elapsed = time.monotonic() - t0
    out = proc.stdout + proc.stderr
    assert proc.returncode == 1 and "1 error" in out and "failed" not in out.splitlines()[-1], out[-3000:]
    (result,) = load_results(tmp_path)[0]
    assert result.status == "error" and "step time limit (4 s)" in result.error
    assert result.steps == 1
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["errors"]["atomic"] == 1 and summary["atomic"]["overall"]["n"] == 0  # not in the rates
    assert elapsed < 90, f"the session took {elapsed:.0f} s"  # boot + one 4 s step + grace; no 600 s wait
    print(f"hanging endpoint: session ended {elapsed:.1f} s after start (step deadline 4 s)")


def test_task_time_limit_is_a_timeout_counted_apart(device_images, tmp_path):
    env = dict(os.environ, PYTHONPATH=str(REPO / "tests" / "data" / "agents"))
    proc = subprocess.run(bench_cmd(tmp_path, "-p", "no:xdist", "-k", "thunar-rename_file", "--agent",
                                    "slow_agent:SlowAgent", "--agent-option", "seconds=30", "--task-timeout", "3"),
                          cwd=REPO, capture_output=True, text=True, timeout=300, env=env)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 1, out[-3000:]
    (result,) = load_results(tmp_path)[0]
    assert result.status == "timeout" and result.end_reason == "timeout"
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["timeouts"]["atomic"] == 1 and summary["atomic"]["overall"]["n"] == 0


def _start_run(run_dir: Path) -> subprocess.Popen:
    cmd = bench_cmd(run_dir, "-n", "2", "--agent", "oracle", "-k", "thunar or mousepad or terminal")
    # Ctrl-C must reach it even where this test runs as a background job (a non-interactive shell starts those
    # with SIGINT ignored, and Python then installs no KeyboardInterrupt handler): SIGINT back to its default
    return subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            start_new_session=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def _finished(run_dir: Path) -> int:
    return sum(r.status in ("passed", "failed") for r in load_results(run_dir)[0])


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_stopped_run_removes_its_devices_and_says_what_never_ran(device_images, tmp_path, sig):
    run_dir = tmp_path / f"run-{sig.name}"
    proc = _start_run(run_dir)
    try:
        wait_for(lambda: _finished(run_dir) >= 2 and leftovers(resource_id(run_dir))[0], 240, "two tasks and live devices")
        t0 = time.monotonic()
        if sig == signal.SIGINT:
            os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C in a terminal reaches the whole process group
        else:
            os.kill(proc.pid, signal.SIGTERM)   # a scheduler stopping the job: the controller only
        out, _ = proc.communicate(timeout=120)
        stopped_in = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    containers, networks = leftovers(resource_id(run_dir))
    assert not containers and not networks, (containers, networks, out[-3000:])
    meta = json.loads((run_dir / "run.json").read_text())
    assert meta["state"] == "interrupted", out[-2000:]
    summary = json.loads((run_dir / "summary.json").read_text())
    plan = json.loads((run_dir / "plan.json").read_text())
    assert summary["not_run"]["atomic"] + summary["unfinished"]["atomic"] + summary["errors"]["atomic"] > 0
    accounted = summary["tasks"] + sum(sum(summary[k].values()) for k in
                                       ("not_run", "unfinished", "errors", "timeouts", "skipped"))
    assert accounted == len(plan["tasks"]), summary
    assert ResultsStore(tmp_path).run(run_dir.name)["state"] == "interrupted"
    print(f"{sig.name}: stopped in {stopped_in:.1f} s, {summary['tasks']} of {len(plan['tasks'])} tasks done")


def test_killed_run_is_interrupted_and_the_next_run_removes_its_leftovers(device_images, tmp_path):
    run_dir = tmp_path / "killed"
    proc = _start_run(run_dir)
    try:
        wait_for(lambda: _finished(run_dir) >= 1 and leftovers(resource_id(run_dir))[0], 240, "a task and live devices")
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    time.sleep(1)
    assert ResultsStore(tmp_path).run(run_dir.name)["state"] == "interrupted"
    # the next run's start-up removes what the dead run left (its processes are gone), then resumes it
    proc = subprocess.run(bench_cmd(run_dir, "-p", "no:xdist", "--agent", "oracle", "--resume", str(run_dir),
                                    "-k", "thunar-rename_file"),
                          cwd=REPO, capture_output=True, text=True, timeout=600)
    out = proc.stdout + proc.stderr
    containers, networks = leftovers(resource_id(run_dir))
    assert not containers and not networks, out[-3000:]
    # which start-up swept them is not asserted: a session another test starts meanwhile may get there first (the
    # sweep itself, and that it spares live runs, is test_cleanup_after_the_run_is_killed's)
    meta = json.loads((run_dir / "run.json").read_text())
    assert len(meta["sessions"]) == 2 and meta["sessions"][1]["resumed"] and meta["state"] == "finished"


def test_resume_only_adds_results(device_images, tmp_path):
    """A finished run resumed with a narrower -k keeps every result it had; its summary still covers the union
    of what was planned; it keeps its first start time and records the resume."""
    run_dir = tmp_path / "run"
    first = subprocess.run(bench_cmd(run_dir, "-n", "2", "--agent", "oracle", "-k", "thunar-rename_file or "
                                     "thunar-copy_file or mousepad-append_line"),
                           cwd=REPO, capture_output=True, text=True, timeout=600)
    assert first.returncode == 0, first.stdout[-3000:]
    before = {r.task_id: r.model_dump_json() for r in load_results(run_dir)[0]}
    started = json.loads((run_dir / "run.json").read_text())["started"]
    again = subprocess.run(bench_cmd(run_dir, "-p", "no:xdist", "--agent", "oracle", "--resume", str(run_dir),
                                     "-k", "thunar-rename_file"),
                           cwd=REPO, capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stdout[-3000:]
    after = {r.task_id: r.model_dump_json() for r in load_results(run_dir)[0]}
    assert after == before  # nothing lost, nothing rerun (all had passed)
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["tasks"] == len(before) == 3
    meta = json.loads((run_dir / "run.json").read_text())
    assert meta["started"] == started and len(meta["sessions"]) == 2
    other = subprocess.run(bench_cmd(run_dir, "-p", "no:xdist", "--agent", "noop", "--resume", str(run_dir)),
                           cwd=REPO, capture_output=True, text=True, timeout=120)
    assert other.returncode == 4 and "the run was made with agent" in other.stdout + other.stderr
    assert {r.task_id: r.model_dump_json() for r in load_results(run_dir)[0]} == before


def test_oracle_trajectory_names_each_device_and_command(device_images, tmp_path):
    proc = subprocess.run(bench_cmd(tmp_path, "-p", "no:xdist", "--agent", "oracle", "-k", "thunar-rename_file"),
                          cwd=REPO, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:]
    (task_dir,) = (tmp_path / "tasks").iterdir()
    steps = [json.loads(line) for line in (task_dir / "traj.jsonl").read_text().splitlines()]
    assert all(s["platform"] == "ubuntu" for s in steps), steps
    commands = [c for s in steps for c in s["extra"].get("commands", [])]
    assert commands and all(c["platform"] == "ubuntu" and c["returncode"] == 0 and c["seconds"] >= 0 and c["command"]
                            for c in commands)
    assert steps[-1]["action"]["type"] == "DONE"
    assert proc.stdout.count("infrastructure error") == 0
    # the dashboard's task API answers for the task id it lists, and for the folder name
    store = ResultsStore(tmp_path.parent)
    listed = store.run(tmp_path.name)["tasks"][0]
    assert store.task(tmp_path.name, listed["task_id"])["task_id"] == listed["task_id"]
    assert store.task(tmp_path.name, listed["name"])["task_id"] == listed["task_id"]
