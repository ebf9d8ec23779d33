"""Windows text files and RTF documents, judged from their exact bytes (Notepad and WordPad templates).

Text: a file's bytes are decoded by what they are — a byte order mark names UTF-8, UTF-16 LE or BE; without one,
valid UTF-8 with non-ASCII characters is UTF-8, pure ASCII is ASCII (ANSI and UTF-8 alike), anything else is ANSI
(Windows-1252, the code page of an English Windows and of Wine here) — and every line break is classified (CRLF,
LF, CR), so an evaluator can say "expected UTF-8 with CRLF line breaks, found ANSI with 3 LF". Expected content
comes from the file as it was right after set-up (`state.baseline(path)`, the template lists it under `baseline`)
with only the asked change applied, and is compared byte for byte: the encoding, the BOM, the line breaks and the
final line break included, because Notepad keeps all of them when it saves.

RTF: `parse_rtf` is a small reader of the RTF 1.x syntax (groups, control words and symbols, `\\'hh` and `\\uN`
escapes with their `\\uc` fallbacks, the font table, skipped destinations such as the colour table, style sheet,
document info and `{\\*...}` groups) that tracks the character formatting a paragraph's text carries — bold
(`\\b`), italic (`\\i`), underline (`\\ul`), font size (`\\fs`, half points) and font (`\\f`) — through groups
and `\\plain`, and splits the text into paragraphs at `\\par`. Binary data (`\\bin`) is refused: none of the
documents these tasks read has pictures. No PyPI package fits: striprtf gives text only, rtfparse a tree of groups
and control words without the formatting state, pyth (2014, Python 2) and pyth3 (2019) bold and italic but not the
font size. A file is RTF when its bytes begin with `{\\rtf` and its groups balance; after the closing brace only
white space and NULs may follow (WordPad under Wine writes a NUL there).
"""

from __future__ import annotations

import datetime as _dt
import re
from collections import Counter
from dataclasses import dataclass, field

from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.state import FinalState
from jarvis_pytest.generators.windows_text import ENCODINGS, encoding as lookup_encoding


def _short(text: str, limit: int = 80) -> str:
    return repr(text if len(text) <= limit else text[:limit] + "…")


# -- text: encodings and line breaks ---------------------------------------------------------------------------
@dataclass(frozen=True)
class DecodedText:
    """A text file's content and how it is stored: `encoding` is a name of ENCODINGS or "ASCII" (bytes that
    are the same in ANSI and UTF-8 without BOM)."""

    text: str
    encoding: str

    @property
    def breaks(self) -> Counter:
        """How many line breaks of each kind the text has: CRLF, LF (alone) and CR (alone)."""
        return line_breaks(self.text)

    def describe(self) -> str:
        return f"{self.encoding} with {describe_breaks(self.breaks)}"


def decode_text(data: bytes) -> DecodedText:
    """The text of a file and its encoding, told from its bytes (see the module's docstring). Raises ValueError
    for bytes that are text in none of them (NUL bytes without a UTF-16 BOM, bytes Windows-1252 leaves
    undefined). RTF is 7-bit text and decodes: callers that need plain text check `is_rtf` themselves."""
    for name in ("UTF-8 with BOM", "UTF-16 LE", "UTF-16 BE"):
        enc = ENCODINGS[name]
        if data.startswith(enc.bom):
            try:
                return DecodedText(data[len(enc.bom):].decode(enc.codec), name)
            except UnicodeDecodeError as exc:
                raise ValueError(f"starts with the {name} byte order mark but is not {name}: {exc}") from None
    if b"\x00" in data:
        raise ValueError("holds NUL bytes without a UTF-16 byte order mark (not a text file)")
    try:
        text = data.decode("ascii")
        return DecodedText(text, "ASCII")
    except UnicodeDecodeError:
        pass
    try:
        return DecodedText(data.decode("utf-8"), "UTF-8")
    except UnicodeDecodeError:
        pass
    try:
        return DecodedText(data.decode("cp1252"), "ANSI")
    except UnicodeDecodeError as exc:  # 0x81, 0x8d, 0x8f, 0x90, 0x9d are unassigned in Windows-1252
        raise ValueError(f"neither UTF-8 nor Windows-1252 text: {exc}") from None


def line_breaks(text: str) -> Counter:
    """The line breaks of `text` by kind: CRLF, LF alone, CR alone."""
    crlf = text.count("\r\n")
    return Counter({k: v for k, v in (("CRLF", crlf), ("LF", text.count("\n") - crlf),
                                      ("CR", text.count("\r") - crlf)) if v})


def describe_breaks(breaks: Counter) -> str:
    if not breaks:
        return "no line breaks"
    total = sum(breaks.values())
    return ", ".join(f"{n} {kind}" for kind, n in sorted(breaks.items())) + (" line break" if total == 1
                                                                              else " line breaks")


