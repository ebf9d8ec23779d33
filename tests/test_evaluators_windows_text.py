"""The plain-text, Notepad and RTF evaluators (`jarvis_pytest/evaluators/text.py`, `rtf.py`)
and their generators (`rtf`, `encoded_text`), run on bytes with no container.

Unit tests of the pieces (encoding detection, line breaks, the RTF reader on what Wine's WordPad writes), then
the ten Notepad and WordPad templates of `tasks/windows/` end to end on a host folder standing in for the device:
set-up files made by the templates' own generators, the fresh state fails, the result a careful person leaves
(the bytes Wine's Notepad and WordPad write, and what Windows 10's would) passes, and every near-miss state of
the template's `negatives` — its steps carried out on the host (the `pythonw -c` code run by the host's Python,
`copy`, `del` and `echo` emulated) — fails with a reason naming what is wrong.
"""

from __future__ import annotations

import datetime
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from jarvis_pytest.errors import ConfigError, InfrastructureError
from jarvis_pytest.evaluators import get_evaluator
from jarvis_pytest.evaluators.state import FinalState
from jarvis_pytest.devices.base import CommandResult
from jarvis_pytest.devices.platforms import PLATFORMS
from jarvis_pytest.evaluators.dates import parse_date
from jarvis_pytest.evaluators.registry import Verdict
from jarvis_pytest.evaluators.rtf import is_rtf, paragraph_format, parse_rtf
from jarvis_pytest.evaluators.text import compare_text, decode_text, describe_breaks, line_breaks, split_lines
from jarvis_pytest.generators import generate
from jarvis_pytest.tasks.instances import materialise, sample_inputs
from jarvis_pytest.tasks.model import Subtask, TaskTemplate
from tests.file_state import state_with

LIBRARY = Path(__file__).resolve().parents[1] / "tasks" / "windows"
TEMPLATES = ["notepad_replace_text", "notepad_save_utf8", "notepad_write_note", "notepad_crlf_line_endings",
             "notepad_delete_lines", "wordpad_bold_title", "wordpad_save_rtf", "wordpad_save_txt",
             "wordpad_font_size", "wordpad_insert_date"]
CRLF = "\r\n"


# -- encodings and line breaks ---------------------------------------------------------------------------------
@pytest.mark.parametrize("data, text, encoding", [
    (b"plain\r\n", "plain\r\n", "ASCII"),
    ("Café\r\n".encode("cp1252"), "Café\r\n", "ANSI"),
    ("Café €\r\n".encode("utf-8"), "Café €\r\n", "UTF-8"),
    (b"\xef\xbb\xbf" + "Café".encode("utf-8"), "Café", "UTF-8 with BOM"),
    (b"\xff\xfe" + "Zoë 東京".encode("utf-16-le"), "Zoë 東京", "UTF-16 LE"),
    (b"\xfe\xff" + "Zoë 東京".encode("utf-16-be"), "Zoë 東京", "UTF-16 BE"),
    (b"", "", "ASCII"),
])
def test_decode_text_tells_the_encoding_from_the_bytes(data, text, encoding):
    found = decode_text(data)
    assert (found.text, found.encoding) == (text, encoding)


@pytest.mark.parametrize("data, needle", [
    (b"a\x00b", "NUL bytes"),
    (b"\xff\xfe\x00\xd8", "UTF-16 LE"),            # a lone surrogate after the BOM
    (b"abc\x81\x8d", "neither UTF-8 nor cp1252"),
])
def test_decode_text_refuses_what_is_no_text(data, needle):
    with pytest.raises(ValueError, match=needle):
        decode_text(data)


def test_the_code_page_of_plain_text_is_the_platforms():
    """One decoder for every platform; where 8-bit text that is not UTF-8 is ANSI comes from `PlatformSpec`."""
    assert decode_text("Café".encode("cp1252"), PLATFORMS["windows"].text_codepage).encoding == "ANSI"
    with pytest.raises(ValueError, match="not UTF-8 text"):
        decode_text("Café".encode("cp1252"), PLATFORMS["ubuntu"].text_codepage)
    data = "Café pears\r\n".encode("cp1252")  # no baseline (a fed file): the weaker check, in the platform's text
    for platform, path, ok in (("windows", r"C:\Users\user\a.txt", True), ("ubuntu", "/home/user/a.txt", False)):
        verdict = get_evaluator("file_text_replaced")(state_with({path: data}, platform=platform), path=path,
                                                      old="apples", new="pears")
        assert verdict.passed is ok and (ok or "not a text file: not UTF-8 text" in verdict.reason), verdict.reason


def test_line_breaks_are_counted_by_kind():
    assert line_breaks("a\r\nb\nc\rd\r\n") == {"CRLF": 2, "LF": 1, "CR": 1}
    assert describe_breaks(line_breaks("a\r\n")) == "1 CRLF line break"
    assert describe_breaks(line_breaks("a")) == "no line breaks"
    assert split_lines("a\r\nb\n\nc\r") == ["a", "b", "", "c"]


