"""Broken storage is one clear error and leaves nothing: a full or read-only results folder stops a run at
start-up (exit 4, naming the folder) or, filling mid-run, ends it with its devices removed and its files kept;
a corrupt run.json or result.json is named by `jarvis runs`, the dashboard and `--resume`, and every other run
still lists. Real file systems (a small tmpfs, a read-only bind mount: the tests run as root, which chmod does not
stop), real pytest processes, a real dashboard server."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import urllib.request
from contextlib import contextmanager
from pathlib import Path

import pytest

from jarvis_pytest.dashboard.server import serving
from jarvis_pytest.results import run_lock
from jarvis_pytest.results.storage import MIN_FREE_ENV

REPO = Path(__file__).resolve().parents[1]
RUN_FORMAT = "jarvis-pytest run"


@pytest.fixture(autouse=True)
def test_locks(monkeypatch):
    """The run locks of the project's tests, apart from the host's runs (as in test_run_isolation.py)."""
    monkeypatch.setenv(run_lock.LOCKS_ENV, str(Path(tempfile.gettempdir()) / "jarvis-runs-of-tests"))


@contextmanager
def mounted(target: Path, *args: str):
    """`mount ARGS target` for the block, unmounted after (lazily: a process may still hold a file there)."""
    target.mkdir(parents=True, exist_ok=True)
    subprocess.run(["mount", *args, str(target)], check=True, capture_output=True)
    try:
        yield target
    finally:
        subprocess.run(["umount", "-l", str(target)], capture_output=True)


def fill(folder: Path, leave: int = 0) -> None:
    """Write into `folder` until its file system has no more than `leave` bytes free."""
    st = os.statvfs(folder)
    size = max(0, st.f_bavail * st.f_frsize - leave)
    try:
        with open(folder / "filler", "wb") as f:
            f.write(b"\0" * size)
    except OSError:
        pass


def bench(run_dir: Path, *args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", str(REPO / "tasks"),
                           "--results-dir", str(run_dir), "-p", "no:xdist", *args], cwd=REPO,
                          capture_output=True, text=True, timeout=300, env={**os.environ, **(env or {})})


def assert_one_clear_error(proc: subprocess.CompletedProcess, *needles: str) -> str:
    out = proc.stdout + proc.stderr
    assert proc.returncode == 4, out
    assert "Traceback" not in out and "INTERNALERROR" not in out, out
    errors = [line for line in out.splitlines() if line.startswith("ERROR:")]
    assert len(errors) == 1, out
    for needle in needles:
        assert needle in errors[0], errors[0]
    return errors[0]


def test_a_full_results_folder_stops_the_run_at_start_up(tmp_path):
    with mounted(tmp_path / "small", "-t", "tmpfs", "-o", "size=2m", "tmpfs") as small:
        fill(small)
        run_dir = small / "run"
        proc = bench(run_dir, "--agent", "noop", "-k", "thunar-rename_file", env={MIN_FREE_ENV: "0"})
        assert_one_clear_error(proc, str(run_dir), "cannot write", "No space left")


def test_less_free_space_than_the_minimum_is_full(tmp_path):
    with mounted(tmp_path / "small", "-t", "tmpfs", "-o", "size=2m", "tmpfs") as small:
        run_dir = small / "run"
        proc = bench(run_dir, "--agent", "noop", "-k", "thunar-rename_file")  # the default minimum: 20 MiB
        assert_one_clear_error(proc, str(run_dir), "full", "MiB free", MIN_FREE_ENV)
        assert not (run_dir / "run.json").exists()


def test_a_read_only_results_folder_stops_the_run_at_start_up(tmp_path):
    (tmp_path / "src").mkdir()
    with mounted(tmp_path / "ro", "--bind", str(tmp_path / "src")) as ro:
        subprocess.run(["mount", "-o", "remount,bind,ro", str(ro)], check=True)
        for run_dir in (ro, ro / "run"):  # the folder itself, or a folder it cannot create
            proc = bench(run_dir, "--agent", "noop", "-k", "thunar-rename_file")
            assert_one_clear_error(proc, str(run_dir), "Read-only file system")


def make_run(root: Path, name: str, run_json: bytes | None, result: bytes | None = None) -> Path:
    """A finished run with one task, its run.json and result.json as given (None: a valid one)."""
    run_dir = root / name
    task = run_dir / "tasks" / "ubuntu-x-y"
    task.mkdir(parents=True)
    valid = {"format": RUN_FORMAT, "run_id": name, "state": "finished", "started": "2026-01-01T00:00:00+00:00",
             "finished": "2026-01-01T00:10:00+00:00", "agent": {"name": "noop"}, "sessions": []}
    (run_dir / "run.json").write_bytes(json.dumps(valid).encode() if run_json is None else run_json)
    ok = {"task_id": "ubuntu-x-y", "category": "c", "platforms": ["ubuntu"], "instruction": "i", "status": "failed",
          "agent": {"name": "noop"}, "started": "2026-01-01T00:00:01+00:00", "finished": "2026-01-01T00:00:02+00:00"}
    (task / "result.json").write_bytes(json.dumps(ok).encode() if result is None else result)
    (run_dir / "plan.json").write_text(json.dumps({"tasks": ["ubuntu-x-y"]}))
    return run_dir


CORRUPT_RUN_JSON = {
    "garbage": b"\x00\xff{not json",
    "a-list": b"[1, 2]",
    "huge-pid": json.dumps({"format": RUN_FORMAT, "state": "running", "pid": 10**30,
                            "host": os.uname().nodename}).encode(),
    "agent-not-an-object": json.dumps({"format": RUN_FORMAT, "state": "finished", "agent": 5}).encode(),
    "sessions-not-a-list": json.dumps({"format": RUN_FORMAT, "state": "finished", "sessions": 7}).encode(),
}


@pytest.mark.parametrize("kind", sorted(CORRUPT_RUN_JSON))
def test_a_corrupt_run_json_is_named_and_every_other_run_lists(tmp_path, kind):
    root = tmp_path / "reports"
    make_run(root, "good-a", None)
    make_run(root, "bad", CORRUPT_RUN_JSON[kind])
    make_run(root, "good-b", None, result=b'{"task_id": "ubuntu-x-y", "status": 12')  # a corrupt result.json
    proc = subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "runs", "--results", str(root)], cwd=REPO,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr
    lines = proc.stdout.splitlines()
    assert [line.split("\t")[0] for line in lines if not line.startswith(" ")] == ["good-b", "good-a", "bad"]
    assert any(line.strip().startswith("unreadable: bad/run.json") for line in lines), proc.stdout
    assert any(line.strip().startswith("unreadable: good-b/tasks/ubuntu-x-y/result.json") for line in lines)
    with serving(root) as server:
        base = f"http://127.0.0.1:{server.server_address[1]}"
        with urllib.request.urlopen(f"{base}/api/runs", timeout=10) as resp:
            runs = {r["id"]: r for r in json.load(resp)["runs"]}
        assert runs["good-a"]["state"] == "finished" and runs["good-a"]["problems"] == []
        assert runs["bad"]["state"] == "unreadable"
        assert [p["file"] for p in runs["bad"]["problems"]] == ["bad/run.json"]
        for run in runs:
            with urllib.request.urlopen(f"{base}/api/runs/{run}", timeout=10) as resp:
                assert resp.status == 200


@pytest.mark.parametrize("kind", sorted(CORRUPT_RUN_JSON))
def test_resume_names_a_corrupt_run_json(tmp_path, kind):
    run_dir = make_run(tmp_path, "bad", CORRUPT_RUN_JSON[kind])
    proc = bench(run_dir, "--resume", str(run_dir), "--agent", "noop", "-k", "thunar-rename_file")
    assert_one_clear_error(proc, str(run_dir / "run.json"), "--resume")


@pytest.mark.parametrize("plan", [b"{nope", b'{"tasks": 5}', b'{"tasks": [], "categories": [1]}'])
def test_resume_names_a_corrupt_plan_json(tmp_path, plan):
    run_dir = make_run(tmp_path, "run", None)
    (run_dir / "plan.json").write_bytes(plan)
    proc = bench(run_dir, "--resume", str(run_dir), "--agent", "noop", "-k", "thunar-rename_file")
    assert_one_clear_error(proc, str(run_dir / "plan.json"), "--resume")


def test_resume_names_a_corrupt_result_json_and_runs_its_task_again(tmp_path):
    run_dir = make_run(tmp_path, "run", None, result=b'{"task_id": "ubuntu-x-y", "status": 1')
    proc = bench(run_dir, "--resume", str(run_dir), "--agent", "noop", "-k", "no-such-task")
    out = proc.stdout + proc.stderr
    assert proc.returncode == 5, out  # nothing selected here; the run itself went on
    assert "Traceback" not in out and "INTERNALERROR" not in out, out
    named = [line for line in out.splitlines() if str(run_dir / "tasks" / "ubuntu-x-y" / "result.json") in line]
    assert len(named) == 1 and "runs again" in named[0], out


@pytest.mark.containers
def test_a_folder_that_fills_mid_run_ends_the_run_with_its_devices_removed_and_its_files_kept(tmp_path):
    """48 KB left: start-up passes (minimum set to 20 KB), run.json, plan.json and the task's first result.json
    fit, its first screenshot (about 75 KB) does not. The task errors naming the folder, no later task starts,
    no container or network of the run is left, and what was written is still there."""
    import docker

    from jarvis_pytest.results.run_state import liveness, read_json, resource_id

    with mounted(tmp_path / "small", "-t", "tmpfs", "-o", "size=4m", "tmpfs") as small:
        run_dir = small / "run"
        fill(small, leave=48 * 1024)
        proc = bench(run_dir, "--agent", "noop", "-k", "thunar-rename_file or mousepad", "--instances", "1",
                     env={MIN_FREE_ENV: "0.02"})
        out = proc.stdout + proc.stderr
        assert proc.returncode in (1, 2), out  # failed/interrupted, not an internal error
        assert "Traceback" not in out and "INTERNALERROR" not in out, out
        assert f"{run_dir}: cannot write into the results folder (No space left on device); the run stops here" in out
        assert " 1 error" in out and " passed" not in out and " failed" not in out, out  # no later task started
        assert out.count("the end of the run (run.json, the summary, report.html) was not written") == 1, out
        api = docker.from_env().api
        label = {"label": f"org.jarvis.run={resource_id(run_dir)}"}
        assert api.containers(all=True, filters=label) == [] and api.networks(filters=label) == []
        meta = read_json(run_dir / "run.json")
        assert meta is not None and liveness(meta) == "interrupted"  # kept; its process is gone
        results = list((run_dir / "tasks").glob("*/result.json"))
        assert len(results) == 1 and json.loads(results[0].read_text())["status"] == "running"


def test_a_results_folder_that_cannot_be_resolved_is_one_clear_error(tmp_path):
    (tmp_path / "a").symlink_to(tmp_path / "b")
    (tmp_path / "b").symlink_to(tmp_path / "a")
    proc = bench(tmp_path / "a", "--agent", "noop", "-k", "no-such-task")
    assert_one_clear_error(proc, str(tmp_path / "a"), "--results-dir", "Symlink loop")