def split_lines(text: str) -> list[str]:
    """The lines of `text`, split at any line break (CRLF, LF, CR); a final line break ends the last line."""
    lines = re.split(r"\r\n|\n|\r", text)
    if lines and lines[-1] == "":
        lines.pop()
    return lines


def same_encoding(found: str, want: str) -> bool:
    """Whether a file decoded as `found` is stored in the encoding `want` (a name of ENCODINGS): ASCII bytes are
    both ANSI and UTF-8 without BOM."""
    return found == want or (found == "ASCII" and want in ("ANSI", "UTF-8"))


def encode_as(text: str, name: str) -> bytes:
    """`text` stored in the encoding `name` (ASCII: as itself), with its byte order mark."""
    if name == "ASCII":
        return text.encode("ascii")
    enc = ENCODINGS[name]
    return enc.bom + text.encode(enc.codec)


def _pieces(text: str) -> list[str]:
    """The lines of `text`, each with its line break (CRLF, LF or CR), the last one without when it has none."""
    return [p for p in re.split(r"(?<=\n)|(?<=\r)(?!\n)", text) if p]


def first_difference(got: str, want: str) -> str:
    """Where two texts first differ, line by line (line breaks shown), for a reason."""
    g, w = _pieces(got), _pieces(want)
    for i, (a, b) in enumerate(zip(g, w)):
        if a != b:
            return f"line {i + 1} is {_short(a)}, expected {_short(b)}"
    if len(g) > len(w):
        return f"an extra line {len(w) + 1}: {_short(g[len(w)])}"
    if len(g) < len(w):
        return f"{len(g)} line(s), expected {len(w)} (missing {_short(w[len(g)])})"
    return "the same text"


def compare_text(data: bytes, want_text: str, want_encoding: str, what: str) -> Verdict:
    """`data` is exactly `want_text` stored in `want_encoding` (a name of ENCODINGS, or "ASCII"): the same
    characters, line breaks and final line break, the same encoding and byte order mark. The reason names the
    first thing that differs: the encoding, the line breaks or the first differing line."""
    want = f"{what}, stored as {want_encoding} with {describe_breaks(line_breaks(want_text))}"
    try:
        found = decode_text(data)
    except ValueError as exc:
        return Verdict.check(False, want, f"not a text file: {exc}")
    if not found.text:
        return Verdict.check(False, want, "an empty file" + (f" (only a {found.encoding} byte order mark)"
                                                             if data else ""))
    if found.text == want_text and same_encoding(found.encoding, want_encoding):
        return Verdict.check(True, want, "exactly that" + ("" if found.encoding == want_encoding
                                                           else f" ({found.encoding}: the same bytes)"))
    if found.text == want_text:
        return Verdict.check(False, want, f"the right text but stored as {found.encoding}")
    if split_lines(found.text) == split_lines(want_text):
        final_want, final_got = bool(re.search(r"[\r\n]$", want_text)), bool(re.search(r"[\r\n]$", found.text))
        if set(found.breaks) <= set(line_breaks(want_text)) and final_want != final_got:
            return Verdict.check(False, want, "the right lines without a final line break" if final_want
                                 else "the right lines with a final line break added")
        return Verdict.check(False, want, f"the right lines with {describe_breaks(found.breaks)}")
    return Verdict.check(False, want, f"{found.describe()}: {first_difference(found.text, want_text)}")


def _original(state: FinalState, path: str, platform: str | None) -> DecodedText | None:
    data = state.baseline(path, platform)
    if data is None:
        return None
    return decode_text(data)


def unchanged(state: FinalState, paths: list[str] | None, platform: str | None) -> list[str]:
    """What happened to each of `paths` that must be as it was at set-up ("gone" or "changed")."""
    problems = []
    for path in paths or []:
        data = state.pull(path, platform)
        if data is None:
            problems.append(f"{path} gone")
        elif state.baseline(path, platform) is not None and data != state.baseline(path, platform):
            problems.append(f"{path} changed ({len(state.baseline(path, platform))} bytes at set-up, "
                            f"{len(data)} now)")
    return problems


@evaluator("windows_text_replaced")
def windows_text_replaced(state: FinalState, path: str, old: str, new: str, platform: str | None = None) -> Verdict:
    """`path` is its set-up text (listed under `baseline`) with every `old` replaced by `new` and nothing else
    changed: byte for byte, in its encoding, with its line breaks and final line break (Notepad keeps them).
    Without a baseline (a file fed by an upstream subtask): `new` present, `old` absent, one kind of line break."""
    old, new = str(old), str(new)
    data = state.pull(path, platform)
    what = f"{path} with every {old!r} replaced by {new!r}"
    if data is None:
        return Verdict.check(False, what, "no file")
    original = _original(state, path, platform)
    if original is not None:
        if old not in original.text:
            return Verdict.check(False, what, f"no {old!r} in the file at set-up (a broken set-up)")
        return compare_text(data, original.text.replace(old, new), original.encoding,
                            f"{path}: its text with every {old!r} replaced by {new!r}, nothing else changed")
    try:
        found = decode_text(data)
    except ValueError as exc:
        return Verdict.check(False, what, f"not a text file: {exc}")
    ok = new in found.text and old not in found.text and len(found.breaks) <= 1
    return Verdict.check(ok, what + " (no set-up copy to compare with)",
                         f"{found.text.count(new)} {new!r}, {found.text.count(old)} {old!r}, "
                         f"{describe_breaks(found.breaks)}")


