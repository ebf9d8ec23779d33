"""A golden: the folder a VM's tasks start from, and the rules that decide whether they may.

    <golden>/                 the base files a profile names (disk, kernel, firmware): never written
    <golden>/snapshot/        written by `prepare` (the runner), nothing else:
        disk.qcow2            an overlay of the base disk: the disk as it was when the memory was saved
        <firmware vars>       the UEFI variables as they were then (each task copies them)
        vmstate               the memory and device state (QEMU's migration stream)
        READY                 JSON: the profile, the QEMU version, the source (image digest), the sizes and
                              modification times of every file above, the state's size and SHA-256

READY is written last, and only once the state stream is complete (`check_stream`). A task restores only from a
golden whose READY names the same machine profile and QEMU version, whose files have not changed since, and whose
state has the recorded size (`check`). Each violation is one ConfigError naming the file, the field and the fix.
"""

from __future__ import annotations

import hashlib
import json
import os
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from jarvis_pytest.devices.vm.profile import Profile
from jarvis_pytest.errors import ConfigError

SNAPSHOT = "snapshot"
DISK = "disk.qcow2"
STATE = "vmstate"
READY = "READY"
FORMAT = 1  # of READY

MAGIC = b"QEVM\x00\x00\x00\x03"   # QEMU's migration stream, version 3
EOF_MARK, VMDESC = 0x00, 0x06        # QEMU_VM_EOF, then QEMU_VM_VMDESCRIPTION: be32 length and JSON, at the end
TAIL_SEARCH = 8 << 20                # bytes of the stream's end searched for that description


@dataclass
class Record:
    """What READY says about a prepared golden."""

    profile: Profile
    qemu: str                             # `qemu-system-x86_64 --version`, first line
    source: dict[str, Any]                # where the base disk came from (e.g. the guest image and its digest)
    state_bytes: int
    state_sha256: str
    files: dict[str, list[int]]           # path in the golden → [size, mtime_ns] when READY was written
    created: float                        # epoch seconds when the memory was saved
    outputs: list[str] = field(default_factory=list)   # stdout of the commands run before the snapshot
    timings: dict[str, float] = field(default_factory=dict)

    def to_json(self) -> str:
        data = {"format": FORMAT, "profile": self.profile.to_dict(), "qemu": self.qemu, "source": self.source,
                "state_bytes": self.state_bytes, "state_sha256": self.state_sha256, "files": self.files,
                "created": self.created, "outputs": self.outputs, "timings": self.timings}
        return json.dumps(data, indent=2, sort_keys=True) + "\n"


def snapshot_dir(golden: Path) -> Path:
    return Path(golden) / SNAPSHOT


def ready_path(golden: Path) -> Path:
    return snapshot_dir(golden) / READY


def read(golden: Path) -> Record:
    """READY of `golden`, or a ConfigError saying the golden is not prepared (or READY is damaged)."""
    path = ready_path(golden)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise ConfigError("this golden has no saved memory state (prepare never finished)", path=path,
                          fix="prepare it: `prepare_snapshot(golden, profile, ...)`") from None
    except (OSError, ValueError) as exc:
        raise ConfigError(f"cannot read the golden's record: {exc}", path=path,
                          fix="prepare the golden again (its snapshot folder is rewritten)") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ConfigError(f"not a golden record of format {FORMAT}", path=path, field="format",
                          fix="prepare the golden again with this version of jarvis-pytest")
    try:
        return Record(profile=Profile.from_dict(data["profile"], where=str(path)), qemu=data["qemu"],
                      source=data["source"], state_bytes=data["state_bytes"], state_sha256=data["state_sha256"],
                      files=data["files"], created=data["created"], outputs=data.get("outputs", []),
                      timings=data.get("timings", {}))
    except KeyError as exc:
        raise ConfigError(f"the record lacks {exc.args[0]!r}", path=path, field=exc.args[0],
                          fix="prepare the golden again") from None


def file_stamp(path: Path) -> list[int]:
    st = path.stat()
    return [st.st_size, st.st_mtime_ns]


