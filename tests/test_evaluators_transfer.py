"""The transfer evaluator against the drive's ledger, without containers: which cheap wrong chains it rejects, and
which side a later subtask may change (decided by the graph's order). The drive's own recording of events runs in
`test_infra_transfer.py`."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest

from jarvis_pytest.evaluators.ledger import DriveLedger
from jarvis_pytest.evaluators.state import FinalState
from jarvis_pytest.evaluators import transfer as transfer_module
from jarvis_pytest.evaluators.file_facts import Entry, Facts
from jarvis_pytest.evaluators.transfer import decide
from jarvis_pytest.harness.evaluation import evaluate_subtasks
from jarvis_pytest.tasks.compose import Draft, Link, build
from jarvis_pytest.tasks.library import load_library
from jarvis_pytest.tasks.transfer import TransferLinks, transfer_links
from tests.file_state import _FilesDevice

REPO = Path(__file__).resolve().parents[1]
SOURCE, DEST = "/home/user/notes.txt", "C:\\Users\\user\\Downloads\\transfer\\notes.txt"
MADE = b"first line\nsecond line\n"       # what the upstream subtask made
SETUP = b"first line\n"                   # what set-up made, before the upstream edited it in place


def sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


class Recorder:
    """Writes a ledger as the drive's watcher does (JSON lines), with the bytes it keeps."""

    def __init__(self):
        self.records, self.objects = [], {}

    def add(self, ev: str, path: str | None = None, **facts) -> "Recorder":
        rec = {"seq": len(self.records) + 1, "t": 0.0, "ev": ev, **facts}
        if path is not None:
            rec["path"] = path
        self.records.append(rec)
        return self

    def write(self, path: str, data: bytes) -> "Recorder":
        self.objects[sha(data)] = data
        return self.add("write", path, sha256=sha(data), size=len(data), stored=True)

    def read(self, path: str) -> "Recorder":
        return self.add("read", path)

    def mark(self) -> "Recorder":
        return self.add("mark", n=sum(r["ev"] == "mark" for r in self.records) + 1)

    def ledger(self, start: int | None = 1, end: int | None = 2) -> DriveLedger:
        text = "\n".join(json.dumps(r) for r in self.records)
        return DriveLedger.parse(text, self.objects.get).between(start, end)


@pytest.fixture(autouse=True)
def destination_kind(monkeypatch):
    """What the destination is (a file, unless a test says otherwise); the device-side reading of file facts is
    tested with the devices (`test_evaluators_file_facts.py`, `test_transfer_ledger.py`)."""
    kinds = {"kind": "file"}

    def read_facts(state, entries=(), **_):
        return Facts(entries={p: Entry(exists=True, kind=kinds["kind"], size=1) for p in entries}, trees={})

    monkeypatch.setattr(transfer_module, "read_facts", read_facts)
    return kinds


def state(ledger, source: bytes | None = MADE, dest: bytes | None = MADE, links=None,
          setup: bytes | None = None) -> FinalState:
    ubuntu = {SOURCE: source} if source is not None else {}
    windows = {DEST: dest} if dest is not None else {}
    baselines = {("ubuntu", SOURCE): setup} if setup is not None else {}
    return FinalState(platform="windows", devices={"ubuntu": _FilesDevice(ubuntu), "windows": _FilesDevice(windows)},
                      ledger=ledger, chain=links or TransferLinks(), baselines=baselines)


def verdict(st: FinalState):
    return decide(st, SOURCE, "ubuntu", DEST)


def carried(data: bytes = MADE) -> Recorder:
    return Recorder().mark().write("/data/notes.txt", data).read("/data/notes.txt")


def test_a_file_uploaded_then_downloaded_passes_and_says_what_arrived():
    d = verdict(state(carried().mark().ledger()))
    assert d.verdict.passed, d.verdict.reason
    assert d.arrived.sha256 == sha(MADE) and d.arrived.served == 1
    assert sha(MADE)[:16] in d.verdict.reason


@pytest.mark.parametrize("name, ledger, dest, words", [
    ("transfer skipped, destination made up", Recorder().mark().mark(), MADE, "no file named notes.txt arrived"),
    ("uploaded, destination typed in, never downloaded", Recorder().mark().write("/data/notes.txt", MADE).mark(),
     MADE, "never taken off it"),
    ("a different file carried under the right name", carried(b"other\n").mark(), b"other\n", "a different file"),
    ("an empty file on the drive", carried(b"").mark(), b"", sha(b"")[:16]),
    ("downloaded, then the destination overwritten by hand", carried().mark(), b"typed\n", "not what the drive served"),
    ("uploaded and never placed", carried().mark(), None, "no file at"),
])
def test_broken_chains_fail_with_the_hashes(name, ledger, dest, words):
    d = verdict(state(ledger.ledger(), dest=dest))
    assert not d.verdict.passed, name
    assert words in d.verdict.reason, d.verdict.reason


def test_a_link_at_the_destination_is_not_a_placed_file(destination_kind):
    destination_kind["kind"] = "link"
    d = verdict(state(carried().mark().ledger()))
    assert not d.verdict.passed and "a link at" in d.verdict.reason


def test_a_different_file_names_both_hashes():
    d = verdict(state(carried(b"other\n").mark().ledger(), dest=b"other\n"))
    assert sha(b"other\n")[:16] in d.verdict.reason and sha(MADE)[:16] in d.verdict.reason


