"""Plain text files on any platform, judged from their exact bytes: how they are decoded, their line breaks, the
evaluators of edits that must change nothing else (a line-ending conversion, a word replaced, lines deleted), of
text written in a given encoding or with given lines (Notepad's Save As, a note), and of answers written into text
files (a folder's listing, a number).

Decoding, in one place for every evaluator of plain text: a byte order mark names UTF-8, UTF-16 LE or BE; without
one, pure ASCII is ASCII (the same bytes in ANSI and UTF-8), valid UTF-8 is UTF-8, and anything else is the
platform's 8-bit ("ANSI") code page where it has one (`PlatformSpec.text_codepage`: Windows-1252 on an English
Windows and on Wine here; Ubuntu and Android have none, so such bytes are no text there). NUL bytes without a
UTF-16 mark are no text anywhere. Every line break is classified (CRLF, LF, CR), so a reason can say "expected
UTF-8 with CRLF line breaks, found ANSI with 3 LF".

Expected content comes from the file as it was right after set-up (`state.baseline(path)`, the template lists it
under `baseline`) with only the asked change applied, and is compared byte for byte: the encoding, the byte order
mark, every line break (a stray CR too) and the final line break included — Notepad, Mousepad and Markor keep
them all when they save.
"""

from __future__ import annotations

import re
from collections import Counter
from dataclasses import dataclass
from typing import Any

from jarvis_pytest.devices.platforms import PlatformSpec, spec
from jarvis_pytest.errors import ConfigError
from jarvis_pytest.evaluators.folders import capture_folders, changed_since_setup, with_unchanged
from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.snapshots import setup_capture
from jarvis_pytest.evaluators.state import FinalState
from jarvis_pytest.generators.windows_text import ENCODINGS, encoding as lookup_encoding

BREAKS = {"CRLF": "\r\n", "LF": "\n", "CR": "\r"}


def _short(text: str, limit: int = 80) -> str:
    return repr(text if len(text) <= limit else text[:limit] + "…")


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


def codepage(state: FinalState, platform: str | None = None) -> str | None:
    """The 8-bit code page plain text may be in on the device of `platform` (default: the subtask's)."""
    return spec(platform or state.platform).text_codepage


def decode_text(data: bytes, codepage: str | None = "cp1252") -> DecodedText:
    """The text of a file and its encoding, told from its bytes (see the module's docstring); `codepage` is the
    platform's ANSI code page (None: there is none). Raises ValueError for bytes that are no text. RTF is 7-bit
    text and decodes: callers that need plain text check for it themselves."""
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
        return DecodedText(data.decode("ascii"), "ASCII")
    except UnicodeDecodeError:
        pass
    try:
        return DecodedText(data.decode("utf-8"), "UTF-8")
    except UnicodeDecodeError as exc:
        if codepage is None:
            raise ValueError(f"not UTF-8 text: {exc}") from None
    try:
        return DecodedText(data.decode(codepage), "ANSI")
    except UnicodeDecodeError as exc:  # 0x81, 0x8d, 0x8f, 0x90, 0x9d are unassigned in Windows-1252
        raise ValueError(f"neither UTF-8 nor {codepage} text: {exc}") from None


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


def pieces(text: str) -> list[str]:
    """The lines of `text`, each with its line break (CRLF, LF or CR), the last one without when it has none."""
    return [p for p in re.split(r"(?<=\n)|(?<=\r)(?!\n)", text) if p]


def first_difference(got: str, want: str) -> str:
    """Where two texts first differ, line by line (line breaks shown), for a reason."""
    g, w = pieces(got), pieces(want)
    for i, (a, b) in enumerate(zip(g, w)):
        if a != b:
            return f"line {i + 1} is {_short(a)}, expected {_short(b)}"
    if len(g) > len(w):
        return f"an extra line {len(w) + 1}: {_short(g[len(w)])}"
    if len(g) < len(w):
        return f"{len(g)} line(s), expected {len(w)} (missing {_short(w[len(g)])})"
    return "the same text"