@evaluator("windows_text_encoded")
def windows_text_encoded(state: FinalState, path: str, source: str, encoding: str, bom: str = "any",
                         platform: str | None = None) -> Verdict:
    """`path` holds exactly the text of `source` (as it was at set-up: listed under `baseline`; else as it is
    now) stored in `encoding` (a name of ENCODINGS: ANSI, UTF-8, UTF-16 LE, UTF-16 BE), with the source's line
    breaks, and `source` itself is unchanged. `bom` for UTF-8: "any" (with or without a byte order mark: Windows
    10's Notepad writes none for "UTF-8" and one for "UTF-8 with BOM", Wine's always one), "yes" or "no". UTF-16
    is always with its byte order mark (Notepad cannot read it without)."""
    enc = lookup_encoding(encoding)
    base = state.baseline(source, platform)
    src = base if base is not None else state.pull(source, platform)
    what = f"{path}: the text of {source} in {enc.name}"
    if src is None:
        return Verdict.check(False, what, f"no {source}")
    text = decode_text(src).text
    data = state.pull(path, platform)
    if data is None:
        return Verdict.check(False, what, "no file")
    names = [enc.name]
    if enc.name in ("UTF-8", "UTF-8 with BOM"):
        names = {"any": ["UTF-8 with BOM", "UTF-8"], "yes": ["UTF-8 with BOM"], "no": ["UTF-8"]}[bom]
        if not any(ord(c) > 127 for c in text) and "UTF-8" in names:
            names.append("ASCII")
    verdicts = [compare_text(data, text, name, what) for name in names]
    verdict = next((v for v in verdicts if v.passed), verdicts[0])
    if not verdict.passed:
        if len(names) > 1:
            return Verdict(False, verdict.reason.replace(f"stored as {names[0]}",
                                                         f"stored as {' or '.join(names[:2])}", 1))
        return verdict
    lost = unchanged(state, [source], platform) if base is not None else []
    return Verdict.check(not lost, what + f" and {source} kept unchanged", "; ".join(lost) or verdict.reason
                         .partition("found ")[2])


@evaluator("windows_text_line_endings")
def windows_text_line_endings(state: FinalState, path: str, newline: str = "CRLF",
                              platform: str | None = None) -> Verdict:
    """Every line break of `path` converted to `newline` (CRLF, LF or CR) and nothing else changed: its set-up
    text (listed under `baseline`) with each line break (of any kind) replaced, byte for byte in the same
    encoding, the final line break kept where there was one. Without a baseline (a file fed by an upstream
    subtask): only that every line break is `newline` and there is at least one."""
    sep = {"CRLF": "\r\n", "LF": "\n", "CR": "\r"}[newline.upper()]
    data = state.pull(path, platform)
    what = f"{path} with {newline.upper()} line breaks"
    if data is None:
        return Verdict.check(False, what, "no file")
    original = _original(state, path, platform)
    if original is not None:
        want = re.sub(r"\r\n|\n|\r", lambda m: sep, original.text)
        return compare_text(data, want, original.encoding, f"{path}: its text with every line break {newline.upper()}"
                            ", nothing else changed")
    try:
        found = decode_text(data)
    except ValueError as exc:
        return Verdict.check(False, what, f"not a text file: {exc}")
    ok = set(found.breaks) == {newline.upper()}
    return Verdict.check(ok, what + " only (no set-up copy to compare with)", describe_breaks(found.breaks))


@evaluator("windows_text_lines")
def windows_text_lines(state: FinalState, path: str, lines: list[str], newline: str = "CRLF",
                       encodings: list[str] | None = None, platform: str | None = None) -> Verdict:
    """`path` is a text file of exactly `lines` (no other line, none changed; a final line break or none), every
    line break `newline` (CRLF: what Notepad writes), stored in one of `encodings` (names of ENCODINGS; default:
    any of them — ANSI, UTF-8 with or without BOM, UTF-16 LE or BE with its BOM)."""
    sep = {"CRLF": "\r\n", "LF": "\n", "CR": "\r"}[newline.upper()]
    lines = [str(x) for x in lines]
    allowed = [lookup_encoding(e).name for e in encodings] if encodings else list(ENCODINGS)
    body = sep.join(lines)
    what = f"{path} with the {len(lines)} lines {_short(' / '.join(lines), 120)}"
    data = state.pull(path, platform)
    if data is None:
        return Verdict.check(False, what, "no file")
    try:
        found = decode_text(data)
    except ValueError as exc:
        return Verdict.check(False, what, f"not a text file: {exc}")
    encoding_ok = any(same_encoding(found.encoding, e) for e in allowed)
    for want_text in (body, body + sep):
        if found.text == want_text and encoding_ok:
            return Verdict.check(True, what + f", {newline.upper()} line breaks", f"exactly that ({found.encoding})")
    if not encoding_ok:
        return Verdict.check(False, what + f" in {' or '.join(allowed)}", f"{found.encoding}")
    got = split_lines(found.text)
    if got == lines:
        return Verdict.check(False, what + f", {newline.upper()} line breaks", f"the lines with "
                             f"{describe_breaks(found.breaks)}")
    return Verdict.check(False, what, f"{found.describe()}: {first_difference(found.text, body + sep)}")


