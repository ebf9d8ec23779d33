"""The drive's ledger watcher (`fixtures/images/transfer/ledger.py`) run on the host over a temporary folder: it
records new versions (with their bytes), reads by others and not its own reads for hashing, folders made later,
links without following them, and writes a mark once everything before the request is recorded. A version is
hashed when the watcher handles its close (within milliseconds): bytes rewritten before that are recorded as the
newer bytes, so the test lets the watcher catch up (a mark) where a real agent's pace would."""

from __future__ import annotations

import hashlib
import importlib.util
import json
import os
import signal
import time
from pathlib import Path

import pytest

LEDGER_SCRIPT = Path(__file__).resolve().parents[1] / "fixtures" / "images" / "transfer" / "ledger.py"


@pytest.fixture
def watched(tmp_path, monkeypatch):
    """(the drive's storage, a function that asks for a mark and returns the records so far)."""
    spec = importlib.util.spec_from_file_location("jarvis_drive_ledger", LEDGER_SCRIPT)
    ledger = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(ledger)
    home = tmp_path / "ledger"
    monkeypatch.setattr(ledger, "LEDGER_DIR", str(home))
    monkeypatch.setattr(ledger, "EVENTS", str(home / "events"))
    monkeypatch.setattr(ledger, "OBJECTS", str(home / "objects"))
    root = tmp_path / "drive"
    (root / "data").mkdir(parents=True)
    (root / "data" / "before.txt").write_bytes(b"there before")
    pid = ledger.fork_watcher(str(root), 7)
    marks = [0]

    def mark() -> list[dict]:
        marks[0] += 1
        os.kill(pid, ledger.MARK_SIGNAL)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            records = [json.loads(line) for line in (home / "events").read_text().splitlines()]
            if any(r["ev"] == "mark" and r["n"] == marks[0] for r in records):
                return records
            time.sleep(0.02)
        raise AssertionError("no mark")

    yield root, mark, home
    os.kill(pid, signal.SIGKILL)
    os.waitpid(pid, 0)


def sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def test_versions_reads_and_marks(watched):
    root, mark, home = watched
    data = root / "data"
    (data / "a.txt").write_bytes(b"made")                 # a new version
    # The watcher hashes a version by reading it, and leaves the close of its own read out by counting. A read by
    # someone else that closes while the watcher is still hashing can be merged by inotify with the watcher's own
    # close (identical events queued back to back are one) and is then lost: a known limit of the ledger (seen
    # once in make test). Here the watcher is done with the version (the mark) before the file is read.
    mark()
    assert (data / "a.txt").read_bytes() == b"made"        # someone took it off the drive
    mark()  # a version is hashed when the watcher handles its close, within milliseconds (here: by this mark)
    (data / "a.txt").write_bytes(b"made again")           # a second version, never read
    (data / "sub").mkdir()
    (data / "sub" / "b.txt").write_bytes(b"in a new folder")
    (data / "tmp.part").write_bytes(b"moved in")
    os.rename(data / "tmp.part", data / "c.txt")
    os.symlink("/etc/passwd", data / "link.txt")
    records = mark()
    events = [(r["ev"], r.get("path"), r.get("sha256")) for r in records]
    assert events[0] == ("write", "/data/before.txt", sha(b"there before"))  # found when the watch began
    a = [e for e in events if e[1] == "/data/a.txt"]
    assert a == [("write", "/data/a.txt", sha(b"made")), ("read", "/data/a.txt", None),
                 ("write", "/data/a.txt", sha(b"made again"))]  # the watcher's own reads for hashing are not there
    assert ("write", "/data/sub/b.txt", sha(b"in a new folder")) in events
    assert ("write", "/data/c.txt", sha(b"moved in")) in events and ("gone", "/data/tmp.part", None) in events
    assert not any(e[1] == "/data/link.txt" and e[0] in ("write", "read") for e in events)
    assert events[-1] == ("mark", None, None) and records[-1]["n"] == 3
    for digest in (sha(b"made"), sha(b"made again"), sha(b"in a new folder")):
        stored = (home / "objects" / digest).read_bytes()
        assert sha(stored) == digest
    # a read after the mark comes after it in the ledger
    (data / "c.txt").read_bytes()
    records = mark()
    assert [(r["ev"], r.get("path")) for r in records[-2:]] == [("read", "/data/c.txt"), ("mark", None)]
