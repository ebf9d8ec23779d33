"""The benchmark end to end through pytest itself, on real containers: the oracle passes and noop fails real
Ubuntu tasks under -n 2, the summary equals the per-task results, xdist or not, and a killed run resumes."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from jarvis_pytest.report.rollup import load_results, rollup
from jarvis_pytest.results.run_state import resource_id

pytestmark = pytest.mark.containers
REPO = Path(__file__).resolve().parents[1]
ATOMIC = "mousepad-write_note or mousepad-replace_text or thunar-rename_file or terminal-brighten_image"
SELECT = ["-k", f"({ATOMIC}) and seed0 or sw-0013 or sw-0016", "--instances", "1"]  # 4 atomic + 2 composed tasks


def bench(run_dir: Path, *args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", str(REPO / "tasks"), "--results-dir",
           str(run_dir), *SELECT, *args]
    return subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=timeout)


def summary_of(run_dir: Path) -> dict:
    return json.loads((run_dir / "summary.json").read_text())


@pytest.fixture(scope="module")
def oracle_run(device_images, tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("oracle")
    proc = bench(run_dir, "--agent", "oracle", "-n", "2")
    return run_dir, proc


def test_oracle_passes_every_task(oracle_run):
    run_dir, proc = oracle_run
    assert proc.returncode == 0, proc.stdout[-4000:]
    results, problems = load_results(run_dir)
    assert not problems and len(results) == 6 and all(r.status == "passed" for r in results)
    assert {r.category for r in results} == {"atomic", "sw"}
    assert "jarvis: task success rates" in proc.stdout and "100.0 (4/4)" in proc.stdout


def test_prewarming_overlaps_the_previous_task(oracle_run):
    """A worker's next task gets devices that began to boot while the previous task ran: created before the task
    started, and taken at once instead of booted; a worker's first task gets devices that began to boot while
    the workers were still collecting (all six tasks are Ubuntu's, so that guess is right)."""
    run_dir, _ = oracle_run
    results, _ = load_results(run_dir)
    first = {}
    for r in sorted(results, key=lambda r: r.started):
        first.setdefault(r.worker, r)
    assert set(first) == {"gw0", "gw1"}
    assert all(r.durations.get("booted_ahead", 0) > 0 for r in first.values()), [r.durations for r in results]
    # most of a boot hidden: the devices began booting long enough before the task that it hardly waited
    hidden = [r for r in results if r.durations.get("booted_ahead", 0) > 1.0
              and r.durations["boot"] < 0.5 * (r.durations["booted_ahead"] + r.durations["boot"])]
    assert hidden, [(r.task_id, r.worker, r.durations) for r in results]


def test_summary_equals_the_per_task_results(oracle_run):
    run_dir, _ = oracle_run
    results, _ = load_results(run_dir)
    assert summary_of(run_dir) == rollup(results, agent="oracle").model_dump(mode="json")


def test_summary_is_the_same_without_xdist(oracle_run, tmp_path):
    run_dir, _ = oracle_run
    before = summary_of(run_dir)
    proc = bench(run_dir, "--agent", "oracle", "--resume", str(run_dir), "-p", "no:xdist")
    assert proc.returncode == 0, proc.stdout[-3000:]
    assert summary_of(run_dir) == before


def test_results_and_report_files(oracle_run):
    run_dir, _ = oracle_run
    task = run_dir / "tasks" / "sw-0013"
    lines = [json.loads(l) for l in (task / "traj.jsonl").read_text().splitlines()]
    assert lines and all((task / f).is_file() for l in lines for f in l["screenshots"].values())
    result = json.loads((task / "result.json").read_text())
    assert result["image_ids"]["ubuntu"].startswith("sha256:") and result["agent"] == {"name": "oracle"}
    assert [s["passed"] for s in result["subtasks"]] == [True, True]
    html = (run_dir / "report.html").read_text()
    assert "Task success rates" in html and "sw-0013" in html
    assert html.count("tasks/sw-0013/step_0000_ubuntu.png") >= 1 and "first screenshot" in html


def test_noop_fails_every_task_with_reasons(device_images, tmp_path):
    proc = bench(tmp_path, "--agent", "noop", "-n", "2")
    assert proc.returncode == 0, proc.stdout[-3000:]  # the agent's failures are results, not a failed run
    results, _ = load_results(tmp_path)
    assert len(results) == 6 and all(r.status == "failed" for r in results)
    assert "file_text_replaced: expected" in proc.stdout and "found no file" in proc.stdout
    assert "file_copied: expected an independent copy" in proc.stdout  # a composed task's subtask
    s = summary_of(tmp_path)
    assert s["atomic"]["ubuntu"]["k"] == 0 and s["composed"]["sw"]["ssr"]["rate"] == 0.0


def test_a_killed_run_keeps_its_results_and_resumes(device_images, tmp_path):
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist", str(REPO / "tasks"),
           "--results-dir", str(tmp_path), "--agent", "oracle", *SELECT]
    proc = subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    try:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline:
            done = [r for r in load_results(tmp_path)[0] if r.status == "passed"]
            if len(done) >= 2:
                break
            time.sleep(0.2)
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(30)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    finished = {r.task_id: r.started for r in load_results(tmp_path)[0] if r.status == "passed"}
    assert 2 <= len(finished) < 6
    subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "cleanup", "--run", str(tmp_path)], check=True,
                   capture_output=True)
    resumed = bench(tmp_path, "--agent", "oracle", "--resume", str(tmp_path), "-n", "2")
    assert resumed.returncode == 0, resumed.stdout[-3000:]
    results = {r.task_id: r for r in load_results(tmp_path)[0]}
    assert len(results) == 6 and all(r.status == "passed" for r in results.values())
    assert all(results[t].started == started for t, started in finished.items())  # not run again