def test_compare_text_names_the_first_difference():
    want = "one\r\ntwo\r\n"
    assert compare_text(b"one\r\ntwo\r\n", want, "ANSI", "x").passed  # ASCII bytes are ANSI bytes
    assert not compare_text(b"\xef\xbb\xbfone\r\ntwo\r\n", want, "ANSI", "x").passed
    assert "stored as UTF-8 with BOM" in compare_text(b"\xef\xbb\xbfone\r\ntwo\r\n", want, "ANSI", "x").reason
    assert "2 LF line breaks" in compare_text(b"one\ntwo\n", want, "ANSI", "x").reason
    assert "without a final line break" in compare_text(b"one\r\ntwo", want, "ANSI", "x").reason
    assert "line 2 is 'three\\r\\n'" in compare_text(b"one\r\nthree\r\n", want, "ANSI", "x").reason
    assert "an empty file" in compare_text(b"", want, "ANSI", "x").reason
    assert "only a UTF-8 with BOM byte order mark" in compare_text(b"\xef\xbb\xbf", want, "ANSI", "x").reason
    assert "not a text file" in compare_text(b"\x00\x01", want, "ANSI", "x").reason


def test_encoded_text_generator_writes_windows_encodings():
    lines = ["Zoë", "12 €"]
    assert generate("encoded_text", {"lines": lines}) == "Zoë\r\n12 €\r\n".encode("cp1252")
    assert generate("encoded_text", {"lines": lines, "encoding": "UTF-16 LE", "final_newline": False}) == \
        b"\xff\xfe" + "Zoë\r\n12 €".encode("utf-16-le")
    assert generate("encoded_text", {"lines": lines, "encoding": "utf-16be", "newline": "\n"}) == \
        b"\xfe\xff" + "Zoë\n12 €\n".encode("utf-16-be")
    assert generate("encoded_text", {"lines": lines, "encoding": "UTF-8 with BOM"}).startswith(b"\xef\xbb\xbfZo\xc3")
    with pytest.raises(ConfigError, match="cp1252"):  # a character ANSI cannot hold is an error, never a '?'
        generate("encoded_text", {"lines": ["東京"], "encoding": "ANSI"})
    with pytest.raises(ConfigError, match="unknown encoding"):
        generate("encoded_text", {"lines": lines, "encoding": "EBCDIC"})
    with pytest.raises(ConfigError, match="newline"):
        generate("encoded_text", {"lines": lines, "newline": "\t"})


# -- the RTF reader ----------------------------------------------------------------------------------------------
# What Wine 8's WordPad wrote here: a title made bold (Ctrl+B), a paragraph set to 20 pt in the format bar, a
# text file saved as RTF (with its blank line), today's date inserted.
WINE_BOLD = (b"{\\rtf1\\ansi\\ansicpg1252\\uc1\\deff0\\deflang1033\\deflangfe1033{\\fonttbl{\\f0 Arial;}}\r\n"
             b"{\\colortbl;}\r\n{\\*\\generator Wine Riched20 2.0;}\r\n\\pard\\sl-240\\slmult1 \\b\\lang1033\\fs24"
             b"\\f0 Quarterly Report\\b0 \\par\r\nSales rose by \\'e9 ten percent.\\par\r\nQuestions go to the "
             b"office.\\par\r\n}\x00")
WINE_SIZE = (b"{\\rtf1\\ansi\\ansicpg1252\\uc1\\deff0\\deflang1033\\deflangfe1033{\\fonttbl{\\f0 Arial;}}\r\n"
             b"{\\colortbl;}\r\n{\\*\\generator Wine Riched20 2.0;}\r\n\\pard\\sl-240\\slmult1 \\lang1033\\fs24\\f0 "
             b"Quarterly Report\\par\r\n\\fs40 Sales rose by ten percent.\\fs24 \\par\r\nQuestions go to the "
             b"office.\\par\r\n}\x00")
WINE_FROM_TEXT = (b"{\\rtf1\\ansi\\ansicpg1252\\uc1\\deff0\\deflang1033\\deflangfe1033{\\fonttbl{\\f0\\fcharset0 "
                  b"Courier New;}}\r\n{\\colortbl;}\r\n{\\*\\generator Wine Riched20 2.0;}\r\n\\pard\\sl-240\\slmult1 "
                  b"\\lang1033\\fs18\\f0 Minutes of the meeting\\par\r\nPresent: Zo\\'eb, Ben\\par\r\n\\par\r\nNext "
                  b"meeting on Friday.\\par\r\n\\par\r\n}\x00")


def runs(doc):
    return [[(r.text, r.bold, r.size) for r in p.runs] for p in doc.paragraphs]


def test_parse_rtf_reads_what_wine_wordpad_writes():
    doc = parse_rtf(WINE_BOLD)
    assert runs(doc) == [[("Quarterly Report", True, 12.0)], [("Sales rose by é ten percent.", False, 12.0)],
                         [("Questions go to the office.", False, 12.0)]]
    assert doc.fonts == {0: "Arial"} and doc.paragraphs[0].runs[0].font == "Arial"
    assert [paragraph_format(p).describe() for p in doc.paragraphs] == ["bold, 12 pt", "not bold, 12 pt",
                                                                        "not bold, 12 pt"]
    assert [sorted(p.sizes()) for p in parse_rtf(WINE_SIZE).paragraphs] == [[12.0], [20.0], [12.0]]
    text = parse_rtf(WINE_FROM_TEXT)
    assert text.texts() == ["Minutes of the meeting", "Present: Zoë, Ben", "", "Next meeting on Friday."]
    assert text.fonts == {0: "Courier New"}