def compare_text(data: bytes, want_text: str, want_encoding: str, what: str,
                 codepage: str | None = "cp1252") -> Verdict:
    """`data` is exactly `want_text` stored in `want_encoding` (a name of ENCODINGS, or "ASCII"): the same
    characters, line breaks and final line break, the same encoding and byte order mark. The reason names the
    first thing that differs: the encoding, the line breaks or the first differing line."""
    want = f"{what}, stored as {want_encoding} with {describe_breaks(line_breaks(want_text))}"
    try:
        found = decode_text(data, codepage)
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


def original_text(state: FinalState, path: str, platform: str | None = None) -> DecodedText | None:
    """The text `path` had right after set-up (listed under `baseline`), or None when there is no baseline."""
    data = state.baseline(path, platform)
    return None if data is None else decode_text(data, codepage(state, platform))


# -- edits that must change nothing else --------------------------------------------------------------------------
def set_up_text(original: bytes, codepage: str | None, want: str) -> DecodedText | Verdict:
    """The text a file had at set-up, or a failed verdict (expecting `want`) naming a broken set-up when it was no
    text then."""
    try:
        return decode_text(original, codepage)
    except ValueError as exc:
        return Verdict.check(False, want, f"no text at set-up ({exc}): a broken set-up")


def check_line_endings(data: bytes, ending: str, original: bytes | None = None, contains: str | None = None,
                       codepage: str | None = "cp1252", name: str = "the file") -> Verdict:
    """`data` is `original` with every line break (of any kind) made `ending` (CRLF, LF or CR, any case), byte for
    byte in the original's encoding, its final line break kept where it had one. Without `original`: every line
    break is `ending` (a stray CR is a CR line break), there is at least one, and the text contains `contains`."""
    kind = ending.upper()
    if kind not in BREAKS:
        return Verdict(False, f"bad evaluator argument: ending {ending!r} (use CRLF, LF or CR)")
    if original is not None:
        before = set_up_text(original, codepage, f"{name} with every line break {kind}")
        if isinstance(before, Verdict):
            return before
        want = re.sub(r"\r\n|\n|\r", BREAKS[kind], before.text)
        return compare_text(data, want, before.encoding, f"{name}: its set-up text with every line break {kind}, "
                            "nothing else changed", codepage)
    what = f"{name} with every line break {kind}"
    if contains:
        what += f", the text still containing {_short(str(contains))}"
    try:
        found = decode_text(data, codepage)
    except ValueError as exc:
        return Verdict.check(False, what, f"not a text file: {exc}")
    if contains is not None and str(contains) not in found.text:
        return Verdict.check(False, what, f"no {_short(str(contains))} in {_short(found.text)}")
    return Verdict.check(set(found.breaks) == {kind}, what + " (no set-up copy to compare with)",
                         describe_breaks(found.breaks))


@evaluator("file_line_endings")
def file_line_endings(state: FinalState, path: str, ending: str, contains: str | None = None,
                      platform: str | None = None) -> Verdict:
    """Every line break of `path` converted to `ending` (CRLF, LF or CR, any case) and nothing else changed: its
    set-up text (listed under `baseline`) with each line break replaced, byte for byte in the same encoding, the
    final line break kept where there was one. Without a baseline (a file an upstream subtask made): every line
    break is `ending`, at least one, and the text still contains `contains`."""
    data = state.pull(path, platform)
    if data is None:
        return Verdict.check(False, f"{path} with {ending.upper()} line breaks", "no file")
    return check_line_endings(data, ending, state.baseline(path, platform), contains, codepage(state, platform), path)