def test_carried_before_the_upstream_edit_fails_even_if_re_uploaded_later():
    """The pre-edit file went through the drive; the edited one was uploaded afterwards but never taken off."""
    rec = Recorder().mark().write("/data/notes.txt", SETUP).read("/data/notes.txt").write("/data/notes.txt", MADE)
    d = verdict(state(rec.mark().ledger(), dest=SETUP))
    assert not d.verdict.passed and "a different file was carried" in d.verdict.reason


def test_a_read_counts_only_for_the_version_it_read():
    rec = Recorder().mark().write("/data/notes.txt", b"v1").read("/data/notes.txt").write("/data/notes.txt", b"v2")
    versions = rec.mark().ledger().named("notes.txt")
    assert [(v.served, v.size) for v in versions] == [(1, 2), (0, 2)]


def test_what_happened_outside_the_agents_turn_does_not_count():
    """A version written at set-up (before the first mark), or served after the last, is not the agent's."""
    rec = Recorder().write("/data/notes.txt", MADE).mark().read("/data/notes.txt").mark().read("/data/notes.txt")
    assert rec.ledger(1, 2).named("notes.txt") == []
    late = Recorder().mark().write("/data/notes.txt", MADE).mark().read("/data/notes.txt")
    assert not verdict(state(late.ledger(1, 2))).verdict.passed


def test_the_upstreams_input_carried_instead_of_its_output_fails():
    """The upstream edits the file in place and was skipped: source, drive and destination agree, on the set-up
    bytes."""
    links = TransferLinks(upstream=0, upstream_edits_in_place=True)
    d = verdict(state(carried(SETUP).mark().ledger(), source=SETUP, dest=SETUP, links=links, setup=SETUP))
    assert not d.verdict.passed and "input, not its output" in d.verdict.reason
    ok = verdict(state(carried().mark().ledger(), links=links, setup=SETUP))
    assert ok.verdict.passed, ok.verdict.reason


def test_a_destination_edited_later_is_not_compared_but_must_be_placed():
    links = TransferLinks(destination_consumed="edit")
    edited = b"first line\r\nsecond line\r\n"
    assert verdict(state(carried().mark().ledger(), dest=edited, links=links)).verdict.passed
    unplaced = verdict(state(carried().mark().ledger(), dest=None, links=links))
    assert not unplaced.verdict.passed and "not placed" in unplaced.verdict.reason
    never_served = verdict(state(Recorder().mark().write("/data/notes.txt", MADE).mark().ledger(), dest=edited,
                                 links=links))
    assert not never_served.verdict.passed


def test_without_a_ledger_the_drives_final_copy_stands_in_and_says_so():
    class Drive:
        def download(self, path):
            assert path == "/data/notes.txt"
            return MADE

    st = state(None)
    st.transfer = Drive()
    d = verdict(st)
    assert d.verdict.passed and "keeps no ledger" in d.verdict.reason


# -- sides by the graph's order -------------------------------------------------------------------------------
def node(library, template_id: str, **values):
    from jarvis_pytest.tasks.compose import Node
    from jarvis_pytest.tasks.instances import sample_inputs
    import random

    tpl = library.get(template_id)
    return Node(tpl, {**sample_inputs(tpl, random.Random(0)), **values})


@pytest.fixture(scope="module")
def library():
    return load_library(REPO / "tasks")


def test_the_subtask_that_edits_a_file_before_it_is_carried_changes_nothing_later(library):
    """Class 1 of issue 36: Mousepad appends a line, then the file is carried to Windows, where Notepad converts
    its line breaks. The append runs before the transfer: the source is compared; the conversion runs after it: the
    destination is not, and the conversion compares with what arrived."""
    built = build(Draft((node(library, "ubuntu-mousepad-append_line"),
                         node(library, "windows-notepad-crlf_line_endings")), (Link(0, "edited_file", 1, "text_file"),)))
    append, transfer, convert = built.subtasks
    links = transfer_links(built.subtasks, built.edges, 1)
    assert links == TransferLinks(upstream=0, downstream=(2,), source_changed_later=False,
                                  destination_consumed="edit", upstream_edits_in_place=True)
    assert not any(k.endswith("changes_later") for e in transfer.evaluate for k in e.args)


def test_a_downstream_edit_is_judged_against_the_arrived_bytes(library):
    """Class 2 of issue 36: the received file's later editor compares its result with the bytes that arrived
    through the drive, not only a property of the result."""
    built = build(Draft((node(library, "windows-notepad-write_note"), node(library, "ubuntu-mousepad-append_line")),
                        (Link(0, "note", 1, "list_file"),)))
    write, transfer, append = built.subtasks
    source, received = str(transfer.input["transferred_file"].value), str(transfer.output["received_file"].value)
    line = str(next(e for e in append.evaluate if e.func == "file_last_line").args["expected"])
    arrived = b"milk\r\neggs\r\n"
    rec = Recorder().mark().write(f"/data/{received.rsplit('/', 1)[1]}", arrived).read(
        f"/data/{received.rsplit('/', 1)[1]}").mark()

    def run(final: bytes):
        devices = {"windows": _FilesDevice({source: arrived}), "ubuntu": _FilesDevice({received: final})}
        return evaluate_subtasks(built.subtasks, devices, None, {}, built.edges, rec.ledger())[2]

    good = run(arrived.replace(b"\r\n", b"\n") + line.encode() + b"\n")
    assert good.passed, [e.reason for e in good.evaluators]
    made_up = run(b"something else\n" + line.encode() + b"\n")  # the right last line on other content
    assert not made_up.passed, [e.reason for e in made_up.evaluators]