def test_parse_rtf_scopes_formatting_to_groups_and_resets_with_plain():
    doc = parse_rtf(rb"{\rtf1{\fonttbl\f0\fnil Courier New;\f1\froman Times;}\f1\fs20 A{\b\i B}C\b D\plain E\par}")
    assert [(r.text, r.bold, r.italic, r.size, r.font) for r in doc.paragraphs[0].runs] == [
        ("A", False, False, 10.0, "Times"), ("B", True, True, 10.0, "Times"), ("C", False, False, 10.0, "Times"),
        ("D", True, False, 10.0, "Times"), ("E", False, False, 12.0, None)]
    assert doc.paragraphs[0].describe_bold() == "partly bold ('BD' only)"
    assert parse_rtf(rb"{\rtf1 \b x\b0 y\par}").paragraphs[0].runs[1].bold is False
    assert parse_rtf(rb"{\rtf1 \ul x\ulnone y\par}").paragraphs[0].runs[0].underline is True


def test_parse_rtf_escapes_unicode_and_skipped_destinations():
    data = (rb"{\rtf1\ansi\ansicpg1251{\stylesheet{\s0 Normal;}}{\info{\title Secret}{\author Me}}"
            rb"{\*\generator X;}\pard \'c4\'e0 \u26481?\u20140\'3f \uc2\u8364XYz \{\}\\\tab t\~u\par"
            rb"\u-10179?\u-8704?\par}")
    doc = parse_rtf(data)
    assert doc.texts() == ["Да 東京 €z {}\\\tt\u00a0u", "\U0001F600"]
    assert doc.codepage == "cp1251"


@pytest.mark.parametrize("data, needle", [
    (b"Hello\r\nWorld", "not RTF"),
    (b"{\\rtf1 unbalanced {\\b x}", "do not balance"),
    (b"{\\rtf1 x}} more", "text after"),
    (b"PK\x03\x04", "not RTF"),
])
def test_parse_rtf_refuses_what_is_not_rtf(data, needle):
    with pytest.raises(ValueError, match=needle):
        parse_rtf(data)
    assert not is_rtf(b"plain") and is_rtf(b"\r\n{\\rtf1}")


def test_rtf_document_generator_round_trips():
    data = generate("rtf_document", {"paragraphs": ["Title Ünï 東京 {x}", "Body \\ text\tend", "Last"],
                                     "bold": [0], "sizes": [16, 12, 10.5], "font": "Times New Roman"})
    assert data.isascii() and data.startswith(b"{\\rtf1\\ansi\\ansicpg1252")
    doc = parse_rtf(data)
    assert doc.texts() == ["Title Ünï 東京 {x}", "Body \\ text\tend", "Last"]
    assert [paragraph_format(p).describe() for p in doc.paragraphs] == ["bold, 16 pt", "not bold, 12 pt",
                                                                        "not bold, 10.5 pt"]
    assert doc.paragraphs[1].runs[0].font == "Times New Roman"
    assert generate("rtf_document", {"paragraphs": ["a"]}) == generate("rtf_document", {"paragraphs": ["a"]})
    for args, needle in (({"paragraphs": ["a"], "bold": [3]}, "does not exist"),
                         ({"paragraphs": ["a"], "sizes": [1, 2]}, "2 entries"),
                         ({"paragraphs": ["a\nb"]}, "line break"),
                         ({"paragraphs": ["a"], "size": 10.3}, "half point"),
                         ({"paragraphs": "a"}, "list of strings")):
        with pytest.raises(ConfigError, match=needle):
            generate("rtf_document", args)


def test_parse_rtf_reads_colour_strikethrough_hidden_highlight_and_alignment():
    doc = parse_rtf(rb"{\rtf1{\fonttbl{\f0 Arial;}{\f1 Times;}}{\colortbl;\red255\green0\blue0;\red0\green0\blue0;"
                    rb"\red255\green255\blue0;}\pard\qc \cf1 R\cf2 K\cf0 A\strike S\strike0\striked1 D\striked0 {\v H}h"
                    rb"\highlight3 Y\plain P\par\pard \ulw U\ulnone N\cb3 B\par}")
    assert doc.colors == [None, "#ff0000", "#000000", "#ffff00"]
    first, second = doc.paragraphs
    got = [(r.text, r.color, r.strike, r.hidden, r.highlight) for r in first.runs]
    assert got == [("R", "#ff0000", False, False, None), ("KA", "auto", False, False, None),  # black is automatic
                   ("SD", "auto", True, False, None),  # \\striked (double) is a strikethrough too
                   ("H", "auto", False, True, None), ("h", "auto", False, False, None),
                   ("Y", "auto", False, False, "#ffff00"), ("P", "auto", False, False, None)]
    assert first.align == "centred" and second.align == "left"  # \pard resets the alignment
    assert [(r.text, r.underline, r.highlight) for r in second.runs] == [("U", True, None), ("N", False, None),
                                                                          ("B", False, "#ffff00")]
    assert first.hidden_text() == "H"


