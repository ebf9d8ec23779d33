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
    assert (data / "a.txt").read_bytes() == b"made"        # someone took it off the drive (maybe while it is hashed)
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
    assert events[-1] == ("mark", None, None) and records[-1]["n"] == 2
    for digest in (sha(b"made"), sha(b"made again"), sha(b"in a new folder")):
        stored = (home / "objects" / digest).read_bytes()
        assert sha(stored) == digest
    # a read after the mark comes after it in the ledger
    (data / "c.txt").read_bytes()
    records = mark()
    assert [(r["ev"], r.get("path")) for r in records[-2:]] == [("read", "/data/c.txt"), ("mark", None)]


def test_a_read_while_the_watcher_hashes_the_same_file_is_recorded(watched):
    """Each file read at once after it was written: the read closes while the watcher may still be hashing the
    version. The watcher's own reads make no event (a hard link in a folder it does not watch), so no read is lost
    to inotify merging it with the watcher's own close (make test lost one that way when the watcher counted its
    own closes)."""
    root, mark, _home = watched
    data = root / "data"
    big = os.urandom(1 << 20) * 12  # hashing it takes the watcher longer than reading it takes us
    for i in range(24):
        path = data / f"f{i}.txt"
        path.write_bytes(big[i:])
        path.read_bytes()
        time.sleep(0.1)  # the watcher's close then comes right after ours, where inotify would merge the two
    records = mark()
    for i in range(24):
        evs = [r["ev"] for r in records if r.get("path") == f"/data/f{i}.txt"]
        assert evs == ["write", "read"], (i, evs)
    assert not any(".jarvis-ledger" in r.get("path", "") for r in records)


def test_the_hashing_folder_cannot_be_turned_against_the_ledger(watched):
    """The hashing folder lies on the shared storage (the drive's `/`, a Windows device's `S:\\`): it is there only
    while the watcher opens a version, and whatever a device that mounts the storage puts at its name (a folder
    of squatters, a file, a link into the served folder, where the watcher's own reads would show as reads) is
    removed first: versions and reads are still recorded, nothing of the watcher's own, nothing left behind."""
    root, mark, _home = watched
    data, hashing = root / "data", root / ".jarvis-ledger"
    mark()
    assert not os.path.lexists(hashing)
    hashing.mkdir()
    for n in range(1, 10):
        (hashing / str(n)).write_bytes(b"squatter")
    (data / "one.txt").write_bytes(b"one")
    mark()
    hashing.write_bytes(b"a file in the way")
    (data / "two.txt").write_bytes(b"two")
    mark()
    hashing.symlink_to(data)
    (data / "three.txt").write_bytes(b"three")
    (data / "three.txt").read_bytes()
    records = mark()
    events = [(r["ev"], r.get("path"), r.get("sha256")) for r in records if r["ev"] != "mark"]
    assert ("write", "/data/one.txt", sha(b"one")) in events and ("write", "/data/two.txt", sha(b"two")) in events
    three = [e for e in events if e[1] == "/data/three.txt"]
    assert three == [("write", "/data/three.txt", sha(b"three")), ("read", "/data/three.txt", None)]
    assert all(e[1] in ("/data/before.txt", "/data/one.txt", "/data/two.txt", "/data/three.txt") for e in events), \
        events
    assert not os.path.lexists(hashing) and sorted(p.name for p in data.iterdir()) == [
        "before.txt", "one.txt", "three.txt", "two.txt"]