def check_replaced(data: bytes, old: str, new: str, original: bytes | None = None,
                   codepage: str | None = "cp1252", name: str = "the file") -> Verdict:
    """`data` is `original` with every `old` replaced by `new` and nothing else changed, byte for byte (its
    encoding, line breaks and final line break kept). Without `original`: `new` present, `old` absent, one kind
    of line break."""
    if original is not None:
        before = set_up_text(original, codepage, f"{name} with every {old!r} replaced by {new!r}")
        if isinstance(before, Verdict):
            return before
        if old not in before.text:
            return Verdict.check(False, f"{name} with every {old!r} replaced by {new!r}",
                                 f"no {old!r} in the file at set-up (a broken set-up)")
        return compare_text(data, before.text.replace(old, new), before.encoding,
                            f"{name}: its set-up text with every {old!r} replaced by {new!r}, nothing else changed",
                            codepage)
    what = f"{name} with {new!r}, no {old!r} and one kind of line break (no set-up copy to compare with)"
    try:
        found = decode_text(data, codepage)
    except ValueError as exc:
        return Verdict.check(False, what, f"not a text file: {exc}")
    ok = new in found.text and old not in found.text and len(found.breaks) <= 1
    return Verdict.check(ok, what, f"{found.text.count(new)} {new!r}, {found.text.count(old)} {old!r}, "
                                   f"{describe_breaks(found.breaks)}")


@evaluator("file_text_replaced")
def file_text_replaced(state: FinalState, path: str, old: str, new: str, platform: str | None = None) -> Verdict:
    """`path` is its set-up text (listed under `baseline`) with every `old` replaced by `new`, nothing else
    changed: byte for byte, in its encoding, with its line breaks and final line break. Without a baseline (a file
    an upstream subtask made): `new` present, `old` absent, one kind of line break."""
    old, new = str(old), str(new)
    data = state.pull(path, platform)
    if data is None:
        return Verdict.check(False, f"{path} with every {old!r} replaced by {new!r}", "no file")
    return check_replaced(data, old, new, state.baseline(path, platform), codepage(state, platform), path)



def check_lines_deleted(data: bytes, word: str, kept: list[str], original: bytes | None = None,
                        codepage: str | None = "cp1252", name: str = "the file") -> Verdict:
    """`data` is `original` without every line containing `word` (any case) — each deleted with its line break —
    and nothing else changed, byte for byte (its encoding, byte order mark and every other line break kept). When
    the deleted lines include the last one, the line break before it may go with it (deleting a last line from the
    end of the line before). Without `original`: no line contains `word` and every line of `kept` is still there,
    exactly."""
    word = str(word)
    if original is not None:
        before = set_up_text(original, codepage, f"{name} without its lines containing {word!r}")
        if isinstance(before, Verdict):
            return before
        parts = pieces(before.text)
        gone = [word.casefold() in p.casefold() for p in parts]
        if not any(gone):
            return Verdict.check(False, f"{name} without its lines containing {word!r}",
                                 f"no line with {word!r} at set-up (a broken set-up)")
        want = "".join(p for p, g in zip(parts, gone) if not g)
        what = f"{name}: its set-up text without the {sum(gone)} line(s) containing {word!r}, nothing else changed"
        verdict = compare_text(data, want, before.encoding, what, codepage)
        bare = re.sub(r"(\r\n|\n|\r)$", "", want)
        if not verdict.passed and gone[-1] and bare != want and bare:
            other = compare_text(data, bare, before.encoding, what, codepage)
            if other.passed:
                return other
        return verdict
    what = f"{name} without lines containing {word!r}, the {len(kept)} other lines kept (no set-up copy to " \
           "compare with)"
    try:
        found = decode_text(data, codepage)
    except ValueError as exc:
        return Verdict.check(False, what, f"not a text file: {exc}")
    got = split_lines(found.text)
    bad = [line for line in got if word.casefold() in line.casefold()]
    lost = [k for k in kept if k not in got]
    return Verdict.check(not bad and not lost, what, (f"{len(bad)} line(s) with it, e.g. {_short(bad[0])}" if bad
                                                      else "none with it") + (f"; lost {lost!r}" if lost else ""))


@evaluator("file_lines_without")
def file_lines_without(state: FinalState, path: str, word: str, kept: list[str],
                       platform: str | None = None) -> Verdict:
    """Every line of `path` containing `word` (any case) deleted, nothing else changed: its set-up text (listed
    under `baseline`) without those lines, byte for byte in its encoding with its line breaks (`check_lines_deleted`;
    Notepad, Mousepad and Markor keep them). Without a baseline (a file an upstream subtask made): no line contains
    `word` and every line of `kept` is still there, exactly."""
    data = state.pull(path, platform)
    if data is None:
        return Verdict.check(False, f"{path} without its lines containing {str(word)!r}", "no file")
    return check_lines_deleted(data, str(word), [str(k) for k in kept], state.baseline(path, platform),
                               codepage(state, platform), path)


