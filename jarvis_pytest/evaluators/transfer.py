"""The transfer drive's checks: a file on the drive, and a transfer proven by provenance.

A transfer is proven by what the drive's ledger (`ledger.py`) recorded during the agent's turn, not by a name on
the drive: the file at the destination must be a version of the file that the drive received and that someone
took off the drive, and that version must hold the source's bytes. So a file typed in at the destination, a
different file carried under the right name, a file carried before the upstream subtask changed it, a file left on
the drive and never taken off it, and the upstream's input carried instead of its output all fail here, each with
the hashes it compared.

Which sides are compared comes from the task graph (`FinalState.chain`, a `tasks.transfer.TransferLinks`): a side
that a subtask after the transfer changes on purpose is not compared with the drive (the received file's later
editor compares its result with the arrived bytes instead: `arrived`). Without a ledger (a drive flavour that keeps
none) the drive's final copy stands in for it, and the verdict says so.
"""

from __future__ import annotations

import hashlib
import ntpath
import posixpath
from dataclasses import dataclass

from jarvis_pytest.devices.platforms import spec
from jarvis_pytest.evaluators.file_facts import read_facts
from jarvis_pytest.evaluators.ledger import Version
from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.state import FinalState


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _said(data: bytes) -> str:
    return f"sha256 {_sha(data)[:16]} ({len(data)} bytes)"


def _listed(versions: list[Version], limit: int = 4) -> str:
    text = "; ".join(v.describe() for v in versions[-limit:])
    return text if len(versions) <= limit else f"{len(versions)} versions, the last: {text}"


def base_name(path: str) -> str:
    """The file name of a path of either platform style."""
    return ntpath.basename(path) if "\\" in path else posixpath.basename(path)


@evaluator("transfer_has_file")
def transfer_has_file(state: FinalState, name: str) -> Verdict:
    """A file named `name` (basename) is somewhere on the transfer drive now."""
    if state.transfer is None:
        return Verdict(False, "task has no transfer drive")
    names = sorted(posixpath.basename(p) for p in state.transfer.walk())
    base = posixpath.basename(name)
    return Verdict.check(base in names, f"{base!r} on the transfer drive", repr(names[:20]))


@dataclass(frozen=True)
class Decision:
    """A transfer's verdict, and the version of the file that arrived at the destination (None: none did)."""

    verdict: Verdict
    arrived: Version | None


def _links(state: FinalState) -> tuple[bool, str | None, bool]:
    chain = state.chain
    return (bool(getattr(chain, "source_changed_later", False)), getattr(chain, "destination_consumed", None),
            bool(getattr(chain, "upstream_edits_in_place", False)))


def decide(state: FinalState, source: str, source_platform: str, path: str, folder: str = "/data") -> Decision:
    """The verdict of `transfer_arrived_unchanged` and the arrived version (see the module's docstring)."""
    want = f"{path} to be {source} of the {source_platform} device, carried through the drive"
    if state.ledger is None:
        return Decision(_without_ledger(state, source, source_platform, path, folder, want), None)
    source_later, consumed, in_place = _links(state)
    name = base_name(source)
    casefold = spec(source_platform).case_insensitive_paths or spec(state.platform).case_insensitive_paths
    versions = state.ledger.named(name, casefold)
    served = [v for v in versions if v.served]
    src = None if source_later else state.pull(source, source_platform)
    matching = [v for v in served if src is not None and v.sha256 == _sha(src)]
    arrived = (matching or served or [None])[-1]

    def fail(found: str) -> Decision:
        return Decision(Verdict.check(False, want, found), arrived)

    if not versions:
        received = _listed(state.ledger.versions) if state.ledger.versions else "nothing"
        return fail(f"no file named {name} arrived on the drive during the task (it received {received})")
    if not served:
        return fail(f"{name} arrived on the drive ({_listed(versions)}) but was never taken off it (no download "
                    "or copy from the drive)")
    notes = []
    if source_later:
        notes.append("the source is not compared: a later subtask changes it")
    else:
        if src is None:
            return fail(f"no file at {source} on the {source_platform} device")
        if not matching:
            return fail(f"the drive served {_listed(served)}, but {source} holds {_said(src)}: a different file was "
                        "carried, or the source changed after it was carried")
        served = matching
    if in_place:
        setup = state.baseline(source, source_platform)
        if setup is not None:
            served = [v for v in served if v.sha256 != _sha(setup)]
            if not served:
                return fail(f"what was carried is {source} as set-up made it ({_said(setup)}): the upstream "
                            "subtask's input, not its output")
    if consumed is None:
        dst = state.pull(path)
        if dst is None:
            return fail(f"no file at {path} ({name} was taken off the drive, but not to there)")
        placed = [v for v in served if v.sha256 == _sha(dst)]
        if not placed:
            return fail(f"{path} holds {_said(dst)}, not what the drive served ({_listed(served)})")
        drive = spec(state.platform).drive_root  # where the drive shows as a drive letter on this device
        facts = read_facts(state, entries=[path] + ([drive] if drive else [])).entries
        entry = facts[path]
        if entry.kind != "file":  # e.g. a symbolic link to the drive's copy: nothing was placed
            return fail(f"{entry.describe()} at {path}, not a file of the {state.platform} device's own")
        if drive and entry.volume is not None and entry.volume == facts[drive].volume:
            # under Wine a link into the drive's storage reads as a plain file, on the drive's volume
            return fail(f"{path} is the drive's own copy on {drive} (seen through a link), not a file of the "
                        f"{state.platform} device's own")
        arrived = placed[-1]
        notes.append(f"{path} holds it")
    else:
        if consumed == "edit" and not state.exists(path):
            return fail(f"no file at {path}: {name} was taken off the drive but not placed there")
        arrived = served[-1]
        notes.append(f"{path} is not compared: a later subtask {'edits' if consumed == 'edit' else consumed + 's'} "
                     "it, and compares its result with these bytes")
    return Decision(Verdict.check(True, want, f"{arrived.describe()} arrived through the drive; "
                                  + "; ".join(notes)), arrived)


def _without_ledger(state: FinalState, source: str, source_platform: str, path: str, folder: str,
                    want: str) -> Verdict:
    """The drive keeps no ledger (e.g. the alist flavour): its final copy stands in for what it served."""
    if state.transfer is None:
        return Verdict.check(False, want, "a task without a transfer drive")
    source_later, consumed, _ = _links(state)
    name = base_name(source)
    try:
        copies = [("drive", state.transfer.download(f"{folder.rstrip('/')}/{name}"))]
    except FileNotFoundError:
        return Verdict.check(False, want, f"no {name} in the drive's {folder}")
    for side, flag, data in (("source", source_later, lambda: state.pull(source, source_platform)),
                             ("destination", consumed is not None, lambda: state.pull(path))):
        if not flag:
            got = data()
            if got is None:
                return Verdict.check(False, want, f"no {side} file")
            copies.append((side, got))
    same = len({_sha(d) for _, d in copies}) == 1
    return Verdict.check(same, want, ", ".join(f"{side} {_said(d)}" for side, d in copies)
                         + " (the drive keeps no ledger: its final copy was compared, not what it served)")


@evaluator("transfer_arrived_unchanged")
def transfer_arrived_unchanged(state: FinalState, source: str, source_platform: str, path: str,
                               folder: str = "/data") -> Verdict:
    """The file `source` on `source_platform` went through the drive and arrived at `path` on this subtask's
    device: the destination holds a version of the file the drive received and served during the agent's turn,
    with the source's bytes (sides a later subtask changes on purpose excepted; see the module's docstring)."""
    return decide(state, source, source_platform, path, folder).verdict