def test_parse_date_reads_wordpads_forms_and_no_time_alone():
    day = datetime.date(2026, 11, 24)
    for text in ("11/24/2026", "Tuesday, November 24, 2026", "2026-11-24", "24 November 2026",
                 "11/24/2026 5:38 AM", "November 24, 2026", "24.11.2026", "Date: 11/24/2026", "Today: 2026-11-24."):
        assert parse_date(text) == day, text
    assert parse_date("5:38:16 AM") is None and parse_date("Kind regards") is None
    assert parse_date("Invoice 11/24/2026") is None


# -- the templates on a host folder ----------------------------------------------------------------------------
def load(name: str) -> TaskTemplate:
    return TaskTemplate.model_validate(json.loads((LIBRARY / f"{name}.json").read_text()))


def instance(name: str, seed: int = 0, **values) -> Subtask:
    import random

    tpl = load(name)
    sampled = sample_inputs(tpl, random.Random(f"test#{name}#{seed}"))
    return materialise(tpl, {**sampled, **values})


class Box:
    """A host folder standing in for the Windows device of one instance: Windows paths (case-insensitive) map to
    files under it; set-up uploads, negative steps and careful results write there."""

    PYTHON = re.compile(r'^C:\\jarvis\\python\\pythonw?\.exe -c "(.*)"$', re.S)

    def __init__(self, root: Path, sub: Subtask):
        self.root, self.sub = root, sub
        self.baselines: dict[str, bytes] = {}

    def host(self, path: str) -> Path:
        return self.root / path.replace(":", "").replace("\\", "/").lower()

    def write(self, path: str, data: bytes) -> None:
        self.host(path).parent.mkdir(parents=True, exist_ok=True)
        self.host(path).write_bytes(data)

    def read(self, path: str) -> bytes:
        return self.host(path).read_bytes()

    def setup(self) -> "Box":
        for step in self.sub.config:
            if step.type == "upload_file":
                data = generate(step.generator, step.args) if step.generator else str(step.content).encode()
                self.write(step.path, data)
        self.baselines = {p: self.read(p) for p in self.sub.baseline if self.host(p).exists()}
        return self

    def run(self, command: str) -> None:
        """Carry out one command of a negative: Python code on the host, or `copy`, `del` or `> f echo`."""
        m = self.PYTHON.match(command)
        if m:
            code = re.sub(r"r'([A-Za-z]:\\[^']*)'", lambda p: repr(str(self.host(p.group(1)))), m.group(1))
            for path in re.findall(r"r'([A-Za-z]:\\[^']*)'", m.group(1)):
                self.host(path).parent.mkdir(parents=True, exist_ok=True)
            subprocess.run([sys.executable, "-c", code], check=True, capture_output=True)
        elif m := re.fullmatch(r'copy /y "([^"]+)" "([^"]+)"', command):
            self.write(m.group(2), self.read(m.group(1)))
        elif m := re.fullmatch(r'del "([^"]+)"', command):
            self.host(m.group(1)).unlink()
        elif m := re.fullmatch(r'> "([^"]+)" echo (.*)', command):
            self.write(m.group(1), (m.group(2) + CRLF).encode("cp1252"))
        else:
            raise AssertionError(f"no emulation of the command {command!r}")

    def state(self) -> FinalState:
        files = {}
        for path in self.paths():
            if self.host(path).exists():
                files[path] = self.read(path)
        return with_clock(state_with(files, platform="windows", baselines=self.baselines))

    def paths(self) -> set[str]:
        """Every Windows path the instance names (its slots, set-up, evaluators)."""
        text = self.sub.model_dump_json()
        return {p.replace("\\\\", "\\") for p in re.findall(r"[A-Za-z]:(?:\\\\[^\"\\']+)+", text)}

    def evaluate(self) -> list:
        state = self.state()
        return [get_evaluator(spec.func)(state, **spec.args) for spec in self.sub.evaluate]


def with_clock(state: FinalState, today: datetime.date | None = None) -> FinalState:
    """`state` whose device answers the platform's date command with `today` (default: the host's local date,
    which the host-run negatives' `datetime.date.today()` also read)."""
    device = state.device()
    command, other = PLATFORMS[state.platform].today_command, device.run
    day = (today or datetime.date.today()).isoformat()

    def run(cmd, user=None, timeout=60.0):
        return CommandResult(0, day + "\r\n", "") if cmd == command else other(cmd, user, timeout)

    device.run = run
    return state


def passed(verdicts) -> bool:
    return all(v.passed for v in verdicts)


def box(tmp_path: Path, name: str, seed: int = 0, **values) -> Box:
    return Box(tmp_path, instance(name, seed, **values)).setup()


SEEDS = [0, 1, 2]


@pytest.mark.parametrize("name", TEMPLATES)
@pytest.mark.parametrize("seed", SEEDS)
def test_the_fresh_state_fails(tmp_path, name, seed):
    verdicts = box(tmp_path, name, seed).evaluate()
    assert not any(v.passed for v in verdicts), [v.reason for v in verdicts]


NEGATIVES = [(name, i) for name in TEMPLATES for i in range(len(load(name).negatives))]


@pytest.mark.parametrize("name, index", NEGATIVES, ids=[f"{n}-{i}" for n, i in NEGATIVES])
@pytest.mark.parametrize("seed", SEEDS)
def test_each_negative_fails_with_a_reason(tmp_path, name, index, seed):
    b = box(tmp_path, name, seed)
    negative = b.sub.negatives[index]
    for step in negative.steps:
        b.run(step.command)
    verdicts = b.evaluate()
    assert not passed(verdicts), f"{negative.note} passed: {[v.reason for v in verdicts]}"
    assert all(v.reason.startswith("expected ") and ", found " in v.reason for v in verdicts)