@evaluator("windows_text_lines_deleted")
def windows_text_lines_deleted(state: FinalState, path: str, word: str, kept: list[str] | None = None,
                               platform: str | None = None) -> Verdict:
    """Every line of `path` containing `word` (any case) deleted, nothing else changed: its set-up text (listed
    under `baseline`) without those lines, byte for byte, in its encoding with its line breaks. Without a
    baseline: no line contains `word` and every line of `kept` is still there."""
    word = str(word)
    data = state.pull(path, platform)
    what = f"{path} without its lines containing {word!r}"
    if data is None:
        return Verdict.check(False, what, "no file")
    original = _original(state, path, platform)
    if original is not None:
        pieces = _pieces(original.text)
        want = "".join(p for p in pieces if word.casefold() not in p.casefold())
        removed = sum(1 for p in pieces if word.casefold() in p.casefold())
        if not removed:
            return Verdict.check(False, what, f"no line with {word!r} at set-up (a broken set-up)")
        return compare_text(data, want, original.encoding,
                            f"{path}: its text without the {removed} line(s) containing {word!r}, nothing else changed")
    try:
        found = decode_text(data)
    except ValueError as exc:
        return Verdict.check(False, what, f"not a text file: {exc}")
    got = split_lines(found.text)
    bad = [line for line in got if word.casefold() in line.casefold()]
    lost = [k for k in kept or [] if k not in got]
    return Verdict.check(not bad and not lost, what + " (no set-up copy to compare with)",
                         f"{len(bad)} line(s) with it" + (f"; lost {lost!r}" if lost else ""))


# -- RTF -------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Run:
    """A stretch of paragraph text with one character formatting. `size` is in points."""

    text: str
    bold: bool = False
    italic: bool = False
    underline: bool = False
    size: float = 12.0
    font: str | None = None


@dataclass
class Paragraph:
    runs: list[Run] = field(default_factory=list)

    @property
    def text(self) -> str:
        return "".join(r.text for r in self.runs)

    def visible(self) -> list[Run]:
        """The runs that show something (white space alone carries no visible bold or size)."""
        return [r for r in self.runs if r.text.strip()]

    def all_bold(self) -> bool:
        runs = self.visible()
        return bool(runs) and all(r.bold for r in runs)

    def any_bold(self) -> bool:
        return any(r.bold for r in self.visible())

    def sizes(self) -> set[float]:
        return {r.size for r in self.visible()}

    def describe_bold(self) -> str:
        runs = self.visible()
        bold = "".join(r.text for r in runs if r.bold)
        if not bold:
            return "not bold"
        return "all bold" if self.all_bold() else f"partly bold ({_short(bold, 40)} only)"


@dataclass
class RtfDocument:
    paragraphs: list[Paragraph]
    fonts: dict[int, str]
    codepage: str = "cp1252"

    def texts(self) -> list[str]:
        """The paragraphs' texts, trailing empty paragraphs dropped (an editor's last empty paragraph)."""
        texts = [p.text for p in self.paragraphs]
        while texts and not texts[-1].strip():
            texts.pop()
        return texts

    def content(self) -> list[Paragraph]:
        out = list(self.paragraphs)
        while out and not out[-1].text.strip():
            out.pop()
        return out


# Destinations whose text is not document text (RTF 1.9.1 spec; `{\*\dest ...}` groups are skipped as well).
SKIP_DESTINATIONS = frozenset({
    "colortbl", "stylesheet", "info", "pict", "object", "header", "headerl", "headerr", "headerf",
    "footer", "footerl", "footerr", "footerf", "footnote", "annotation", "fldinst", "listtable",
    "listoverridetable", "revtbl", "rsidtbl", "generator", "xmlnstbl", "filetbl", "themedata", "colorschememapping",
    "latentstyles", "datastore", "pntext", "pntxta", "pntxtb", "title", "author", "operator", "keywords",
    "comment", "doccomm", "bkmkstart", "bkmkend", "field-private", "txe", "xe", "tc", "shpinst", "nonshppict"})
SYMBOLS = {"tab": "\t", "line": "\n", "emdash": "\u2014", "endash": "\u2013", "bullet": "\u2022",
           "lquote": "\u2018", "rquote": "\u2019", "ldblquote": "\u201c", "rdblquote": "\u201d",
           "emspace": "\u2003", "enspace": "\u2002", "qmspace": "\u2005", "cell": "\t"}
