"""Text read off a device's screen image (OCR), for GUI targets the accessibility tree does not show.

Some of what a person reads on the screen is in no accessibility tree: a title drawn by the window manager, the
file dialog GTK shows for Chromium (which loads no GTK accessibility bridge), a list Wine draws itself. A GUI step
can name such text as its target's `screen_text` (`tasks.model.GuiTarget`); the GUI oracle then reads the words of
the screenshot with Tesseract (`tesseract` on the host: `make host-packages` installs it) and looks for the text
in runs of words on one line (`runs`), matched as any target's text is (`gui_oracle.text_matches`).
"""

from __future__ import annotations

import shutil
import subprocess
from dataclasses import dataclass
from typing import Iterator, Sequence

from jarvis_pytest.errors import ConfigError

OCR_TIMEOUT = 30.0  # seconds one screenshot's OCR may take (about 1.6 s for 1920x1080 on 2 cores)
MIN_CONFIDENCE = 30.0  # words Tesseract is less sure of are left out (its confidence, 0-100)


@dataclass(frozen=True)
class Word:
    """One word on the screen: its text, its box [x, y, w, h] in screen pixels, and the line it is on."""

    text: str
    box: tuple[int, int, int, int]
    line: tuple[int, int, int]  # Tesseract's block, paragraph and line numbers


def read_words(png: bytes) -> list[Word]:
    """The words of a PNG screenshot, in reading order. ConfigError where Tesseract is not installed."""
    exe = shutil.which("tesseract")
    if exe is None:
        raise ConfigError("a GUI step names text on the screen (`screen_text`), which is read with Tesseract, and "
                          "tesseract is not installed", field="screen_text",
                          fix="install it (Debian: apt-get install tesseract-ocr), or run `make host-packages`")
    proc = subprocess.run([exe, "stdin", "stdout", "tsv"], input=png, capture_output=True, timeout=OCR_TIMEOUT)
    if proc.returncode != 0:
        raise RuntimeError(f"tesseract failed ({proc.returncode}): {proc.stderr.decode(errors='replace')[-300:]}")
    words = []
    for row in proc.stdout.decode("utf-8", errors="replace").splitlines()[1:]:
        cells = row.split("\t")
        if len(cells) != 12 or cells[0] != "5" or not cells[11].strip():
            continue
        try:
            confidence = float(cells[10])
            numbers = [int(c) for c in cells[1:10]]
        except ValueError:
            continue
        if confidence < MIN_CONFIDENCE:
            continue
        _, block, par, line, _, left, top, width, height = numbers
        words.append(Word(cells[11].strip(), (left, top, width, height), (block, par, line)))
    return words


def runs(words: Sequence[Word]) -> Iterator[tuple[str, list[int]]]:
    """Every run of consecutive words on one line: its text (the words joined by spaces) and the box around it,
    in reading order, the shorter runs of a start first."""
    lines: dict[tuple[int, int, int], list[Word]] = {}
    for word in words:
        lines.setdefault(word.line, []).append(word)
    for line in lines.values():
        for i in range(len(line)):
            for j in range(i, len(line)):
                part = line[i:j + 1]
                left = min(w.box[0] for w in part)
                top = min(w.box[1] for w in part)
                right = max(w.box[0] + w.box[2] for w in part)
                bottom = max(w.box[1] + w.box[3] for w in part)
                yield " ".join(w.text for w in part), [left, top, right - left, bottom - top]
