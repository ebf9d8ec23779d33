"""Runs do not touch each other: a live run's results folder is refused to a second run (before it writes a byte
there), and the orphan sweeps remove only what dead runs left, never what a live run (any of its xdist workers)
or an ended `--keep-devices` run holds; those wait for `jarvis cleanup --kept`. Real pytest processes, real
locks held by real processes; the container parts create labelled containers of their own (no device boots)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from jarvis_pytest.infra.cleanup import is_kept, is_orphan
from jarvis_pytest.infra.containers import LABEL_HOST, LABEL_PID, LABEL_RUN, LABEL_WORKER
from jarvis_pytest.llm.fake_server import FakeChatServer, stall
from jarvis_pytest.results import run_lock
from jarvis_pytest.results.run_state import resource_id

REPO = Path(__file__).resolve().parents[1]
HOLD = """
import sys
from jarvis_pytest.results.run_lock import RunLock
lock = RunLock(sys.argv[1]); lock.acquire(keep_devices=sys.argv[2] == "keep")
print("held", flush=True)
sys.stdin.readline()  # until the test says so
lock.release()
"""


TEST_LOCKS = Path(tempfile.gettempdir()) / "jarvis-runs-of-tests"


@pytest.fixture(autouse=True)
def test_locks(monkeypatch):
    """These tests' runs keep their locks apart from the host's runs (so `--kept` sees only theirs), in one
    folder for all the tests' runs (tests/conftest.py sets it for the session)."""
    monkeypatch.setenv(run_lock.LOCKS_ENV, str(TEST_LOCKS))
    return TEST_LOCKS



def bench(run_dir: Path, *args: str) -> list[str]:
    return [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", str(REPO / "tasks"), "--results-dir",
            str(run_dir), *args]