TOKEN = re.compile(rb"\\([a-zA-Z]{1,32})(-?\d{1,10})? ?|\\'([0-9a-fA-F]{2})|\\(.)|([{}])|([\r\n]+)|([^\\{}\r\n]+)",
                   re.DOTALL)
CODEPAGES = {437: "cp437", 850: "cp850", 1250: "cp1250", 1251: "cp1251", 1252: "cp1252", 1253: "cp1253",
             1254: "cp1254", 1255: "cp1255", 1256: "cp1256", 1257: "cp1257", 10000: "mac_roman", 65001: "utf-8"}


@dataclass
class _State:
    """The character formatting and destination of one RTF group (a child group starts as a copy)."""

    bold: bool = False
    italic: bool = False
    underline: bool = False
    half_points: int = 24
    font: int | None = None
    dest: str = "body"        # body (document text), fonttbl (the font table) or skip (text to ignore)
    uc: int = 1               # fallback characters after \uN

    def copy(self) -> "_State":
        return _State(**self.__dict__)


def is_rtf(data: bytes) -> bool:
    """Whether `data` begins as an RTF document does (`{\\rtf`, after white space)."""
    return data.lstrip(b" \t\r\n").startswith(b"{\\rtf")


class _Reader:
    """One pass over an RTF document's tokens (see `parse_rtf`)."""

    def __init__(self) -> None:
        self.codepage = "cp1252"
        self.deff: int | None = None
        self.fonts: dict[int, str] = {}
        self.paragraphs: list[Paragraph] = [Paragraph()]
        self.stack: list[_State] = []
        self.state = _State()
        self.skip_chars = 0          # \uN fallback characters still to skip
        self.high: int | None = None  # the high surrogate of a \uN pair
        self.raw = bytearray()        # consecutive \'hh bytes, decoded together
        self.font_no: int | None = None
        self.font_name: list[str] = []

    # text
    def text(self, text: str) -> None:
        if self.state.dest == "fonttbl":
            for i, part in enumerate(text.split(";")):
                if i:
                    self.end_font()
                self.font_name.append(part)
            return
        if self.state.dest != "body" or not text:
            return
        s = self.state
        font = self.fonts.get(s.font if s.font is not None else (self.deff if self.deff is not None else -1))
        run = Run(text, s.bold, s.italic, s.underline, s.half_points / 2, font)
        runs = self.paragraphs[-1].runs
        if runs and (runs[-1].bold, runs[-1].italic, runs[-1].underline, runs[-1].size, runs[-1].font) == \
                (run.bold, run.italic, run.underline, run.size, run.font):
            runs[-1] = Run(runs[-1].text + text, run.bold, run.italic, run.underline, run.size, run.font)
        else:
            runs.append(run)

    def flush_raw(self) -> None:
        if self.raw:
            data, self.raw = bytes(self.raw), bytearray()
            self.text(data.decode(self.codepage, errors="replace"))

    def unicode(self, value: int) -> None:
        unit = value + 65536 if value < 0 else value
        if 0xD800 <= unit < 0xDC00:
            self.high = unit
            return
        if 0xDC00 <= unit < 0xE000 and self.high is not None:
            self.text(chr(0x10000 + ((self.high - 0xD800) << 10) + (unit - 0xDC00)))
        else:
            self.text(chr(unit))
        self.high = None

    def end_font(self) -> None:
        if self.font_no is not None:
            self.fonts[self.font_no] = "".join(self.font_name).strip()
        self.font_no, self.font_name = None, []

    def new_paragraph(self) -> None:
        if self.state.dest == "body":
            self.paragraphs.append(Paragraph())

    # control words
    def word(self, name: str, value: int | None) -> None:
        s = self.state
        if name in SKIP_DESTINATIONS:
            s.dest = "skip"
        elif name == "fonttbl":
            s.dest = "fonttbl"
        elif name == "ansicpg" and value is not None:
            self.codepage = CODEPAGES.get(value, "cp1252")
        elif name == "deff":
            self.deff = value
        elif name == "f":
            if s.dest == "fonttbl":
                self.end_font()
                self.font_no = value
            else:
                s.font = value
        elif name == "b":
            s.bold = value != 0
        elif name == "i":
            s.italic = value != 0
        elif name in ("ul", "uld", "uldb", "ulw", "ulth", "uldash", "ulwave"):
            s.underline = value != 0
        elif name == "ulnone":
            s.underline = False
        elif name == "fs":
            s.half_points = value if value is not None and value > 0 else 24
        elif name == "plain":
            s.bold = s.italic = s.underline = False
            s.half_points, s.font = 24, None
        elif name == "uc":
            s.uc = max(0, value if value is not None else 1)
        elif name == "u" and value is not None:
            self.unicode(value)
            self.skip_chars = s.uc
        elif name in ("par", "sect", "row"):
            self.new_paragraph()
        elif name in SYMBOLS:
            self.text(SYMBOLS[name])

    def read(self, body: bytes) -> int:
        """Read `body` (it begins with `{\\rtf`); returns where the document's outermost group closes."""
        for m in TOKEN.finditer(body):
            word, param, hexbyte, symbol, brace, newline, text = m.groups()
            if newline is not None:
                continue  # CR and LF in RTF source are not text
            if hexbyte is None:
                self.flush_raw()
            if self.skip_chars and brace is None and word is None:  # the fallback of a \uN
                if text is not None and len(text) > self.skip_chars:
                    text, self.skip_chars = text[self.skip_chars:], 0
                else:
                    self.skip_chars -= len(text) if text is not None else 1
                    continue
            if brace == b"{":
                self.stack.append(self.state)
                self.state = self.state.copy()
            elif brace == b"}":
                if self.state.dest == "fonttbl" and (not self.stack or self.stack[-1].dest != "fonttbl"):
                    self.end_font()
                if not self.stack:
                    raise ValueError("a closing brace without its opening one")
                self.state = self.stack.pop()
                if not self.stack:
                    return m.end()
            elif word is not None:
                self.skip_chars = 0
                if word == b"bin":
                    raise ValueError("binary data (\\bin) outside a picture or object")
                self.word(word.decode("ascii"), int(param) if param is not None else None)
            elif hexbyte is not None:
                self.raw.append(int(hexbyte, 16))
            elif symbol is not None:
                ch = symbol.decode("latin-1")
                if ch == "*":
                    self.state.dest = "skip"
                elif ch in "\\{}":
                    self.text(ch)
                elif ch == "~":
                    self.text("\u00a0")
                elif ch == "_":
                    self.text("\u2011")
                elif ch in "\r\n":
                    self.new_paragraph()
                # \- (optional hyphen), \| and \: carry no text
            elif text is not None:
                self.text(text.decode(self.codepage, errors="replace"))
        raise ValueError(f"its groups do not balance ({len(self.stack)} left open)")


