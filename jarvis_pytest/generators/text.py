"""Generators of plain-text files (notes, CSV rows) from slot values."""

from __future__ import annotations

from jarvis_pytest.generators.registry import generator


@generator("text_lines")
def text_lines(lines: list[str], newline: str = "\n", final_newline: bool = True) -> bytes:
    """The `lines` joined by `newline` (UTF-8), ending with one when `final_newline`."""
    if not isinstance(lines, list) or not all(isinstance(x, (str, int, float)) for x in lines):
        raise TypeError("`lines` must be a list of strings")
    text = newline.join(str(x) for x in lines) + (newline if final_newline and lines else "")
    return text.encode("utf-8")