def test_every_template_has_an_artefact_and_another_negative_and_an_oracle():
    gui = 0
    for name in TEMPLATES:
        tpl = load(name)
        kinds = {n.kind for n in tpl.negatives}
        assert "artefact" in kinds and kinds - {"artefact"}, name
        assert tpl.solution and not tpl.backends, name  # every one runs on Wine
        gui += any(step.action is not None for step in tpl.solution)
    assert gui >= 3


# The results a careful person leaves: the bytes the applications write (Wine's; Windows 10's where it differs).
def wine_rtf(bodies: list[str], size: int = 22) -> bytes:
    """RTF as Wine's WordPad writes it, each paragraph given as its RTF body (text and control words)."""
    head = (b"{\\rtf1\\ansi\\ansicpg1252\\uc1\\deff0\\deflang1033\\deflangfe1033{\\fonttbl{\\f0\\fcharset0 Arial;}}"
            b"\r\n{\\colortbl;}\r\n{\\*\\generator Wine Riched20 2.0;}\r\n\\pard\\sl-240\\slmult1 \\lang1033\\fs%d"
            b"\\f0 " % size)
    return head + "\r\n".join(bodies).encode("cp1252") + b"\r\n}\x00"


def rtf_escape(text: str) -> str:
    return "".join(c if ord(c) < 128 else "\\'%02x" % c.encode("cp1252")[0] for c in text)


def careful_results(b: Box) -> list[dict[str, bytes]]:
    """Final files a careful person may leave for the instance in `b` (each dict: Windows path → bytes)."""
    sub, v = b.sub, {k: s.value for k, s in {**b.sub.input, **b.sub.output}.items()}
    name = sub.template.removeprefix("windows-").replace("-", "_")
    if name == "notepad_replace_text":
        return [{v["text_file"]: b.read(v["text_file"]).replace(v["old_word"].encode(), v["new_word"].encode())}]
    if name == "notepad_save_utf8":
        text = decode_text(b.read(v["source"])).text
        return [{v["converted"]: b"\xef\xbb\xbf" + text.encode()},  # Wine's Notepad: with a BOM
                {v["converted"]: text.encode()}]                     # Windows 10's "UTF-8": without
    if name == "notepad_write_note":
        lines = [f"Call {v['person']} back", f"Buy {v['item']}", f"Meeting at {v['hour']}:00"]
        return [{v["note"]: CRLF.join(lines).encode("cp1252")},
                {v["note"]: (CRLF.join(lines) + CRLF).encode("cp1252")},
                {v["note"]: b"\xef\xbb\xbf" + (CRLF.join(lines) + CRLF).encode()},
                {v["note"]: b"\xff\xfe" + CRLF.join(lines).encode("utf-16-le")}]
    if name == "notepad_crlf_line_endings":
        return [{v["text_file"]: b.read(v["text_file"]).replace(b"\n", b"\r\n")}]
    if name == "notepad_delete_lines":
        kept = [line for line in b.read(v["text_file"]).split(b"\r\n") if v["word"].encode() not in line]
        return [{v["text_file"]: b"\r\n".join(kept)}]
    if name == "wordpad_bold_title":
        body = ["This note explains the change in detail.", "Questions go to the office."]
        return [{v["doc"]: wine_rtf([f"\\b {v['title']}\\b0 \\par"] + [p + "\\par" for p in body])}]
    if name == "wordpad_save_rtf":
        lines = split_lines(decode_text(b.read(v["text_file"])).text)
        return [{v["doc"]: wine_rtf([rtf_escape(line) + "\\par" for line in lines] + ["\\par"], 18)}]
    if name == "wordpad_save_txt":
        text = CRLF.join(parse_rtf(b.read(v["doc"])).texts())
        return [{v["text_file"]: text.encode("cp1252")},                   # Text document (ANSI)
                {v["text_file"]: b"\xff\xfe" + text.encode("utf-16-le")}]  # Unicode text document
    if name == "wordpad_font_size":
        body = ["The opening hours change next month.", "Details follow in a separate letter."]
        half = int(2 * float(v["size"]))
        return [{v["doc"]: wine_rtf([f"\\fs{half} {v['heading']}\\fs22 \\par"] + [p + "\\par" for p in body])}]
    if name == "wordpad_insert_date":
        today = datetime.date.today()  # the device's clock (see `with_clock`)
        letter = [rtf_escape(f"Dear {v['person']},"), "Thank you for your visit to our shop.", "Kind regards"]
        forms = (f"{today.month}/{today.day}/{today.year}", today.strftime("%A, %B %d, %Y").replace(" 0", " "))
        return [{v["doc"]: wine_rtf([p + "\\par" for p in letter + [form]])} for form in forms]
    raise AssertionError(name)


@pytest.mark.parametrize("name", TEMPLATES)
@pytest.mark.parametrize("seed", SEEDS)
def test_what_a_careful_person_leaves_passes(tmp_path, name, seed):
    results = careful_results(box(tmp_path / "probe", name, seed))
    for i, files in enumerate(results):
        b = box(tmp_path / str(i), name, seed)
        for path, data in files.items():
            b.write(path, data)
        verdicts = b.evaluate()
        assert passed(verdicts), (i, [v.reason for v in verdicts])