def holder(run_dir: Path, keep: bool = False) -> subprocess.Popen:
    """A real process holding the run lock of `run_dir` (as a run's controller does) until its stdin gets a line."""
    proc = subprocess.Popen([sys.executable, "-c", HOLD, str(run_dir), "keep" if keep else "-"], cwd=REPO,
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "held"
    return proc


def dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def labels_of(run_dir: Path, pid: int) -> dict[str, str]:
    import socket

    return {LABEL_RUN: resource_id(run_dir), LABEL_WORKER: "gw1", LABEL_HOST: socket.gethostname(),
            LABEL_PID: str(pid)}


def wait_for(predicate, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(0.2)
    raise AssertionError(f"timed out waiting for {what}")


def test_a_second_run_on_a_live_runs_folder_is_refused_before_it_writes(tmp_path):
    """Run A holds its folder from its first moment (here: while its model check waits on a stalled endpoint);
    run B on the same --results-dir exits 4 naming the folder and A's pid, and writes nothing there."""
    run_dir = tmp_path / "shared"
    with FakeChatServer(models=("planner", "grounder")) as fake:
        fake.probe_reply = stall(120)  # A's model check waits (up to its 30 s limit): A is live, at start-up
        first = subprocess.Popen(bench(run_dir, "-p", "no:xdist", "--agent", "holo2", "--planner-base-url", fake.url,
                                       "--planner-model", "planner", "--grounder-base-url", fake.url,
                                       "--grounder-model", "grounder", "-k", "thunar-rename_file"),
                                 cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            wait_for(lambda: fake.received >= 1, 60, "run A's model check")
            before = sorted(p.name for p in run_dir.iterdir())
            second = subprocess.run(bench(run_dir, "-p", "no:xdist", "--agent", "noop", "-k", "no-such-task"),
                                    cwd=REPO, capture_output=True, text=True, timeout=120)
            out = second.stdout + second.stderr
            assert second.returncode == 4, out
            assert "Traceback" not in out and "INTERNALERROR" not in out, out
            error = [line for line in out.splitlines() if line.startswith("ERROR:")]
            assert len(error) == 1 and str(run_dir) in error[0] and f"pid {first.pid}" in error[0], out
            assert sorted(p.name for p in run_dir.iterdir()) == before  # not a byte from B (no run.json, no report)
            assert first.poll() is None  # A goes on
        finally:
            first.send_signal(signal.SIGKILL)  # however A dies, its folder is free again
            first.wait(timeout=30)
    third = subprocess.run(bench(run_dir, "-p", "no:xdist", "--agent", "noop", "-k", "no-such-task"),
                           cwd=REPO, capture_output=True, text=True, timeout=120)
    assert third.returncode == 5, third.stdout + third.stderr  # taken: nothing selected, nothing refused


def test_a_live_run_on_another_host_is_seen_through_its_heartbeat(tmp_path):
    """No lock of this host guards a folder a run on another host writes into: its fresh run.json heartbeat does."""
    import json

    from jarvis_pytest.errors import ConfigError
    from jarvis_pytest.results.writer import now_iso

    run_dir = tmp_path / "shared-over-nfs"
    run_dir.mkdir()
    (run_dir / "run.json").write_text(json.dumps({"format": "jarvis-pytest run", "state": "running", "pid": 4242,
                                                  "host": "elsewhere", "heartbeat": now_iso()}))
    with pytest.raises(ConfigError, match="pid 4242 on elsewhere"):
        run_lock.RunLock(run_dir).acquire()
    assert not run_lock.is_live(resource_id(run_dir))  # refused: it let the lock go


def test_live_runs_and_kept_devices_are_never_orphans(tmp_path):
    """A resource made by a worker that is gone is an orphan only once its run's controller is gone too, and
    never when that run kept its devices; `forget` (what `jarvis cleanup --kept` does after removing them) ends
    that."""
    live_dir, kept_dir, dead_dir = tmp_path / "live", tmp_path / "kept", tmp_path / "dead"
    gone = dead_pid()
    controller = holder(live_dir)
    try:
        assert not is_orphan(labels_of(live_dir, gone))  # a replaced xdist worker of a live run
    finally:
        controller.communicate("\n", timeout=30)
    assert is_orphan(labels_of(live_dir, gone))  # the run ended: what is left is its leftovers
    kept = holder(kept_dir, keep=True)
    assert not is_orphan(labels_of(kept_dir, gone)) and not is_kept(labels_of(kept_dir, gone))  # live, not yet kept
    kept.communicate("\n", timeout=30)
    assert not is_orphan(labels_of(kept_dir, gone)) and is_kept(labels_of(kept_dir, gone))
    assert resource_id(kept_dir) in run_lock.kept_runs()
    run_lock.forget(resource_id(kept_dir))
    assert is_orphan(labels_of(kept_dir, gone)) and not is_kept(labels_of(kept_dir, gone))
    assert is_orphan(labels_of(dead_dir, gone))  # a run without any lock (an older version, or killed)
    assert not is_orphan(labels_of(dead_dir, os.getpid()))  # its maker still runs


@pytest.mark.containers
def test_sweeps_leave_live_and_kept_runs_alone_and_cleanup_kept_removes_them(tmp_path, only_kept_test):
    """Real labelled containers and networks (created, never started): the orphan sweep (as every run's start-up
    does, narrowed here to these runs) removes the dead run's and keeps the live and the kept run's; `jarvis
    cleanup --list` names the kept run's; `jarvis cleanup --kept` removes them and forgets the run."""
    import docker

    client = docker.from_env()
    image = next(t for i in client.images.list() for t in i.tags if t.startswith("jarvis/"))
    gone = dead_pid()
    dirs = {name: tmp_path / name for name in ("live", "kept", "dead")}
    made = []
    try:
        for name, run_dir in dirs.items():
            labels = labels_of(run_dir, gone)
            made.append(client.containers.create(image, command="true", labels=labels,
                                                 name=f"jarvis-isolation-{name}-{os.getpid()}"))
            made.append(client.networks.create(f"jarvis-isolation-{name}-{os.getpid()}", labels=labels))
        kept = holder(dirs["kept"], keep=True)
        kept.communicate("\n", timeout=30)
        controller = holder(dirs["live"])
        try:
            from jarvis_pytest.infra.cleanup import cleanup

            for run_dir in dirs.values():
                cleanup(run_id=resource_id(run_dir), orphans_only=True)

            def left(name: str) -> int:
                f = {"label": f"{LABEL_RUN}={resource_id(dirs[name])}"}
                return len(client.api.containers(all=True, filters=f)) + len(client.api.networks(filters=f))

            assert (left("live"), left("kept"), left("dead")) == (2, 2, 0)
            env = dict(os.environ)
            listed = subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "cleanup", "--list"], cwd=REPO,
                                    env=env, capture_output=True, text=True, timeout=120)
            assert listed.returncode == 0, listed.stderr
            assert resource_id(dirs["kept"]) in listed.stdout and f"jarvis-isolation-kept-{os.getpid()}" in listed.stdout
            assert resource_id(dirs["live"]) not in listed.stdout
            removed = subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "cleanup", "--kept"], cwd=REPO,
                                     env=env, capture_output=True, text=True, timeout=120)
            assert removed.returncode == 0, removed.stderr
            assert "removed (devices kept with --keep-devices by ended runs)" in removed.stdout, removed.stdout
            assert (left("live"), left("kept")) == (2, 0)
            assert resource_id(dirs["kept"]) not in run_lock.kept_runs()
        finally:
            controller.communicate("\n", timeout=30)
    finally:
        for resource in made:
            try:
                resource.remove(force=True) if hasattr(resource, "status") else resource.remove()
            except docker.errors.NotFound:
                pass