# -- text written in a given encoding or with given lines -------------------------------------------------------------
@evaluator("file_text_encoded")
def file_text_encoded(state: FinalState, path: str, source: str, encoding: str, bom: str = "any",
                      platform: str | None = None) -> Verdict:
    """`path` holds exactly the text of `source` (as it was at set-up: listed under `baseline`; else as it is
    now) stored in `encoding` (a name of ENCODINGS: ANSI — the platform's code page, where it has one —, UTF-8,
    UTF-16 LE, UTF-16 BE), with the source's line breaks, and `source` itself is unchanged. `bom` for UTF-8:
    "any" (with or without a byte order mark: Windows 10's Notepad writes none for "UTF-8" and one for "UTF-8
    with BOM", Wine's always one), "yes" or "no". UTF-16 is always with its byte order mark (without one no
    editor can tell it from 8-bit text)."""
    enc = lookup_encoding(encoding)
    base = state.baseline(source, platform)
    src = base if base is not None else state.pull(source, platform)
    what = f"{path}: the text of {source} in {enc.name}"
    if src is None:
        return Verdict.check(False, what, f"no {source}")
    try:
        text = decode_text(src, codepage(state, platform)).text
    except ValueError as exc:
        return Verdict.check(False, what, f"{source} is no text ({exc})")
    data = state.pull(path, platform)
    if data is None:
        return Verdict.check(False, what, "no file")
    names = [enc.name]
    if enc.name in ("UTF-8", "UTF-8 with BOM"):
        names = {"any": ["UTF-8 with BOM", "UTF-8"], "yes": ["UTF-8 with BOM"], "no": ["UTF-8"]}[bom]
        if not any(ord(c) > 127 for c in text) and "UTF-8" in names:
            names.append("ASCII")
    verdicts = [compare_text(data, text, name, what, codepage(state, platform)) for name in names]
    verdict = next((v for v in verdicts if v.passed), verdicts[0])
    if not verdict.passed:
        if len(names) > 1:
            return Verdict(False, verdict.reason.replace(f"stored as {names[0]}",
                                                         f"stored as {' or '.join(names[:2])}", 1))
        return verdict
    lost = changed_since_setup(state, [source], platform) if base is not None else []
    return Verdict.check(not lost, what + f" and {source} kept unchanged", "; ".join(lost) or verdict.reason
                         .partition("found ")[2])


@evaluator("file_text_lines")
def file_text_lines(state: FinalState, path: str, lines: list[str], newline: str,
                    encodings: list[str] | None = None, platform: str | None = None) -> Verdict:
    """`path` is a text file of exactly `lines` (no other line, none changed; a final line break or none), every
    line break `newline` (CRLF, LF or CR: what the platform's editor writes), stored in one of `encodings` (names
    of ENCODINGS; default: any of them — ANSI where the platform has a code page, UTF-8 with or without BOM, UTF-16
    LE or BE with its BOM)."""
    sep = BREAKS[newline.upper()]
    lines = [str(x) for x in lines]
    allowed = [lookup_encoding(e).name for e in encodings] if encodings else list(ENCODINGS)
    body = sep.join(lines)
    what = f"{path} with the {len(lines)} lines {_short(' / '.join(lines), 120)}"
    data = state.pull(path, platform)
    if data is None:
        return Verdict.check(False, what, "no file")
    try:
        found = decode_text(data, codepage(state, platform))
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


# -- answers written into text files: a listing, a number ---------------------------------------------------------------
def listed_names(text: str) -> list[str]:
    """The non-blank lines of a listing, trimmed."""
    return [line.strip() for line in re.split(r"\r\n|\n|\r", text) if line.strip()]


