"""The host side of the transfer drive's ledger (`fixtures/images/transfer/ledger.py`): ask for a mark, read the
records and the bytes of a received version.

The ledger lives in the drive container's own file system, out of the reach of the drive's users; the harness reads
it through the engine (`get_archive`), never through the drive's HTTP server. A mark is asked for with a signal to
the drive's PID 1 and is there once the drive says `mark <generation> <n>` on its standard output (as a renewal is
awaited: `Lifecycle._renewed`).
"""

from __future__ import annotations

import io
import tarfile
import time
from typing import Any

from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.infra.transfer_server import drive_said

EVENTS = "/run/jarvis-ledger/events"
OBJECTS = "/run/jarvis-ledger/objects"
MARK_TIMEOUT = 10.0   # seconds the drive may take to write a mark (a drain of queued events; milliseconds here)
MARK_POLL = 0.02


def mark(container: Any, signal: str, timeout: float = MARK_TIMEOUT) -> int:
    """Ask the drive for a mark in its ledger; return its number once every event before the request is recorded.
    An InfrastructureError when the drive does not answer in `timeout` seconds (its ledger watcher is gone)."""
    generation, before = drive_said(container)
    try:
        container.kill(signal=signal)
    except Exception as exc:
        raise InfrastructureError(f"cannot signal the transfer drive {container.name} for a ledger mark: {exc}") from exc
    deadline = time.monotonic() + timeout
    while True:
        said = drive_said(container)
        if said[0] == generation and said[1] > before:
            return said[1]
        if time.monotonic() > deadline:
            raise InfrastructureError(f"the transfer drive {container.name} wrote no ledger mark within {timeout:g} s "
                                      f"(it last said generation {said[0]}, mark {said[1]}): its ledger watcher is "
                                      "gone, so what the task moved through the drive cannot be proven")
        time.sleep(MARK_POLL)


def read_file(container: Any, path: str) -> bytes | None:
    """The bytes of the file at `path` in the container (through the engine), or None when there is none."""
    import docker.errors

    try:
        stream, _ = container.get_archive(path)
    except docker.errors.NotFound:
        return None
    except Exception as exc:
        raise InfrastructureError(f"cannot read {path} of the transfer drive {container.name}: {exc}") from exc
    with tarfile.open(fileobj=io.BytesIO(b"".join(stream))) as tar:
        member = tar.next()
        handle = tar.extractfile(member) if member is not None else None
        return handle.read() if handle is not None else None


def read_events(container: Any) -> str:
    """The ledger's records of the drive's current generation (JSON lines)."""
    data = read_file(container, EVENTS)
    if data is None:
        raise InfrastructureError(f"the transfer drive {container.name} has no ledger ({EVENTS})")
    return data.decode("utf-8", errors="replace")


def read_object(container: Any, sha256: str) -> bytes | None:
    """The bytes of a version the drive received, by its SHA-256 (None: not kept, e.g. past the ledger's limit)."""
    if len(sha256) != 64 or any(c not in "0123456789abcdef" for c in sha256):
        return None
    return read_file(container, f"{OBJECTS}/{sha256}")
