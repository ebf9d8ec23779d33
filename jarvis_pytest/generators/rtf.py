"""Generators of Rich Text Format (RTF 1.x) documents, the format WordPad saves by default: paragraphs of plain
text with a font, a size and bold per paragraph, deterministic from the arguments.

The output is what a word processor writes for such a document (a font table, then one `\\pard ... \\par` per
paragraph); characters outside ASCII are written as `\\'hh` (Windows-1252) or `\\uN?` escapes, so the file is
7-bit as the specification asks. WordPad (Wine's and Windows') and LibreOffice open it.
"""

from __future__ import annotations

from jarvis_pytest.generators.registry import generator


def escape(text: str) -> str:
    """`text` as RTF body text: `\\`, `{` and `}` escaped, a tab as `\\tab`, characters outside ASCII as `\\'hh`
    (Windows-1252) or `\\uN?` (UTF-16 code units, `N` signed as RTF wants, `?` the fallback for old readers)."""
    out = []
    for ch in text:
        if ch in "\\{}":
            out.append("\\" + ch)
        elif ch == "\t":
            out.append("\\tab ")
        elif " " <= ch <= "~":
            out.append(ch)
        elif ch in "\r\n":
            raise TypeError("a paragraph cannot contain a line break (give each line as its own paragraph)")
        else:
            try:
                out.append("\\'%02x" % ch.encode("cp1252")[0])
            except UnicodeEncodeError:
                units = ch.encode("utf-16-le")
                for i in range(0, len(units), 2):
                    n = int.from_bytes(units[i:i + 2], "little")
                    out.append(f"\\u{n - 65536 if n > 32767 else n}?")
    return "".join(out)


def _half_points(size: float | int | str) -> int:
    value = float(size)
    if not 1 <= value <= 1638 or value * 2 != int(value * 2):
        raise TypeError(f"font size {size!r} must be a whole or half point size from 1 to 1638")
    return int(value * 2)


@generator("rtf_document")
def rtf_document(paragraphs: list[str], bold: list[int] | None = None, sizes: list[float] | None = None,
                 font: str = "Arial", size: float = 12) -> bytes:
    """An RTF document of `paragraphs` in the font `font`: paragraph i is `sizes[i]` points (default `size`) and
    bold when i is in `bold` (indices from 0)."""
    if not isinstance(paragraphs, list) or not all(isinstance(p, (str, int, float)) for p in paragraphs):
        raise TypeError("`paragraphs` must be a list of strings")
    bold = [int(i) for i in bold or []]
    sizes = list(sizes) if sizes is not None else [size] * len(paragraphs)
    if len(sizes) != len(paragraphs):
        raise TypeError(f"`sizes` has {len(sizes)} entries for {len(paragraphs)} paragraphs")
    if any(not 0 <= i < len(paragraphs) for i in bold):
        raise TypeError(f"`bold` {bold} names a paragraph that does not exist")
    if any(c in str(font) for c in "\\{};"):
        raise TypeError(f"font name {font!r} cannot contain \\, braces or ;")
    lines = ["{\\rtf1\\ansi\\ansicpg1252\\deff0\\deflang1033",
             "{\\fonttbl{\\f0\\fswiss\\fcharset0 %s;}}" % font,
             "{\\*\\generator jarvis-pytest;}\\viewkind4\\uc1"]
    for i, (text, pt) in enumerate(zip(paragraphs, sizes)):
        on, off = ("\\b ", "\\b0") if i in bold else ("", "")
        lines.append(f"\\pard\\plain\\f0\\fs{_half_points(pt)} {on}{escape(str(text))}{off}\\par")
    lines.append("}")
    return ("\r\n".join(lines) + "\r\n").encode("ascii")