BROKEN_SETUP = {
    "id": "ubuntu-terminal-broken_setup", "platform": "ubuntu", "app": "Terminal",
    "instruction": "Create the file {{path}}.",
    "inputs": {"path": {"type": "txt_file", "choices": ["/home/user/made.txt"]}},
    "config": [{"type": "command", "command": "test -e /tmp/setup-may-run || exit 7"}],
    "evaluate": [{"func": "file_exists", "args": {"path": "{{path}}"}}],
    "solution": [{"command": "touch '{{path}}'"}],
}


def test_infrastructure_errors_are_errors_apart_and_rerun(device_images, tmp_path):
    library = tmp_path / "library"
    (library / "ubuntu").mkdir(parents=True)
    (library / "ubuntu" / "broken.json").write_text(json.dumps(BROKEN_SETUP))
    run_dir = tmp_path / "run"
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist", str(REPO / "tasks"),
           "--library", str(library), "--dataset", str(tmp_path / "none.json"), "--instances", "1",
           "--results-dir", str(run_dir), "--agent", "oracle", "-k", "test_atomic"]
    (tmp_path / "none.json").write_text('{"tasks": []}')
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=300)
    assert "1 error" in proc.stdout and "failed" not in proc.stdout.splitlines()[-1], proc.stdout[-3000:]
    assert "setup command failed (7)" in proc.stdout
    s = summary_of(run_dir)
    assert s["errors"]["atomic"] == 1 and s["atomic"]["overall"]["n"] == 0  # not counted as an agent failure
    # the error is not kept by --resume: once the device can be set up, the rerun runs the task
    fixed = dict(BROKEN_SETUP, config=[{"type": "command", "command": "true"}])
    (library / "ubuntu" / "broken.json").write_text(json.dumps(fixed))
    proc = subprocess.run(cmd + ["--resume", str(run_dir)], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:]
    assert summary_of(run_dir)["atomic"]["overall"]["k"] == 1
    # now the task has a verdict: changing it again and resuming would reuse that verdict for another task
    (library / "ubuntu" / "broken.json").write_text(json.dumps(dict(fixed, instruction="Create {{path}} now.")))
    proc = subprocess.run(cmd + ["--resume", str(run_dir)], cwd=REPO, capture_output=True, text=True, timeout=300)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 4 and "tasks with a result changed" in out and "Traceback" not in out, out[-3000:]


def test_step_timeout_and_module_class_agent(device_images, tmp_path):
    """A user agent (module:Class) that gives no decision within the step time limit: the task is an
    infrastructure error (the agent's endpoint hangs), never an agent failure, and the session ends at once."""
    env = dict(os.environ, PYTHONPATH=str(REPO / "tests" / "data" / "agents"))
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist", str(REPO / "tasks"),
           "--results-dir", str(tmp_path), "--instances", "1", "-k", "thunar-rename_file", "--agent", "slow_agent:SlowAgent",
           "--agent-option", "seconds=20", "--step-timeout", "1"]
    t0 = time.monotonic()
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 1 and time.monotonic() - t0 < 60, proc.stdout[-3000:]
    (result,) = load_results(tmp_path)[0]
    assert result.status == "error" and "step time limit" in result.error and result.steps == 1
    assert result.agent == {"name": "slow", "seconds": 20.0}


def test_keep_devices_leaves_them_running_and_says_how_to_reach_them(device_images, tmp_path, only_kept_test):
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist", str(REPO / "tasks"),
           "--results-dir", str(tmp_path), "--instances", "1", "-k", "thunar-rename_file", "--agent", "noop", "--keep-devices"]
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=300)
    try:
        assert "docker exec -it jarvis-" in proc.stderr + proc.stdout
        import docker

        kept = docker.from_env().containers.list(filters={"label": f"org.jarvis.run={resource_id(tmp_path)}"})
        assert sorted(c.labels["org.jarvis.role"] for c in kept) == ["device", "holder", "transfer"]
        holder = next(c for c in kept if c.labels["org.jarvis.role"] == "holder")
        assert "docker rm -f " in proc.stderr + proc.stdout and holder.name in proc.stderr + proc.stdout
    finally:
        subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "cleanup", "--run", str(tmp_path)], check=True)