# -- without a baseline (an input fed by an upstream subtask) ---------------------------------------------------------
def test_without_a_baseline_the_fallback_checks_still_catch_the_obvious(tmp_path):
    path = r"C:\Users\user\Documents\f.txt"

    def run(func, data, **args):
        return get_evaluator(func)(with_clock(state_with({path: data}, platform="windows")), path=path, **args)

    assert run("file_text_replaced", b"a pears\r\nb pears\r\n", old="apples", new="pears").passed
    assert not run("file_text_replaced", b"a pears\r\nb apples\r\n", old="apples", new="pears").passed
    assert not run("file_text_replaced", b"a pears\r\nb pears\n", old="apples", new="pears").passed  # mixed
    assert run("file_line_endings", b"a\r\nb\r\n", ending="CRLF").passed
    assert not run("file_line_endings", b"a\r\nb\n", ending="crlf").passed
    assert "no line breaks" in run("file_line_endings", b"ab", ending="CRLF").reason
    assert not run("file_line_endings", b"a\r\r\nb\r\n", ending="CRLF").passed  # a stray CR
    assert not run("file_line_endings", b"x\r\n", ending="CRLF", contains="Notes").passed
    assert run("file_lines_without", b"keep\r\nalso\r\n", word="gone", kept=["keep", "also"]).passed
    assert not run("file_lines_without", b"keep\r\ngone too\r\n", word="gone", kept=["keep"]).passed
    assert "lost ['also']" in run("file_lines_without", b"keep\r\n", word="gone", kept=["keep", "also"]).reason
    assert "lost" in run("file_lines_without", b"keep \r\nalso\r\n", word="gone", kept=["keep", "also"]).reason
    doc = generate("rtf_document", {"paragraphs": ["T", "o"], "bold": [0]})
    assert run("rtf_paragraph_bold", doc, text="T", others=["o"]).passed
    assert not run("rtf_paragraph_bold", generate("rtf_document", {"paragraphs": ["T", "o"], "bold": [1]}),
                   text="T", others=["o"]).passed
    assert run("rtf_font_size", generate("rtf_document", {"paragraphs": ["T", "o"], "sizes": [20, 11]}),
               text="T", size=20).passed
    today = datetime.date.today().isoformat()
    assert run("rtf_date_added", generate("rtf_document", {"paragraphs": ["Hi", today]})).passed
    assert "the date alone" in run("rtf_date_added", generate("rtf_document", {"paragraphs": [today]})).reason
    last_year = (datetime.date.today() - datetime.timedelta(days=400)).isoformat()
    assert not run("rtf_date_added", generate("rtf_document", {"paragraphs": ["Hi", last_year]})).passed


def test_file_text_encoded_bom_choice_and_utf16():
    src, out = r"C:\Users\user\Documents\s.txt", r"C:\Users\user\Documents\o.txt"
    source = "Zoë\r\n".encode("cp1252")

    def run(data, **args):
        state = state_with({src: source, out: data}, platform="windows", baselines={src: source})
        return get_evaluator("file_text_encoded")(state, path=out, source=src, **args)

    assert run("Zoë\r\n".encode(), encoding="UTF-8").passed
    assert run(b"\xef\xbb\xbf" + "Zoë\r\n".encode(), encoding="UTF-8").passed
    assert not run(b"\xef\xbb\xbf" + "Zoë\r\n".encode(), encoding="UTF-8", bom="no").passed
    assert not run("Zoë\r\n".encode(), encoding="UTF-8", bom="yes").passed
    assert run(b"\xff\xfe" + "Zoë\r\n".encode("utf-16-le"), encoding="UTF-16 LE").passed
    assert "stored as UTF-16 BE" in run(b"\xfe\xff" + "Zoë\r\n".encode("utf-16-be"), encoding="UTF-16 LE").reason
    assert not run("Zoë\r\n".encode("utf-16-le"), encoding="UTF-16 LE").passed  # no BOM: Notepad reads it as ANSI


# -- every formatting property compared; hidden text hides nothing (issue 36) ------------------------------------------
COLOURED = (b"{\\colortbl;}", b"{\\colortbl;\\red255\\green0\\blue0;\\red255\\green255\\blue0;}")
TIMES = (b"Arial;}}", b"Arial;}{\\f1\\fcharset0 Times New Roman;}}")