def check_listing(plat: PlatformSpec, text: str, names: list[str], folder: str) -> Verdict:
    """The lines of `text` are exactly the file names `names` (any order, each once), compared as the platform
    compares names (without case on Windows)."""
    key = str.casefold if plat.case_insensitive_paths else str
    want = f"the {len(names)} file names of {folder}, one per line, names only"
    lines = listed_names(text)
    got = [key(line) for line in lines]
    expected = [key(n) for n in names]
    missing = [n for n in names if key(n) not in got]
    extra = [line for line in lines if key(line) not in expected]
    doubled = sorted({line for line in got if got.count(line) > 1})
    problems = ([f"missing {missing}"] if missing else []) + ([f"other lines {[x[:60] for x in extra[:5]]}"]
                                                              if extra else []) + (
        [f"listed twice {doubled}"] if doubled else [])
    return Verdict.check(not problems, want, "; ".join(problems) or "so")


def read_answer(state: FinalState, path: str, platform: str | None) -> tuple[str | None, str]:
    """The text of the answer file `path` in whatever encoding the platform's programs write it (`decode_text`),
    or (None, why not)."""
    data = state.pull(path, platform)
    if data is None:
        return None, "no file"
    try:
        return decode_text(data, codepage(state, platform)).text, ""
    except ValueError as exc:
        return None, f"not a text file: {exc}"


@evaluator("file_lists_folder")
def file_lists_folder(state: FinalState, path: str, folder: str, names: list[str],
                      platform: str | None = None) -> Verdict:
    """`path` (a text file in any encoding the platform's programs write: `decode_text`) lists exactly the file
    names `names` of `folder`, which the set-up made (the task's own inputs; `folder` a `feedable: false` input),
    one per line in any order; and `folder` itself is as the set-up left it (its snapshot: nothing renamed,
    deleted, added, edited or hidden — listing is reading)."""
    text, why = read_answer(state, path, platform)
    if text is None:
        return Verdict.check(False, f"a listing of {folder} at {path}", why)
    verdict = check_listing(spec(platform or state.platform), text, list(names), folder)
    return with_unchanged(state, verdict, f"the file names of {folder} at {path}", platform, folders=[folder])


@setup_capture("file_lists_folder")
def _listed_folder_at_setup(state: FinalState, folder: str, platform: str | None = None, **_: Any) -> dict:
    return capture_folders(state, [folder], platform)


def check_number(text: str, expected: int) -> Verdict:
    """`text` is the whole number `expected` alone (surrounding white space aside)."""
    got = text.strip()
    ok = got.lstrip("+-").isdigit() and int(got) == expected
    return Verdict.check(ok, f"just the number {expected}", _short(got) if got else "an empty file")


NUMBER_OPS = {"sum": sum, "count": len}


@evaluator("file_number_is")
def file_number_is(state: FinalState, path: str, terms: list[Any], op: str = "sum",
                   unchanged: list[str] | None = None, platform: str | None = None) -> Verdict:
    """`path` holds just the whole number computed on the host from the task's own values `terms` (`op`: "sum"
    — one term is the number itself — or "count"), in any encoding the platform's programs write; and what
    `unchanged` names is as at set-up (`changed_since_setup`): a file (e.g. the input the numbers came from) as its
    baseline, a folder (a `feedable: false` input, e.g. the folder whose files were counted) as its set-up
    snapshot."""
    if op not in NUMBER_OPS:
        raise ConfigError(f"file_number_is: unknown op {op!r}", field="evaluate.args.op",
                          fix=f"use one of {sorted(NUMBER_OPS)}")
    expected = NUMBER_OPS[op]([int(str(t)) for t in terms])
    text, why = read_answer(state, path, platform)
    if text is None:
        return Verdict.check(False, f"{path} holding {expected}", why)
    return with_unchanged(state, check_number(text, expected), f"{path} holding {expected}", platform,
                          unchanged=list(unchanged or []))


@setup_capture("file_number_is")
def _counted_folders_at_setup(state: FinalState, unchanged: list[str] | None = None, platform: str | None = None,
                              **_: Any) -> dict:
    return capture_folders(state, list(unchanged or []), platform)
