"""Generators of presentations: a .pptx (python-pptx) of title-and-content slides, deterministic to the byte."""

from __future__ import annotations

import datetime
import io

from jarvis_pytest.generators.packages import FIXED_DATE, deterministic_package
from jarvis_pytest.generators.registry import generator


@generator("pptx_presentation")
def pptx_presentation(titles: list[str], bullets: list[str] | None = None) -> bytes:
    """A .pptx with one "Title and Content" slide per title; every slide's body lists `bullets` (default: a
    line naming the slide)."""
    from pptx import Presentation

    if not isinstance(titles, list) or not titles:
        raise TypeError("`titles` must be a non-empty list of strings")
    prs = Presentation()
    layout = prs.slide_layouts[1]
    for i, title in enumerate(titles, 1):
        slide = prs.slides.add_slide(layout)
        slide.shapes.title.text = str(title)
        body = slide.placeholders[1].text_frame
        lines = [str(b) for b in bullets] if bullets else [f"Point {i}: {title}"]
        body.text = lines[0]
        for line in lines[1:]:
            body.add_paragraph().text = line
    prs.core_properties.created = prs.core_properties.modified = datetime.datetime.fromisoformat(FIXED_DATE)
    prs.core_properties.author = "jarvis"
    buf = io.BytesIO()
    prs.save(buf)
    return deterministic_package(buf.getvalue())  # python-pptx stamps each member with the current time
