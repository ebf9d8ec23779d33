"""RTF documents (what WordPad saves by default; LibreOffice reads and writes them too), read from their bytes,
and the evaluators of WordPad's templates: a paragraph made bold or resized, a date added, a conversion from or
to plain text.

`parse_rtf` is a small reader of the RTF 1.x syntax (groups, control words and symbols, `\\'hh` and `\\uN`
escapes with their `\\uc` fallbacks, the font and colour tables, skipped destinations such as the style sheet,
document info and `{\\*...}` groups) that tracks the formatting each character of a paragraph carries through
groups, `\\plain` and `\\pard`, and splits the text into paragraphs at `\\par`. Character formatting: bold
(`\\b`), italic (`\\i`), underline (`\\ul` and its kinds), strikethrough (`\\strike`, `\\striked`), hidden text
(`\\v`), font size (`\\fs`, half points), font (`\\f`, by name from the font table), colour (`\\cf`, resolved
through the colour table to RGB; the automatic colour and explicit black are one: black text on white) and
highlight (`\\highlight`, `\\cb`); paragraph formatting: alignment (`\\ql`, `\\qc`, `\\qr`, `\\qj`). Binary data
(`\\bin`) is refused: none of the documents these tasks read has pictures. No PyPI package fits: striprtf gives
text only, rtfparse a tree of groups and control words without the formatting state, pyth (2014, Python 2) and
pyth3 (2019) bold and italic but not the font size. A file is RTF when its bytes begin with `{\\rtf` and its
groups balance; after the closing brace only white space and NULs may follow (WordPad under Wine writes a NUL).

How documents are compared: every formatting property the reader knows is compared character by character
(white space aside: it shows no formatting), except the one the instruction asks to change. Hidden text is text:
a paragraph made hidden shows as a formatting change, text added hidden as a change of text, so hiding cannot
mask an edit.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field, replace
from typing import Any, Callable

from jarvis_pytest.evaluators.dates import allowed_days, parse_date
from jarvis_pytest.evaluators.folders import changed_since_setup
from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.state import FinalState
from jarvis_pytest.evaluators.text import codepage, decode_text, file_text_lines, split_lines

AUTO = "auto"  # the automatic text colour (black on white)
PAGE = "#ffffff"  # the colour of the page WordPad shows
PROPS = ("bold", "italic", "underline", "strike", "hidden", "size", "font", "color", "highlight")


def _short(text: str, limit: int = 80) -> str:
    return repr(text if len(text) <= limit else text[:limit] + "…")


# -- the document model ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Run:
    """A stretch of paragraph text with one character formatting. `size` is in points, `font` a name of the font
    table, `color` "#rrggbb" or AUTO, `highlight` "#rrggbb" or None."""

    text: str
    bold: bool = False
    italic: bool = False
    underline: bool = False
    size: float = 12.0
    font: str | None = None
    strike: bool = False
    hidden: bool = False
    color: str = AUTO
    highlight: str | None = None

    def style(self) -> dict[str, Any]:
        """The run's character formatting, property by property (PROPS)."""
        return {p: getattr(self, p) for p in PROPS}


@dataclass
class Paragraph:
    runs: list[Run] = field(default_factory=list)
    align: str = "left"

    @property
    def text(self) -> str:
        return "".join(r.text for r in self.runs)

    def inked(self) -> list[Run]:
        """The runs that carry formatting one can see (white space alone shows no bold or size)."""
        return [r for r in self.runs if r.text.strip()]

    def styles(self) -> list[dict[str, Any]]:
        """The character formatting of each character of `text`, in order."""
        return [r.style() for r in self.runs for _ in r.text]

    def hidden_text(self) -> str:
        return "".join(r.text for r in self.inked() if r.hidden)

    def unseen_text(self) -> str:
        """The text that does not show: hidden, or white on the white page (not highlighted)."""
        return "".join(r.text for r in self.inked() if r.hidden or (r.color == PAGE and not r.highlight))

    def all_bold(self) -> bool:
        runs = self.inked()
        return bool(runs) and all(r.bold for r in runs)

    def any_bold(self) -> bool:
        return any(r.bold for r in self.inked())

    def sizes(self) -> set[float]:
        return {r.size for r in self.inked()}

    def describe_bold(self) -> str:
        bold = "".join(r.text for r in self.inked() if r.bold)
        if not bold:
            return "not bold"
        return "all bold" if self.all_bold() else f"partly bold ({_short(bold, 40)} only)"