def parse_rtf(data: bytes) -> RtfDocument:
    """The paragraphs of an RTF document with the formatting of each run of text (see the module's docstring).
    Raises ValueError for bytes that are not RTF or whose groups do not balance."""
    body = data.lstrip(b" \t\r\n")
    if not body.startswith(b"{\\rtf"):
        raise ValueError(f"not RTF: it begins with {data[:12]!r}, not {{\\rtf")
    reader = _Reader()
    end = reader.read(body)
    if body[end:].strip(b"\x00 \t\r\n"):
        raise ValueError(f"text after the document's closing brace: {body[end:end + 20]!r}")
    paragraphs = reader.paragraphs
    while len(paragraphs) > 1 and not paragraphs[-1].runs:
        paragraphs.pop()  # the paragraph opened by the last \\par is empty
    return RtfDocument(paragraphs, reader.fonts, reader.codepage)


# -- RTF evaluators --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Format:
    """A paragraph's character formatting in short: bold, italic and underline each "all", "none" or "part" of
    its visible text, and the font sizes (points) its visible text has."""

    bold: str
    italic: str
    underline: str
    sizes: tuple[float, ...]

    def describe(self) -> str:
        words = {"all": "{}", "part": "partly {}", "none": "not {}"}
        parts = [words[self.bold].format("bold")] + [words[getattr(self, k)].format(k) for k in ("italic", "underline")
                                                     if getattr(self, k) != "none"]
        sizes = "/".join(f"{s:g}" for s in self.sizes) or "no text at any"
        return ", ".join(parts + [f"{sizes} pt"])


def paragraph_format(p: Paragraph) -> Format:
    runs = p.visible()

    def share(attr: str) -> str:
        on = [getattr(r, attr) for r in runs]
        return "all" if on and all(on) else ("part" if any(on) else "none")

    return Format(share("bold"), share("italic"), share("underline"), tuple(sorted(p.sizes())))


def read_rtf(state: FinalState, path: str, platform: str | None) -> tuple[RtfDocument | None, str]:
    """(the parsed RTF document at `path`, "") or (None, why not: no file, not RTF, unreadable)."""
    data = state.pull(path, platform)
    if data is None:
        return None, "no file"
    try:
        return parse_rtf(data), ""
    except ValueError as exc:
        return None, str(exc)


def _baseline_rtf(state: FinalState, path: str, platform: str | None) -> RtfDocument | None:
    data = state.baseline(path, platform)
    return None if data is None else parse_rtf(data)