@pytest.mark.containers
def test_devices_kept_by_a_run_outlive_the_next_runs_start_up(tmp_path, only_kept_test):
    """A real run with --keep-devices leaves its devices; the next, unrelated run's start-up sweep leaves them
    too; `jarvis cleanup --kept` removes them."""
    import docker

    kept_dir = tmp_path / "kept-run"
    first = subprocess.run(bench(kept_dir, "-p", "no:xdist", "--agent", "noop", "-k", "thunar-rename_file",
                                 "--instances", "1", "--keep-devices"), cwd=REPO, capture_output=True, text=True,
                           timeout=300)
    assert "1 failed" in first.stdout, first.stdout + first.stderr  # noop fails the task; its devices stay
    api = docker.from_env().api
    label = {"label": f"{LABEL_RUN}={resource_id(kept_dir)}"}
    kept = sorted(n for c in api.containers(all=True, filters=label) for n in c["Names"])
    try:
        assert kept, first.stdout + first.stderr
        second = subprocess.run(bench(tmp_path / "next-run", "-p", "no:xdist", "--agent", "noop", "-k",
                                      "no-such-task"), cwd=REPO, capture_output=True, text=True, timeout=300)
        assert second.returncode == 5, second.stdout + second.stderr
        assert sorted(n for c in api.containers(all=True, filters=label) for n in c["Names"]) == kept
        # a sweep that reads another run-lock folder knows nothing of the run's record: the keep label holds them
        other = dict(os.environ, JARVIS_RUN_LOCKS=str(tmp_path / "other-locks"))
        swept = subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "cleanup"], cwd=REPO, env=other,
                               capture_output=True, text=True, timeout=120)
        assert swept.returncode == 0, swept.stderr
        assert sorted(n for c in api.containers(all=True, filters=label) for n in c["Names"]) == kept
        assert resource_id(kept_dir) in swept.stdout  # listed as kept, with how to remove it
    finally:
        removed = subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "cleanup", "--kept"], cwd=REPO,
                                 capture_output=True, text=True, timeout=120)
    assert removed.returncode == 0, removed.stderr
    assert api.containers(all=True, filters=label) == [] and api.networks(filters=label) == []


@pytest.mark.containers
def test_a_run_removes_its_folders_dead_sessions_leftovers_at_start_up_unless_they_were_kept(tmp_path, only_kept_test):
    """What an earlier, dead session of the same folder left goes when the folder's next run starts (the lock of
    the new run makes its run id live, so the orphan rule alone would keep it); devices that session kept stay,
    and stay kept after the next run."""
    import docker

    client = docker.from_env()
    image = next(t for i in client.images.list() for t in i.tags if t.startswith("jarvis/"))
    gone = dead_pid()
    made = []
    try:
        for name, keep in (("plain", False), ("kept", True)):
            run_dir = tmp_path / name
            holder(run_dir, keep=keep).communicate("\n", timeout=30)  # the earlier session, ended
            made.append(client.containers.create(image, command="true", labels=labels_of(run_dir, gone),
                                                 name=f"jarvis-isolation-{name}-{os.getpid()}"))
            proc = subprocess.run(bench(run_dir, "-p", "no:xdist", "--agent", "noop", "-k", "no-such-task"),
                                  cwd=REPO, capture_output=True, text=True, timeout=300)
            assert proc.returncode == 5, proc.stdout + proc.stderr
            f = {"label": f"{LABEL_RUN}={resource_id(run_dir)}"}
            assert len(client.api.containers(all=True, filters=f)) == (1 if keep else 0), name
        f = {"label": f"{LABEL_RUN}={resource_id(tmp_path / 'kept')}"}
        assert len(client.api.containers(all=True, filters=f)) == 1
        assert resource_id(tmp_path / "kept") in run_lock.kept_runs()
    finally:
        for c in made:
            try:
                c.remove(force=True)
            except docker.errors.NotFound:
                pass
        run_lock.forget(resource_id(tmp_path / "kept"))


def test_prune_forgets_what_killed_runs_left_and_keeps_kept_and_live_runs(tmp_path):
    killed, live, kept = (holder(tmp_path / n, keep=(n == "kept")) for n in ("killed", "live", "kept"))
    killed.kill()
    killed.wait(timeout=30)
    kept.communicate("\n", timeout=30)
    try:
        paths = {n: run_lock.lock_path(resource_id(tmp_path / n)) for n in ("killed", "live", "kept")}
        assert all(p.exists() for p in paths.values())
        run_lock.prune()
        assert (paths["killed"].exists(), paths["live"].exists(), paths["kept"].exists()) == (False, True, True)
        assert run_lock.is_live(resource_id(tmp_path / "live"))
    finally:
        live.communicate("\n", timeout=30)
        run_lock.forget(resource_id(tmp_path / "kept"))