def recorded_files(golden: Path, profile: Profile) -> list[str]:
    """The golden's files whose change would make the saved state a lie: the base files, the snapshot's disk and
    variables, the state."""
    snap = [f"{SNAPSHOT}/{DISK}", f"{SNAPSHOT}/{STATE}"]
    if profile.firmware_vars:
        snap.append(f"{SNAPSHOT}/{profile.firmware_vars}")
    return [f for f in profile.files() if f != profile.firmware_vars] + snap


def check(golden: Path, profile: Profile, qemu: str | None = None) -> Record:
    """The golden's record, if a task with `profile` (and, given, QEMU `qemu`) may restore from it; else the
    ConfigError that says why and what to do."""
    golden = Path(golden)
    record = read(golden)
    where = ready_path(golden)
    differ = record.profile.differences(profile)
    if differ:
        shown = "; ".join(f"{name}: saved {getattr(record.profile, name)!r}, asked {getattr(profile, name)!r}"
                          for name in differ)
        raise ConfigError(f"the machine profile differs from the one the memory was saved with ({shown})",
                          path=where, field=f"profile.{differ[0]}",
                          fix="restore with the recorded profile, or prepare the golden again with this one")
    if qemu is not None and qemu != record.qemu:
        raise ConfigError(f"saved by {record.qemu!r}, restoring with {qemu!r}: a memory state loads only into the "
                          "QEMU that wrote it", path=where, field="qemu",
                          fix="prepare the golden again with this runner image (`jarvis images build --only "
                              "vm-runner` changed QEMU)")
    state = snapshot_dir(golden) / STATE
    try:
        size = state.stat().st_size
    except FileNotFoundError:
        raise ConfigError("the golden's memory state is missing", path=state, fix="prepare the golden again") from None
    if size != record.state_bytes:
        raise ConfigError(f"the memory state has {size} bytes, the record {record.state_bytes}: incomplete",
                          path=state, field="state_bytes", fix="prepare the golden again")
    with state.open("rb") as f:
        if f.read(len(MAGIC)) != MAGIC:
            raise ConfigError("not a QEMU migration stream (version 3)", path=state,
                              fix="prepare the golden again")
    for rel, stamp in sorted(record.files.items()):
        path = golden / rel
        try:
            now = file_stamp(path)
        except FileNotFoundError:
            raise ConfigError("a file of the golden is missing", path=path, field=f"files.{rel}",
                              fix="prepare the golden again") from None
        if now != list(stamp):
            raise ConfigError(f"changed since its memory was saved (size, mtime {now} != recorded {stamp}): the "
                              "guest's memory no longer matches its disk", path=path, field=f"files.{rel}",
                              fix="never write a golden's files; prepare it again")
    return record


def check_stream(path: Path) -> None:
    """Raise ConfigError unless `path` is a complete QEMU migration stream: its header, and at its very end the
    end-of-state mark followed by the device description QEMU writes last (a stream cut anywhere lacks it)."""
    path = Path(path)
    size = path.stat().st_size
    with path.open("rb") as f:
        if f.read(len(MAGIC)) != MAGIC:
            raise ConfigError("not a QEMU migration stream (version 3)", path=path, fix="prepare the golden again")
        start = max(len(MAGIC), size - TAIL_SEARCH)
        f.seek(start)
        tail = f.read()
    at = tail.rfind(bytes([VMDESC]))
    while at > 0:
        (length,) = struct.unpack(">I", tail[at + 1:at + 5]) if at + 5 <= len(tail) else (-1,)
        if at + 5 + length == len(tail) and tail[at - 1] == EOF_MARK:
            try:
                json.loads(tail[at + 5:])
                return
            except ValueError:
                break
        at = tail.rfind(bytes([VMDESC]), 0, at)
    raise ConfigError(f"the memory state ({size} bytes) does not end with QEMU's end mark and device description: "
                      "it is incomplete", path=path, fix="prepare the golden again")


def sha256_of(path: Path) -> str:
    h = hashlib.sha256()
    with Path(path).open("rb") as f:
        while chunk := f.read(1 << 20):
            h.update(chunk)
    return h.hexdigest()


def write_record(golden: Path, record: Record) -> None:
    """Write READY atomically (a reader sees no READY or a whole one)."""
    path = ready_path(golden)
    tmp = path.with_name(f".{READY}.{os.getpid()}")
    tmp.write_text(record.to_json())
    os.replace(tmp, path)