@dataclass
class RtfDocument:
    paragraphs: list[Paragraph]
    fonts: dict[int, str]
    codepage: str = "cp1252"
    colors: list[str | None] = field(default_factory=list)

    def texts(self) -> list[str]:
        """The paragraphs' texts, trailing empty paragraphs dropped (an editor's last empty paragraph)."""
        return [p.text for p in self.content()]

    def content(self) -> list[Paragraph]:
        out = list(self.paragraphs)
        while out and not out[-1].text.strip():
            out.pop()
        return out


# -- the reader -------------------------------------------------------------------------------------------------------
# Destinations whose text is not document text (RTF 1.9.1 spec; `{\*\dest ...}` groups are skipped as well).
SKIP_DESTINATIONS = frozenset({
    "stylesheet", "info", "pict", "object", "header", "headerl", "headerr", "headerf",
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
UNDERLINES = frozenset({"ul", "uld", "uldash", "uldashd", "uldashdd", "uldb", "ulhwave", "ulldash", "ulth",
                        "ulthd", "ulthdash", "ulthdashd", "ulthdashdd", "ulthldash", "ululdbwave", "ulw", "ulwave"})
ALIGNMENTS = {"ql": "left", "qc": "centred", "qr": "right", "qj": "justified", "qd": "distributed"}


@dataclass
class _State:
    """The formatting and destination of one RTF group (a child group starts as a copy)."""

    bold: bool = False
    italic: bool = False
    underline: bool = False
    strike: bool = False
    hidden: bool = False
    half_points: int = 24
    font: int | None = None
    color: int = 0            # an index of the colour table (0: the automatic colour in what WordPad writes)
    highlight: int = 0        # an index of the colour table (0: none)
    align: str = "left"
    dest: str = "body"        # body (document text), fonttbl, colortbl or skip (text to ignore)
    uc: int = 1               # fallback characters after \uN

    def copy(self) -> "_State":
        return _State(**self.__dict__)

    def plain(self) -> None:
        """\\plain: the default character formatting (paragraph formatting and destination stay)."""
        self.bold = self.italic = self.underline = self.strike = self.hidden = False
        self.half_points, self.font, self.color, self.highlight = 24, None, 0, 0


def is_rtf(data: bytes) -> bool:
    """Whether `data` begins as an RTF document does (`{\\rtf`, after white space)."""
    return data.lstrip(b" \t\r\n").startswith(b"{\\rtf")


class _Reader:
    """One pass over an RTF document's tokens (see `parse_rtf`)."""

    def __init__(self) -> None:
        self.codepage = "cp1252"
        self.deff: int | None = None
        self.fonts: dict[int, str] = {}
        self.colors: list[str | None] = []   # the colour table: "#rrggbb", or None for an entry left empty (auto)
        self.rgb: dict[str, int] = {}
        self.paragraphs: list[Paragraph] = [Paragraph()]
        self.stack: list[_State] = []
        self.state = _State()
        self.skip_chars = 0          # \uN fallback characters still to skip
        self.high: int | None = None  # the high surrogate of a \uN pair
        self.raw = bytearray()        # consecutive \'hh bytes, decoded together
        self.font_no: int | None = None
        self.font_name: list[str] = []

    def resolve(self, index: int) -> str | None:
        return self.colors[index] if 0 <= index < len(self.colors) else None

    # text
    def text(self, text: str) -> None:
        if self.state.dest == "fonttbl":
            for i, part in enumerate(text.split(";")):
                if i:
                    self.end_font()
                self.font_name.append(part)
            return
        if self.state.dest == "colortbl":
            for _ in range(text.count(";")):
                self.end_color()
            return
        if self.state.dest != "body" or not text:
            return
        s = self.state
        font = self.fonts.get(s.font if s.font is not None else (self.deff if self.deff is not None else -1))
        color = self.resolve(s.color)
        run = Run(text, s.bold, s.italic, s.underline, s.half_points / 2, font, s.strike, s.hidden,
                  AUTO if color in (None, "#000000") else color, self.resolve(s.highlight) if s.highlight else None)
        paragraph = self.paragraphs[-1]
        paragraph.align = s.align
        if paragraph.runs and paragraph.runs[-1].style() == run.style():
            paragraph.runs[-1] = replace(paragraph.runs[-1], text=paragraph.runs[-1].text + text)
        else:
            paragraph.runs.append(run)

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

    def end_color(self) -> None:
        rgb, self.rgb = self.rgb, {}
        self.colors.append("#%02x%02x%02x" % tuple(rgb.get(c, 0) & 255 for c in ("red", "green", "blue"))
                           if rgb else None)

    def new_paragraph(self) -> None:
        if self.state.dest == "body":
            self.paragraphs[-1].align = self.state.align
            self.paragraphs.append(Paragraph())

    # control words
    def word(self, name: str, value: int | None) -> None:
        s = self.state
        on = value != 0
        if name in SKIP_DESTINATIONS:
            s.dest = "skip"
        elif name in ("fonttbl", "colortbl"):
            s.dest = name
        elif s.dest == "colortbl":
            if name in ("red", "green", "blue") and value is not None:
                self.rgb[name] = value
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
        elif name in ("b", "i", "strike", "striked", "v"):
            setattr(s, {"b": "bold", "i": "italic", "striked": "strike", "v": "hidden"}.get(name, name), on)
        elif name in UNDERLINES:
            s.underline = on
        elif name == "ulnone":
            s.underline = False
        elif name == "fs":
            s.half_points = value if value is not None and value > 0 else 24
        elif name == "cf":
            s.color = value or 0
        elif name in ("highlight", "cb", "chcbpat"):
            s.highlight = value or 0
        elif name == "plain":
            s.plain()
        elif name == "pard":
            s.align = "left"
        elif name in ALIGNMENTS:
            s.align = ALIGNMENTS[name]
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
    return RtfDocument(paragraphs, reader.fonts, reader.codepage, reader.colors)


# -- comparing documents -----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Format:
    """A paragraph's character formatting in short, for reasons: bold, italic and underline each "all", "none" or
    "part" of its inked text, and the font sizes (points) it has."""

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
    runs = p.inked()

    def share(attr: str) -> str:
        on = [getattr(r, attr) for r in runs]
        return "all" if on and all(on) else ("part" if any(on) else "none")

    return Format(share("bold"), share("italic"), share("underline"), tuple(sorted(p.sizes())))


@dataclass(frozen=True)
class Expected:
    """What one paragraph must be: its text, the formatting of each of its characters (None: any) and its
    alignment (None: any)."""

    text: str
    styles: tuple[dict[str, Any], ...] | None = None
    align: str | None = None

    @classmethod
    def like(cls, p: Paragraph, **change: Any) -> "Expected":
        """`p` as it is, with the character formatting `change` (properties of PROPS) applied to all its text."""
        return cls(p.text, tuple({**s, **change} for s in p.styles()), p.align)


def show(prop: str, value: Any) -> str:
    """One formatting property's value in words."""
    if prop == "size":
        return f"{value:g} pt"
    if prop == "font":
        return f"in {value}" if value else "in the default font"
    if prop == "color":
        return "in the automatic colour (black)" if value == AUTO else f"in colour {value}"
    if prop == "highlight":
        return f"highlighted {value}" if value else "not highlighted"
    words = {"bold": "bold", "italic": "italic", "underline": "underlined", "strike": "struck through",
             "hidden": "hidden (\\v)"}
    return words[prop] if value else ("visible" if prop == "hidden" else "not " + words[prop])


def style_differences(p: Paragraph, want: tuple[dict[str, Any], ...]) -> list[str]:
    """How the formatting of `p`'s characters differs from `want` (one dict per character; white space aside),
    one phrase per property: which text, what it is, what it should be."""
    got = p.styles()
    found: dict[str, list[int]] = {}
    for i, ch in enumerate(p.text):
        if ch.isspace():
            continue
        for prop in PROPS:
            if got[i][prop] != want[i][prop]:
                found.setdefault(prop, []).append(i)
    out = []
    for prop in PROPS:
        if prop in found:
            at = found[prop]
            span = p.text[at[0]:at[-1] + 1]
            where = "its text" if span.strip() == p.text.strip() else _short(span, 40)
            out.append(f"{where} {show(prop, got[at[0]][prop])}, expected {show(prop, want[at[0]][prop])}")
    return out


def compare_paragraphs(doc: RtfDocument, want: list[Expected]) -> str | None:
    """None when `doc`'s paragraphs (trailing empty ones aside) are exactly `want`, in order; else what differs
    first: a text, the formatting of characters (every property that differs), an alignment, the count."""
    got = doc.content()
    for i, (w, p) in enumerate(zip(want, got)):
        label = f"paragraph {i + 1} ({_short(w.text, 40)})"
        if p.text != w.text:
            return f"paragraph {i + 1} reads {_short(p.text)}, expected {_short(w.text)}"
        problems = style_differences(p, w.styles) if w.styles is not None else []
        if w.align is not None and p.align != w.align:
            problems.append(f"{p.align}-aligned, expected {w.align}-aligned")
        if problems:
            return f"{label}: " + "; ".join(problems)
    if len(got) > len(want):
        return f"an extra paragraph {len(want) + 1}: {_short(got[len(want)].text)}"
    if len(got) < len(want):
        return f"{len(got)} paragraph(s), expected {len(want)} (missing {_short(want[len(got)].text)})"
    return None


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


def _target(original: RtfDocument, text: str) -> int | None:
    for i, p in enumerate(original.content()):
        if p.text.strip() == text.strip():
            return i
    return None


def check_rtf_change(doc: RtfDocument, original: RtfDocument, text: str, change: dict[str, Any],
                     what: str) -> Verdict:
    """`doc` is `original` with the paragraph reading `text` given the character formatting `change` (properties
    of PROPS) and everything else — every text, every other property of every character, every alignment — as
    it was."""
    index = _target(original, text)
    if index is None:
        return Verdict.check(False, what, f"no paragraph {text!r} in the document at set-up (a broken set-up)")
    want = [Expected.like(p, **(change if i == index else {})) for i, p in enumerate(original.content())]
    problem = compare_paragraphs(doc, want)
    return Verdict.check(problem is None, what, problem or "so")


def _fallback_problems(p: Paragraph | None, name: str) -> list[str]:
    if p is None:
        return [f"{name} gone"]
    hidden = p.hidden_text()
    return [f"{name} has hidden text ({_short(hidden, 30)})"] if hidden else []


# -- the evaluators ---------------------------------------------------------------------------------------------------
def _judge_change(state: FinalState, path: str, platform: str | None, text: str, change: dict, what: str,
                  without_baseline: Callable[[RtfDocument], Verdict]) -> Verdict:
    """Read `path` as RTF and judge the `change` of paragraph `text` against its set-up copy (`check_rtf_change`),
    or with `without_baseline` where there is none (an upstream subtask made the file)."""
    doc, why = read_rtf(state, path, platform)
    if doc is None:
        return Verdict.check(False, what, why)
    original = _baseline_rtf(state, path, platform)
    if original is not None:
        return check_rtf_change(doc, original, text, change, what)
    return without_baseline(doc)


@evaluator("rtf_paragraph_bold")
def rtf_paragraph_bold(state: FinalState, path: str, text: str, others: list[str] | None = None,
                       platform: str | None = None) -> Verdict:
    """`path` is an RTF document (its real format) in which the paragraph `text` is bold throughout and nothing
    else changed: the same paragraphs and texts as at set-up (listed under `baseline`), every character's other
    formatting (italic, underline, strikethrough, hidden, size, font, colour, highlight) and every paragraph's
    alignment as they were, the other paragraphs not made bold. Without a baseline: `text` is all bold and the
    paragraphs `others` are there and not bold, none of them hidden."""
    text = str(text)
    what = f"{path}: an RTF document whose paragraph {text!r} is bold, nothing else changed"
    return _judge_change(state, path, platform, text, {"bold": True}, what,
                         lambda doc: _bold_without_baseline(doc, text, others, what))


def _bold_without_baseline(doc: RtfDocument, text: str, others: list[str] | None, what: str) -> Verdict:
    paras = {p.text.strip(): p for p in doc.content()}
    if text.strip() not in paras:
        return Verdict.check(False, what, f"no paragraph {text!r}; paragraphs {[_short(t, 30) for t in paras]}")
    title = paras[text.strip()]
    problems = ([] if title.all_bold() else [f"the title {title.describe_bold()}"]) + _fallback_problems(title,
                                                                                                         "the title")
    for other in others or []:
        p = paras.get(str(other).strip())
        problems += _fallback_problems(p, repr(other))
        if p is not None and p.any_bold():
            problems.append(f"{_short(str(other), 30)} {p.describe_bold()}")
    return Verdict.check(not problems, what + " (no set-up copy to compare with)", "; ".join(problems) or "so")


@evaluator("rtf_font_size")
def rtf_font_size(state: FinalState, path: str, text: str, size: float, platform: str | None = None) -> Verdict:
    """`path` is an RTF document (its real format) in which all the text of the paragraph `text` is `size`
    points (exactly: RTF stores half points, and WordPad writes the size typed) and nothing else changed: the
    same paragraphs and texts as at set-up (listed under `baseline`), every character's other formatting and
    the other paragraphs' sizes as they were. Without a baseline: that paragraph's size, none of it hidden."""
    text, size = str(text), float(size)
    what = f"{path}: an RTF document whose paragraph {text!r} is {size:g} pt (exactly), nothing else changed"
    return _judge_change(state, path, platform, text, {"size": size}, what,
                         lambda doc: _size_without_baseline(doc, text, size, what))


def _size_without_baseline(doc: RtfDocument, text: str, size: float, what: str) -> Verdict:
    p = next((p for p in doc.content() if p.text.strip() == text.strip()), None)
    if p is None:
        return Verdict.check(False, what, f"no paragraph {text!r}")
    problems = _fallback_problems(p, "the paragraph")
    return Verdict.check(p.sizes() == {size} and not problems, what + " (no set-up copy to compare with)",
                         "; ".join(["/".join(f"{s:g}" for s in sorted(p.sizes())) + " pt"] + problems))


def plain_conversion(doc: RtfDocument, lines: list[str]) -> list[Expected]:
    """What an RTF document made from plain text must be: its lines as paragraphs, all text in one font and size
    (whichever the word processor chose), not bold, italic, underlined, struck through or hidden, in the
    automatic colour, not highlighted, left-aligned."""
    first = next((s for p in doc.content() for ch, s in zip(p.text, p.styles()) if not ch.isspace()), None)
    plain = {**Run("", size=first["size"] if first else 12.0, font=first["font"] if first else None).style()}
    return [Expected(line, tuple(plain for _ in line), "left") for line in lines]


@evaluator("rtf_matches_text")
def rtf_matches_text(state: FinalState, path: str, source: str, platform: str | None = None) -> Verdict:
    """`path` is an RTF document (its real format, not text under an .rtf name) whose paragraphs are exactly the
    lines of the text file `source` (as it was at set-up when listed under `baseline`, else as it is), with the
    plain formatting of converted text (`plain_conversion`: one font and size, no emphasis, nothing hidden), and
    `source` itself is still there unchanged."""
    what = f"{path}: an RTF document with the lines of {source} as its paragraphs, plain text formatting"
    base = state.baseline(source, platform)
    src = base if base is not None else state.pull(source, platform)
    if src is None:
        return Verdict.check(False, what, f"no {source}")
    lines = split_lines(decode_text(src, codepage(state, platform)).text)
    while lines and not lines[-1].strip():
        lines.pop()
    doc, why = read_rtf(state, path, platform)
    if doc is None:
        return Verdict.check(False, what, why)
    problem = compare_paragraphs(doc, plain_conversion(doc, lines))
    if problem:
        return Verdict.check(False, what, problem)
    lost = changed_since_setup(state, [source], platform)
    return Verdict.check(not lost, what + f", {source} kept", "; ".join(lost) or f"the {len(lines)} paragraphs")


@evaluator("text_matches_rtf")
def text_matches_rtf(state: FinalState, path: str, source: str, newline: str = "CRLF",
                     platform: str | None = None) -> Verdict:
    """`path` is a plain text file (not RTF under a .txt name) whose lines are exactly the paragraphs of the RTF
    document `source` (as it was at set-up when listed under `baseline`, else as it is), `newline` line breaks
    (CRLF: what WordPad writes), in any encoding of ENCODINGS (WordPad's "Text document" is ANSI, its "Unicode
    text document" UTF-16 LE); and `source` itself is still there unchanged, byte for byte (its formatting and
    hidden text included)."""
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
    verdict = file_text_lines(state, path, paragraphs, newline=newline, platform=platform)
    if not verdict.passed:
        return verdict
    lost = changed_since_setup(state, [source], platform)
    return Verdict.check(not lost, what + f", {source} kept", "; ".join(lost) or verdict.reason.partition("found ")[2])


@evaluator("rtf_date_added")
def rtf_date_added(state: FinalState, path: str, setup_day: str | None = None, platform: str | None = None) -> Verdict:
    """`path` is an RTF document (its real format) whose last paragraph is today's date by the device's own clock,
    asked at evaluation (in any form WordPad's Insert > Date and time or a person writes it, e.g. 11/24/2026 or
    Tuesday, November 24, 2026), shown (not hidden text, not white on the white page); and whose other paragraphs
    are the set-up document's (listed under `baseline`) with their texts, formatting and alignment unchanged
    (empty paragraphs aside). `setup_day`: a file holding the device's date at set-up (listed under `baseline`);
    only when the device's clock crossed midnight since then does the day before count too. Without a baseline:
    the date and at least one paragraph before it."""
    days, when = allowed_days(state, setup_day, platform)
    what = f"{path}: an RTF document ending with {when}, nothing else changed"
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
    if date not in days:
        return Verdict.check(False, what, f"the date {date} in the last paragraph {_short(last)}")
    if got[-1].unseen_text():
        return Verdict.check(False, what, f"the date {_short(last)} as hidden text (\\v) or white on the white page: "
                             f"{_short(got[-1].unseen_text(), 40)} does not show")
    original = _baseline_rtf(state, path, platform)
    if original is None:
        return Verdict.check(len(got) > 1, what + " (no set-up copy to compare with)",
                             f"{date}" if len(got) > 1 else "the date alone")
    before = RtfDocument(got[:-1], doc.fonts)
    problem = compare_paragraphs(before, [Expected.like(p) for p in original.content() if p.text.strip()])
    return Verdict.check(problem is None, what, problem or f"{_short(last)} after the original paragraphs")