def compare_paragraphs(doc: RtfDocument, want: list[tuple[str, Format | None]]) -> str | None:
    """None when `doc`'s paragraphs (trailing empty ones aside) are exactly `want`: (text, formatting; None:
    any formatting) in order; else what differs first."""
    got = doc.content()
    for i, ((text, fmt), p) in enumerate(zip(want, got)):
        if p.text != text:
            return f"paragraph {i + 1} reads {_short(p.text)}, expected {_short(text)}"
        if fmt is not None and paragraph_format(p) != fmt:
            return f"paragraph {i + 1} ({_short(text, 40)}) is {paragraph_format(p).describe()}, expected " \
                   f"{fmt.describe()}"
    if len(got) > len(want):
        return f"an extra paragraph {len(want) + 1}: {_short(got[len(want)].text)}"
    if len(got) < len(want):
        return f"{len(got)} paragraph(s), expected {len(want)} (missing {_short(want[len(got)][0])})"
    return None


def _target(original: RtfDocument, text: str) -> int | None:
    for i, p in enumerate(original.content()):
        if p.text.strip() == text.strip():
            return i
    return None


def check_rtf_change(doc: RtfDocument, original: RtfDocument, text: str, change: dict, what: str) -> Verdict:
    """`doc` is `original` with the paragraph reading `text` given the formatting `change` (fields of Format)
    and every other paragraph, and every text, as it was."""
    index = _target(original, text)
    if index is None:
        return Verdict.check(False, what, f"no paragraph {text!r} in the document at set-up (a broken set-up)")
    want = []
    for i, p in enumerate(original.content()):
        fmt = paragraph_format(p)
        if i == index:
            fmt = Format(**{**fmt.__dict__, **change})
        want.append((p.text, fmt))
    problem = compare_paragraphs(doc, want)
    if problem is None:
        return Verdict.check(True, what, "so")
    return Verdict.check(False, what, problem)


@evaluator("rtf_paragraph_bold")
def rtf_paragraph_bold(state: FinalState, path: str, text: str, others: list[str] | None = None,
                       platform: str | None = None) -> Verdict:
    """`path` is an RTF document (its real format) in which the paragraph `text` is bold throughout and nothing
    else changed: the same paragraphs and texts as at set-up (listed under `baseline`), every other paragraph
    with its set-up formatting (not bold), the title's italic, underline and size as they were. Without a
    baseline: `text` is all bold and the paragraphs `others` are there and not bold."""
    text = str(text)
    what = f"{path}: an RTF document whose paragraph {text!r} is bold, nothing else changed"
    doc, why = read_rtf(state, path, platform)
    if doc is None:
        return Verdict.check(False, what, why)
    original = _baseline_rtf(state, path, platform)
    if original is not None:
        return check_rtf_change(doc, original, text, {"bold": "all"}, what)
    paras = {p.text.strip(): p for p in doc.content()}
    if text.strip() not in paras:
        return Verdict.check(False, what, f"no paragraph {text!r}; paragraphs {[_short(t, 30) for t in paras]}")
    problems = [] if paras[text.strip()].all_bold() else [f"the title {paras[text.strip()].describe_bold()}"]
    for other in others or []:
        p = paras.get(str(other).strip())
        if p is None:
            problems.append(f"{other!r} gone")
        elif p.any_bold():
            problems.append(f"{_short(str(other), 30)} {p.describe_bold()}")
    return Verdict.check(not problems, what + " (no set-up copy to compare with)", "; ".join(problems) or "so")


@evaluator("rtf_font_size")
def rtf_font_size(state: FinalState, path: str, text: str, size: float, platform: str | None = None) -> Verdict:
    """`path` is an RTF document (its real format) in which all the text of the paragraph `text` is `size`
    points (exactly: RTF stores half points, and WordPad writes the size typed) and nothing else changed: the
    same paragraphs and texts as at set-up (listed under `baseline`), the other paragraphs' sizes and every
    paragraph's bold, italic and underline as they were. Without a baseline: that paragraph's size only."""
    text, size = str(text), float(size)
    what = f"{path}: an RTF document whose paragraph {text!r} is {size:g} pt (exactly), nothing else changed"
    doc, why = read_rtf(state, path, platform)
    if doc is None:
        return Verdict.check(False, what, why)
    original = _baseline_rtf(state, path, platform)
    if original is not None:
        return check_rtf_change(doc, original, text, {"sizes": (size,)}, what)
    p = next((p for p in doc.content() if p.text.strip() == text.strip()), None)
    if p is None:
        return Verdict.check(False, what, f"no paragraph {text!r}")
    return Verdict.check(p.sizes() == {size}, what + " (no set-up copy to compare with)",
                         "/".join(f"{s:g}" for s in sorted(p.sizes())) + " pt")


@evaluator("rtf_matches_text")
def rtf_matches_text(state: FinalState, path: str, source: str, platform: str | None = None) -> Verdict:
    """`path` is an RTF document (its real format, not text under an .rtf name) whose paragraphs are exactly the
    lines of the text file `source` (as it was at set-up when listed under `baseline`, else as it is), and
    `source` itself is still there unchanged."""
    what = f"{path}: an RTF document with the lines of {source} as its paragraphs"
    base = state.baseline(source, platform)
    src = base if base is not None else state.pull(source, platform)
    if src is None:
        return Verdict.check(False, what, f"no {source}")
    lines = split_lines(decode_text(src).text)
    while lines and not lines[-1].strip():
        lines.pop()
    doc, why = read_rtf(state, path, platform)
    if doc is None:
        return Verdict.check(False, what, why)
    problem = compare_paragraphs(doc, [(line, None) for line in lines])
    if problem:
        return Verdict.check(False, what, problem)
    lost = unchanged(state, [source], platform)
    return Verdict.check(not lost, what + f", {source} kept", "; ".join(lost) or f"the {len(lines)} paragraphs")