@pytest.mark.parametrize("title, body, head, needle", [
    ("\\b\\cf1 {t}\\cf0\\b0 \\par", None, COLOURED, "its text in colour #ff0000, expected in the automatic colour"),
    ("\\b\\strike {t}\\strike0\\b0 \\par", None, None, "its text struck through, expected not struck through"),
    ("\\b\\ul {t}\\ulnone\\b0 \\par", None, None, "its text underlined, expected not underlined"),
    ("\\b\\i {t}\\i0\\b0 \\par", None, None, "its text italic, expected not italic"),
    ("\\b\\f1 {t}\\f0\\b0 \\par", None, TIMES, "its text in Times New Roman, expected in Arial"),
    ("\\b\\highlight2 {t}\\highlight0\\b0 \\par", None, COLOURED, "its text highlighted #ffff00"),
    ("\\qc\\b {t}\\b0 \\par\\ql", None, None, "centred-aligned, expected left-aligned"),
    ("\\b {t}\\b0 \\par", "{{\\v This note explains the change in detail.}}\\par", None,
     "paragraph 2 ('This note explains the change in detail.'): its text hidden (\\v), expected visible"),
    ("\\b {t}{{\\v  (draft)}}\\b0 \\par", None, None, "reads"),  # text added, hidden
    ("\\b {t}\\b0 \\par", "This note explains the change in detail.{{\\v  Not really.}}\\par", None,
     "paragraph 2 reads 'This note explains the change in detail. Not really.'"),
])
def test_bold_title_compares_every_property_but_bold(tmp_path, title, body, head, needle):
    """The title made bold as asked, plus one change nobody asked for: each fails, naming what changed."""
    b = box(tmp_path, "wordpad_bold_title")
    t = b.sub.input["title"].value
    paragraphs = [title.format(t=t), body or "This note explains the change in detail.\\par",
                  "Questions go to the office.\\par"]
    data = wine_rtf(paragraphs)
    b.write(b.sub.input["doc"].value, data.replace(*head) if head else data)
    verdicts = b.evaluate()
    assert not passed(verdicts) and needle in reasons(verdicts), reasons(verdicts)
    b.write(b.sub.input["doc"].value, wine_rtf([f"\\b {t}\\b0 \\par"] + paragraphs[1:] if body is None else
                                               [f"\\b {t}\\b0 \\par", "This note explains the change in detail.\\par",
                                                "Questions go to the office.\\par"]))
    assert passed(b.evaluate()), reasons(b.evaluate())


def test_font_size_compares_every_property_but_the_size(tmp_path):
    b = box(tmp_path, "wordpad_font_size")
    h, half = b.sub.input["heading"].value, int(2 * float(b.sub.input["size"].value))
    rest = ["The opening hours change next month.\\par", "Details follow in a separate letter.\\par"]
    for heading, head, needle in ((f"\\fs{half}\\cf1 {h}\\cf0\\fs22 \\par", COLOURED, "in colour #ff0000"),
                                  (f"\\fs{half}\\f1 {h}\\f0\\fs22 \\par", TIMES, "in Times New Roman"),
                                  (f"\\fs{half}\\strike {h}\\strike0\\fs22 \\par", None, "struck through"),
                                  (f"\\fs{half}\\v {h}\\v0\\fs22 \\par", None, "hidden (\\v)")):
        data = wine_rtf([heading] + rest)
        b.write(b.sub.input["doc"].value, data.replace(*head) if head else data)
        assert needle in reasons(b.evaluate()), (needle, reasons(b.evaluate()))


def test_text_saved_as_rtf_must_keep_plain_formatting(tmp_path):
    b = box(tmp_path, "wordpad_save_rtf")
    lines = split_lines(decode_text(b.read(b.sub.input["text_file"].value)).text)
    doc = b.sub.output["doc"].value
    body = [rtf_escape(line) + "\\par" for line in lines] + ["\\par"]
    for i, (edit, head, needle) in enumerate((
            (lambda x: "\\b " + x + "\\b0 ", None, "its text bold, expected not bold"),
            (lambda x: "{\\v " + x + "}", None, "its text hidden (\\v), expected visible"),
            (lambda x: "\\f1 " + x + "\\f0 ", TIMES, "its text in Times New Roman, expected in Courier New"),
            (lambda x: "\\cf1 " + x + "\\cf0 ", COLOURED, "in colour #ff0000"))):
        edited = list(body)
        edited[1] = edit(edited[1][:-len("\\par")]) + "\\par"
        data = wine_rtf(edited, 18).replace(b"Arial", b"Courier New")
        b.write(doc, data.replace(*(h.replace(b"Arial", b"Courier New") for h in head)) if head else data)
        assert needle in reasons(b.evaluate()), (i, reasons(b.evaluate()))
    b.write(doc, wine_rtf(body, 18).replace(b"Arial", b"Courier New"))  # one font and size, whichever it is
    assert passed(b.evaluate()), reasons(b.evaluate())


def reasons(verdicts) -> str:
    return " | ".join(v.reason for v in verdicts if not v.passed)


# -- today by the device's clock (issue 36) ----------------------------------------------------------------------------
DAY = r"C:\Users\user\AppData\Local\jarvis\wordpad_insert_date.day"


def dated_letter(day: datetime.date, hidden: bool = False) -> bytes:
    date = f"{day.month}/{day.day}/{day.year}"
    return wine_rtf(["Dear Ann,\\par", "Kind regards\\par", ("{\\v " + date + "}" if hidden else date) + "\\par"])


def judge_date(data: bytes, device_day: datetime.date, setup_day: datetime.date | None) -> Verdict:
    path = r"C:\Users\user\Documents\letter.rtf"
    base = {path: wine_rtf(["Dear Ann,\\par", "Kind regards\\par"])}
    if setup_day is not None:
        base[DAY] = setup_day.isoformat().encode()
    state = with_clock(state_with({path: data}, platform="windows", baselines=base), device_day)
    return get_evaluator("rtf_date_added")(state, path=path, setup_day=DAY)


