"""The transfer drive's ledger as evaluators see it: which versions of which files the drive received, and which of
them someone took off the drive, between two marks (the start and the end of the agent's turn).

The drive records it (`fixtures/images/transfer/ledger.py`) where no task can change it, for uploads over HTTP and
for files written straight into its storage alike; the harness reads it after the agent's turn
(`TaskEnvironment.drive_ledger`) and hands it to evaluators as `FinalState.ledger`.
"""

from __future__ import annotations

import json
import posixpath
from dataclasses import dataclass
from typing import Callable

from jarvis_pytest.errors import InfrastructureError


@dataclass(frozen=True)
class Version:
    """One version of a file the drive received: a write closed, or a file moved in."""

    seq: int          # its place in the ledger
    path: str         # on the drive, e.g. /data/report.txt
    sha256: str
    size: int
    time: float       # wall-clock seconds (the drive's clock)
    stored: bool      # its bytes were kept (the ledger keeps up to 256 MiB a task)
    served: int = 0   # how often it was read (downloaded, copied off the drive) while it was the file's content

    @property
    def name(self) -> str:
        return posixpath.basename(self.path)

    def describe(self) -> str:
        return f"{self.path} (sha256 {self.sha256[:16]}, {self.size} bytes, served {self.served}×)"


class DriveLedger:
    """The versions a drive received between two marks, with how often each was served."""

    def __init__(self, records: list[dict], read_object: Callable[[str], bytes | None] | None = None,
                 start: int | None = None, end: int | None = None):
        self.records = sorted(records, key=lambda r: r.get("seq", 0))
        self.read_object = read_object
        self.start, self.end = start, end
        self._content: dict[str, bytes | None] = {}
        if any(r.get("ev") == "overflow" for r in self.records):
            raise InfrastructureError("the transfer drive's ledger overflowed (the kernel dropped file events): what "
                                      "the task moved through the drive cannot be proven")
        self._versions = self._replay()

    @classmethod
    def parse(cls, text: str, read_object: Callable[[str], bytes | None] | None = None) -> "DriveLedger":
        """A ledger from the drive's JSON lines (the whole generation; narrow it with `between`)."""
        records = []
        for line in text.splitlines():
            if line.strip():
                try:
                    records.append(json.loads(line))
                except json.JSONDecodeError as exc:
                    raise InfrastructureError(f"the transfer drive's ledger has a broken record ({exc}): "
                                              f"{line[:200]!r}") from exc
        return cls(records, read_object)

    def between(self, start: int | None, end: int | None) -> "DriveLedger":
        """The same ledger narrowed to what happened after mark `start` (None: from the drive's start) and before
        mark `end` (None: to now)."""
        return DriveLedger(self.records, self.read_object, start, end)

    def _mark_seq(self, n: int | None, default: float) -> float:
        if n is None:
            return default
        for r in self.records:
            if r.get("ev") == "mark" and r.get("n") == n:
                return r["seq"]
        raise InfrastructureError(f"the transfer drive's ledger has no mark {n}")

    def window(self) -> list[dict]:
        """The records between the two marks (the marks included), as the drive wrote them."""
        lo, hi = self._mark_seq(self.start, 0), self._mark_seq(self.end, float("inf"))
        return [r for r in self.records if lo <= r.get("seq", 0) <= hi]

    def _replay(self) -> list[Version]:
        lo, hi = self._mark_seq(self.start, 0), self._mark_seq(self.end, float("inf"))
        current: dict[str, int] = {}   # path → index in `out` of its content now (versions in the window only)
        out: list[Version] = []
        for r in self.records:
            seq, ev, path = r.get("seq", 0), r.get("ev"), r.get("path")
            if seq >= hi:
                break
            inside = seq > lo
            if ev == "write":
                current.pop(path, None)
                if inside:
                    out.append(Version(seq=seq, path=path, sha256=r["sha256"], size=r["size"], time=r.get("t", 0.0),
                                       stored=bool(r.get("stored"))))
                    current[path] = len(out) - 1
            elif ev == "read" and inside and path in current:
                v = out[current[path]]
                out[current[path]] = Version(v.seq, v.path, v.sha256, v.size, v.time, v.stored, v.served + 1)
            elif ev in ("gone", "link", "other"):
                current.pop(path, None)
        return out

    @property
    def versions(self) -> list[Version]:
        """Every version received in the window, in order."""
        return list(self._versions)

    def named(self, name: str, casefold: bool = False) -> list[Version]:
        """The versions of files called `name` (a base name; anywhere on the drive), in order."""
        want = name.casefold() if casefold else name
        return [v for v in self._versions if (v.name.casefold() if casefold else v.name) == want]

    def content(self, sha256: str) -> bytes | None:
        """The bytes of a received version (None: not kept)."""
        if sha256 not in self._content:
            self._content[sha256] = self.read_object(sha256) if self.read_object else None
        return self._content[sha256]