@evaluator("text_matches_rtf")
def text_matches_rtf(state: FinalState, path: str, source: str, newline: str = "CRLF",
                     platform: str | None = None) -> Verdict:
    """`path` is a plain text file (not RTF under a .txt name) whose lines are exactly the paragraphs of the RTF
    document `source` (as it was at set-up when listed under `baseline`, else as it is), `newline` line breaks
    (CRLF: what WordPad writes), in any encoding of ENCODINGS (WordPad's "Text document" is ANSI, its "Unicode
    text document" UTF-16 LE); and `source` itself is still there unchanged."""
    what = f"{path}: plain text with the paragraphs of {source} as its lines"
    base = state.baseline(source, platform)
    src = base if base is not None else state.pull(source, platform)
    if src is None:
        return Verdict.check(False, what, f"no {source}")
    try:
        paragraphs = parse_rtf(src).texts()
    except ValueError as exc:
        return Verdict.check(False, what, f"{source} unreadable: {exc}")
    data = state.pull(path, platform)
    if data is None:
        return Verdict.check(False, what, "no file")
    if is_rtf(data):
        return Verdict.check(False, what, "an RTF document, not plain text")
    verdict = windows_text_lines(state, path, paragraphs, newline=newline, platform=platform)
    if not verdict.passed:
        return verdict
    lost = unchanged(state, [source], platform)
    return Verdict.check(not lost, what + f", {source} kept", "; ".join(lost) or verdict.reason.partition("found ")[2])


DATE_FORMATS = ("%m/%d/%Y", "%m/%d/%y", "%d/%m/%Y", "%d.%m.%Y", "%Y-%m-%d", "%A, %B %d, %Y", "%B %d, %Y",
                "%A, %d %B %Y", "%d %B %Y", "%a, %b %d, %Y", "%b %d, %Y", "%d %b %Y", "%d-%b-%y", "%d-%b-%Y")
TIME = re.compile(r"\s*,?\s*\d{1,2}:\d{2}(:\d{2})?(\s*[AaPp]\.?[Mm]\.?)?$")


LABEL = re.compile(r"^(date|today|dated|datum)\s*:?\s*", re.I)


def parse_date(text: str) -> _dt.date | None:
    """The date `text` names in one of WordPad's (Insert > Date and time) or other common written forms, a label
    such as "Date:" before it and a time of day after it allowed; None when it names none."""
    text = TIME.sub("", LABEL.sub("", text.strip()).rstrip("."))
    for fmt in DATE_FORMATS:
        try:
            return _dt.datetime.strptime(text, fmt).date()
        except ValueError:
            continue
    return None


@evaluator("rtf_date_added")
def rtf_date_added(state: FinalState, path: str, tolerance_days: int = 1, platform: str | None = None) -> Verdict:
    """`path` is an RTF document (its real format) whose last paragraph is today's date (in any form WordPad's
    Insert > Date and time or a person writes it, e.g. 11/24/2026 or Tuesday, November 24, 2026; today by the
    host's clock in UTC, within `tolerance_days` for time zones and midnight), and whose other paragraphs are
    the set-up document's (listed under `baseline`) with their texts and formatting unchanged (empty paragraphs
    aside). Without a baseline: only the date and at least one paragraph before it."""
    today = _dt.datetime.now(_dt.timezone.utc).date()
    what = f"{path}: an RTF document ending with today's date ({today}, \u00b1{tolerance_days} day), nothing else " \
           "changed"
    doc, why = read_rtf(state, path, platform)
    if doc is None:
        return Verdict.check(False, what, why)
    got = [p for p in doc.content() if p.text.strip()]
    if not got:
        return Verdict.check(False, what, "an empty document")
    last = got[-1].text.strip()
    date = parse_date(last)
    if date is None:
        return Verdict.check(False, what, f"the last paragraph {_short(last)}, not a date")
    if abs((date - today).days) > int(tolerance_days):
        return Verdict.check(False, what, f"the date {date} in the last paragraph {_short(last)}")
    original = _baseline_rtf(state, path, platform)
    if original is None:
        return Verdict.check(len(got) > 1, what + " (no set-up copy to compare with)",
                             f"{date}" if len(got) > 1 else "the date alone")
    before = RtfDocument(got[:-1], doc.fonts)
    problem = compare_paragraphs(before, [(p.text, paragraph_format(p)) for p in original.content()
                                          if p.text.strip()])
    return Verdict.check(problem is None, what, problem or f"{_short(last)} after the original paragraphs")
