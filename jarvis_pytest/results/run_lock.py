"""Which results folders live runs hold, and which ended runs kept their devices (`--keep-devices`).

A run's controller holds an exclusive `flock` on `<locks>/<resource id>.lock` from start-up to its end (one file
per results folder: `run_state.resource_id`). The lock lives outside the results folder, so it is taken before
anything is written there, even when the folder cannot be written. The kernel drops it when the process dies,
however it dies. xdist workers take no lock: their run is live while their controller holds it.

The file holds a JSON record of its last holder: ``{"run_dir", "pid", "host", "started", "ended",
"keep_devices"}``. It stays after the run, so that a run started with `--keep-devices` is known as kept: the
orphan sweeps (`infra/cleanup.py`) leave its devices to `jarvis cleanup --kept`, which then forgets the record.
A later run in the same folder keeps them too (and so whatever it leaves), until then.

`<locks>` is `$JARVIS_RUN_LOCKS`, else `<temp dir>/jarvis-runs` (this host only; a results folder shared between
hosts is guarded by its run.json heartbeat: `run_state.liveness`).
"""

from __future__ import annotations

import fcntl
import json
import os
import socket
import tempfile
import time
from pathlib import Path
from typing import Any

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.results.run_state import heartbeat_fresh, liveness, read_json, resource_id
from jarvis_pytest.results.writer import now_iso

LOCKS_ENV = "JARVIS_RUN_LOCKS"
ACQUIRE_WAIT = 2.0  # seconds a start-up retries a held lock (a sweep holds it for an instant to look)


def locks_dir() -> Path:
    """The folder of run locks on this host."""
    return Path(os.environ.get(LOCKS_ENV) or Path(tempfile.gettempdir()) / "jarvis-runs")


def lock_path(run_id: str) -> Path:
    """The lock file of the run whose resources carry `run_id` (label `org.jarvis.run`)."""
    return locks_dir() / f"{run_id}.lock"


def _record(path: Path) -> dict[str, Any]:
    try:
        data = json.loads(path.read_text(encoding="utf-8") or "{}")
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def is_live(run_id: str) -> bool:
    """Whether a process of this host holds the lock of run `run_id` now."""
    try:
        fd = os.open(lock_path(run_id), os.O_RDONLY)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    finally:
        os.close(fd)  # also drops the shared lock, if taken
    return False


def is_kept(run_id: str) -> bool:
    """Whether run `run_id` was started with --keep-devices and has ended (its devices wait for `jarvis cleanup
    --kept`)."""
    return bool(_record(lock_path(run_id)).get("keep_devices")) and not is_live(run_id)


def kept_runs() -> dict[str, dict[str, Any]]:
    """run id → record, for every ended run of this host that kept its devices."""
    try:
        paths = sorted(locks_dir().glob("*.lock"))
    except OSError:
        return {}
    return {p.stem: rec for p in paths if (rec := _record(p)).get("keep_devices") and not is_live(p.stem)}


def forget(run_id: str) -> None:
    """Drop the record of an ended run (after its devices were removed); nothing while it is live."""
    path = lock_path(run_id)
    try:
        fd = os.open(path, os.O_RDWR)
    except OSError:
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        if os.fstat(fd).st_ino == os.stat(path).st_ino:
            path.unlink()  # holding the lock: a run that opened the old file sees it unlinked and retries
    except (BlockingIOError, OSError):
        pass
    finally:
        os.close(fd)


def prune() -> None:
    """Forget the records of ended runs that kept nothing (a killed run leaves its lock file behind)."""
    try:
        paths = list(locks_dir().glob("*.lock"))
    except OSError:
        return
    for path in paths:
        if not _record(path).get("keep_devices"):
            forget(path.stem)  # nothing while its run is live


class RunLock:
    """The lock of one results folder, held by a run's controller from start-up to its end."""

    def __init__(self, run_dir: Path):
        self.run_dir = Path(run_dir).resolve()
        self.run_id = resource_id(self.run_dir)
        self.path = lock_path(self.run_id)
        self._fd: int | None = None
        self.keep_devices = False
        self.was_kept = False  # the folder's last run kept its devices (--keep-devices): they are still theirs

    @property
    def held(self) -> bool:
        return self._fd is not None

    def acquire(self, keep_devices: bool = False, wait: float = ACQUIRE_WAIT) -> None:
        """Take the folder for this process, or raise ConfigError naming the folder and the live run's pid."""
        if self._fd is not None:
            return
        try:
            self._take(wait)
            meta = read_json(self.run_dir / "run.json")
            if liveness(meta) == "running" and heartbeat_fresh(meta or {}):  # another host's run, or one of a
                self.release()                                                # version without this lock
                self._refuse(meta or {})
            self.was_kept = bool(_record(self.path).get("keep_devices"))
            self.keep_devices = keep_devices or self.was_kept  # kept devices stay kept until `jarvis cleanup`
            self._write({"run_dir": str(self.run_dir), "pid": os.getpid(), "host": socket.gethostname(),
                         "started": now_iso(), "ended": "", "keep_devices": self.keep_devices})
        except OSError as exc:
            self.release()
            raise ConfigError(f"cannot take the run lock {self.path} ({exc.strerror or exc})", field=LOCKS_ENV,
                              fix=f"free space in {self.path.parent} or make it writable, or set {LOCKS_ENV} to "
                                  "a folder of this host that is") from None

    def _take(self, wait: float) -> None:
        directory = self.path.parent
        if not directory.is_dir():
            directory.mkdir(parents=True, exist_ok=True)
            try:
                directory.chmod(0o1777)  # every user's runs share it, as /tmp
            except OSError:
                pass
        deadline = time.monotonic() + wait
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                if time.monotonic() < deadline:
                    time.sleep(0.1)
                    continue
                self._refuse(_record(self.path))
            try:
                same = os.fstat(fd).st_ino == os.stat(self.path).st_ino
            except OSError:
                same = False
            if same:
                break
            os.close(fd)  # `forget` removed the file after we opened it: take the new one
        self._fd = fd
        try:
            os.fchmod(fd, 0o666)  # other users' runs read who holds it, and take it after us
        except OSError:
            pass

    def _refuse(self, holder: dict[str, Any]) -> None:
        pid, host = holder.get("pid", "?"), holder.get("host") or socket.gethostname()
        since = f", since {holder['started']}" if holder.get("started") else ""
        raise ConfigError(f"a live run holds this results folder (pid {pid} on {host}{since})", path=self.run_dir,
                          fix="wait for that run to end or stop it (Ctrl-C), or give another --results-dir")

    def _write(self, record: dict[str, Any]) -> None:
        assert self._fd is not None
        data = json.dumps(record, sort_keys=True).encode()
        os.ftruncate(self._fd, 0)
        os.pwrite(self._fd, data, 0)

    def release(self) -> None:
        """Let the folder go; the record stays, saying whether the run kept its devices (idempotent)."""
        if self._fd is None:
            return
        fd, self._fd = self._fd, None
        try:
            record = _record(self.path) if self.keep_devices else {}
            if record:
                self._fd = fd
                self._write(record | {"ended": now_iso()})
                self._fd = None
            else:
                os.ftruncate(fd, 0)
        except OSError:
            pass
        finally:
            os.close(fd)
        if not self.keep_devices:
            forget(self.run_id)
