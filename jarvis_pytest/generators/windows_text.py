"""Generators of Windows text files: lines in a Windows encoding (ANSI, UTF-8 with or without a byte order mark,
UTF-16 little- or big-endian with its BOM) and line ending (CRLF by default), as Notepad reads and writes them.

`ENCODINGS` names each encoding as Notepad's Save As dialog does and gives its codec and byte order mark; the
plain-text evaluators (`jarvis_pytest/evaluators/text.py`) use the same table.
"""

from __future__ import annotations

from dataclasses import dataclass

from jarvis_pytest.generators.registry import generator


@dataclass(frozen=True)
class Encoding:
    """A Windows text encoding: its name, Python codec and the byte order mark Notepad writes with it."""

    name: str
    codec: str
    bom: bytes = b""


ENCODINGS: dict[str, Encoding] = {e.name: e for e in (
    Encoding("ANSI", "cp1252"),  # Windows-1252: the ANSI code page of an English (US) Windows, and of Wine here
    Encoding("UTF-8", "utf-8"),
    Encoding("UTF-8 with BOM", "utf-8", b"\xef\xbb\xbf"),
    Encoding("UTF-16 LE", "utf-16-le", b"\xff\xfe"),  # Notepad's "Unicode"
    Encoding("UTF-16 BE", "utf-16-be", b"\xfe\xff"),  # Notepad's "Unicode big endian"
)}
ALIASES = {"cp1252": "ANSI", "windows-1252": "ANSI", "utf8": "UTF-8", "utf-8-sig": "UTF-8 with BOM",
           "unicode": "UTF-16 LE", "utf-16": "UTF-16 LE", "utf-16le": "UTF-16 LE", "utf-16be": "UTF-16 BE"}


def encoding(name: str) -> Encoding:
    """The encoding called `name` (a key of ENCODINGS, any case, or an alias such as cp1252 or utf-16)."""
    key = str(name).strip()
    for known in ENCODINGS:
        if key.lower() == known.lower():
            return ENCODINGS[known]
    if key.lower() in ALIASES:
        return ENCODINGS[ALIASES[key.lower()]]
    raise ValueError(f"unknown encoding {name!r} (use one of {', '.join(ENCODINGS)})")


def encode(text: str, name: str) -> bytes:
    """`text` in the encoding `name`, with its byte order mark; a character the encoding cannot hold is an
    error (a generator never writes `?` in its place)."""
    enc = encoding(name)
    try:
        return enc.bom + text.encode(enc.codec)
    except UnicodeEncodeError as exc:
        bad = exc.object[exc.start:exc.end]
        raise ValueError(f"{enc.name} ({enc.codec}) cannot hold {bad!r}") from None


@generator("encoded_text")
def encoded_text(lines: list[str], encoding: str = "ANSI", newline: str = "\r\n", final_newline: bool = True) -> bytes:
    """The `lines` joined by `newline` (CRLF by default), ending with one when `final_newline`, in `encoding`
    (ANSI = Windows-1252, UTF-8, UTF-8 with BOM, UTF-16 LE or UTF-16 BE, the last two with their BOM)."""
    if not isinstance(lines, list) or not all(isinstance(x, (str, int, float)) for x in lines):
        raise TypeError("`lines` must be a list of strings")
    if newline not in ("\r\n", "\n", "\r"):
        raise TypeError(f"`newline` must be CRLF, LF or CR, not {newline!r}")
    text = newline.join(str(x) for x in lines) + (newline if final_newline and lines else "")
    try:
        return encode(text, encoding)
    except ValueError as exc:
        raise TypeError(str(exc)) from None