def test_the_date_is_the_devices_today_exactly():
    device = datetime.date(2031, 3, 1)  # the device's clock, whatever the host's says
    assert judge_date(dated_letter(device), device, device).passed
    for day in (device - datetime.timedelta(days=1), device + datetime.timedelta(days=1),
                datetime.date.today() if datetime.date.today() != device else device.replace(year=2030)):
        verdict = judge_date(dated_letter(day), device, device)
        assert not verdict.passed and f"the date {day}" in verdict.reason and "(set up the same day)" in verdict.reason
    no_record = judge_date(dated_letter(device - datetime.timedelta(days=1)), device, None)
    assert not no_record.passed and "no record of the set-up day" in no_record.reason


def test_the_day_before_counts_only_when_the_devices_clock_crossed_midnight():
    device = datetime.date(2031, 3, 1)
    before = device - datetime.timedelta(days=1)
    verdict = judge_date(dated_letter(before), device, before)  # set up at 23:59, evaluated at 00:01
    assert verdict.passed and "crossed midnight since set-up on 2031-02-28" in verdict.reason
    assert judge_date(dated_letter(device), device, before).passed
    assert not judge_date(dated_letter(before - datetime.timedelta(days=1)), device, before).passed


def test_a_hidden_date_is_no_date_added():
    device = datetime.date(2031, 3, 1)
    verdict = judge_date(dated_letter(device, hidden=True), device, device)
    assert not verdict.passed and "as hidden text" in verdict.reason
    white = dated_letter(device).replace(b"{\\colortbl;}", b"{\\colortbl;\\red255\\green255\\blue255;}")
    white = white.replace(f"{device.month}/".encode(), f"\\cf1 {device.month}/".encode())
    verdict = judge_date(white, device, device)
    assert not verdict.passed and "white on the white page" in verdict.reason, verdict.reason


def test_a_device_that_does_not_tell_its_date_is_an_infrastructure_error():
    path = r"C:\Users\user\Documents\letter.rtf"
    state = state_with({path: dated_letter(datetime.date.today())}, platform="windows")
    state.device().run = lambda cmd, user=None, timeout=60.0: CommandResult(1, "", "'pythonw.exe' is not recognized")
    with pytest.raises(InfrastructureError, match="did not tell its date"):
        get_evaluator("rtf_date_added")(state, path=path)


def test_the_twins_are_gone_and_the_merged_evaluators_take_any_case():
    path = r"C:\Users\user\Documents\f.txt"
    before, after = b"a\nb apples\n", b"a\r\nb apples\r\n"
    state = state_with({path: after}, platform="windows", baselines={path: before})
    assert get_evaluator("file_line_endings")(state, path=path, ending="crlf").passed
    for twin in ("windows_text_line_endings", "windows_text_replaced", "windows_text_lines_deleted",
                 "windows_text_encoded", "windows_text_lines", "windows_file_copied", "files_identical",
                 "copy_identical", "windows_tree", "windows_folders_copied", "windows_file_lists",
                 "windows_file_number"):
        with pytest.raises(ConfigError, match="unknown evaluator"):
            get_evaluator(twin)


CLASS_NEGATIVES = [  # (template, words of the negative's note, what its reason must name): each fails for its class
    ("wordpad_bold_title", "colour changed", "in colour #c00000, expected in the automatic colour"),
    ("wordpad_bold_title", "struck through", "struck through, expected not struck through"),
    ("wordpad_bold_title", "another font", "in Times New Roman, expected in Arial"),
    ("wordpad_bold_title", "second paragraph made hidden", "paragraph 2 ('This note explains the change in detail.'): "
                                                           "its text hidden (\\v), expected visible"),
    ("wordpad_font_size", "colour changed", "in colour #0000c0"),
    ("wordpad_font_size", "another font", "in Times New Roman, expected in Arial"),
    ("wordpad_font_size", "last paragraph made hidden", "paragraph 3 ('Details follow in a separate letter.'): its "
                                                        "text hidden (\\v)"),
    ("wordpad_insert_date", "yesterday's date", f"the date {datetime.date.today() - datetime.timedelta(days=1)}"),
    ("wordpad_insert_date", "as hidden text", "as hidden text (\\v) or white on the white page"),
    ("wordpad_insert_date", "thank-you line made hidden", "paragraph 2 ('Thank you for your visit to our shop.'): its "
                                                          "text hidden (\\v)"),
    ("wordpad_insert_date", "struck through", "paragraph 3 ('Kind regards'): its text struck through"),
    ("wordpad_save_rtf", "first line made bold", "paragraph 1 ('Minutes of the"),
    ("wordpad_save_rtf", "made hidden text", "paragraph 2 ('Present: Zoë Martin, Ben Cole'): its text hidden (\\v)"),
]


@pytest.mark.parametrize("name, words, needle", CLASS_NEGATIVES, ids=[f"{n}-{w}" for n, w, _ in CLASS_NEGATIVES])
def test_the_negatives_of_each_class_fail_for_that_class(tmp_path, name, words, needle):
    b = box(tmp_path, name)
    negative = next(n for n in b.sub.negatives if words in n.note)
    for step in negative.steps:
        b.run(step.command)
    assert needle in reasons(b.evaluate()), reasons(b.evaluate())
