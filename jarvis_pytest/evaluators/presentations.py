"""Checks of presentations (.pptx with python-pptx, .odp with odfpy), read on the host.

`read_presentation` turns either format into a list of slides, each with its title and all its texts (title,
body, and speaker notes), so each check is written once for both formats.
"""

from __future__ import annotations

import io
from dataclasses import dataclass, field

from jarvis_pytest.evaluators.documents import norm, office_kind, pdf_has_text
from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.state import FinalState, judge_file



@dataclass
class Slide:
    title: str
    texts: list[str] = field(default_factory=list)
    notes: str = ""


def presentation_kind(data: bytes) -> str:
    """"pptx" or "odp" by content; ValueError otherwise."""
    kind = office_kind(data)
    if kind not in ("pptx", "odp"):
        raise ValueError(f"not a presentation ({kind or 'no zip package'})")
    return kind


def read_presentation(data: bytes) -> tuple[str, list[Slide]]:
    """(kind, slides) of .pptx or .odp bytes; ValueError when they are neither."""
    kind = presentation_kind(data)
    return kind, (_read_pptx(data) if kind == "pptx" else _read_odp(data))


def _read_pptx(data: bytes) -> list[Slide]:
    from pptx import Presentation

    slides = []
    for s in Presentation(io.BytesIO(data)).slides:
        title = s.shapes.title.text_frame.text if s.shapes.title is not None else ""
        texts = [sh.text_frame.text for sh in s.shapes if sh.has_text_frame and sh.text_frame.text.strip()]
        notes = s.notes_slide.notes_text_frame.text if s.has_notes_slide and s.notes_slide.notes_text_frame else ""
        slides.append(Slide(norm(title), [norm(t) for t in texts], norm(notes)))
    return slides


def _read_odp(data: bytes) -> list[Slide]:
    from odf import teletype
    from odf.draw import Frame, Page
    from odf.namespaces import PRESENTATIONNS
    from odf.opendocument import load

    slides = []
    for page in load(io.BytesIO(data)).presentation.getElementsByType(Page):
        slide = Slide("")
        for frame in page.getElementsByType(Frame):
            role = frame.attributes.get((PRESENTATIONNS, "class"))
            text = norm(" ".join(teletype.extractText(p) for p in _paragraphs(frame)))
            if any(a.qname == (PRESENTATIONNS, "notes") for a in _ancestors(frame)):
                slide.notes = text if role == "notes" else slide.notes
                continue
            if role == "title" and not slide.title:
                slide.title = text
            if text:
                slide.texts.append(text)
        slides.append(slide)
    return slides


def _paragraphs(node):
    """The text paragraphs and headings inside `node`, in order."""
    for child in node.childNodes:
        if getattr(child, "qname", (None, None))[1] in ("p", "h"):
            yield child
        elif child.nodeType == child.ELEMENT_NODE:
            yield from _paragraphs(child)


def _ancestors(node):
    node = node.parentNode
    while node is not None and hasattr(node, "qname"):
        yield node
        node = node.parentNode


def _with_presentation(state: FinalState, path: str, platform: str | None, want: str, check) -> Verdict:
    return judge_file(state, path, want, read_presentation, lambda parsed: check(*parsed), platform)


def check_titles(kind: str, slides: list[Slide], titles: list[str], want_kind: str | None = None) -> Verdict:
    """The slides' titles are exactly `titles`, in order (and the file is of `want_kind`, when given)."""
    if want_kind and kind != want_kind:
        return Verdict.check(False, f"a .{want_kind} presentation", f"a .{kind} file")
    got, want = [s.title for s in slides], [norm(t) for t in titles]
    return Verdict.check(got == want, f"slides titled {want!r}", repr(got))


@evaluator("slide_titles_are")
def slide_titles_are(state: FinalState, path: str, titles: list[str], without: str | None = None,
                     kind: str | None = None, platform: str | None = None) -> Verdict:
    """The presentation's slides have exactly these titles, in this order (leaving out `without`, the title of a
    slide that should be gone)."""
    titles = [t for t in titles if without is None or norm(t) != norm(without)]
    return _with_presentation(state, path, platform, f"slides titled {titles!r}",
                              lambda k, slides: check_titles(k, slides, titles, kind))


def check_slide_title(kind: str, slides: list[Slide], number: int, title: str, count: int | None,
                      want_kind: str | None = None) -> Verdict:
    """Slide `number` (1-based) is titled `title`, and there are `count` slides (when given)."""
    if want_kind and kind != want_kind:
        return Verdict.check(False, f"a .{want_kind} presentation", f"a .{kind} file")
    if count is not None and len(slides) != int(count):
        return Verdict.check(False, f"{count} slides", f"{len(slides)} slides")
    got = slides[int(number) - 1].title if 1 <= int(number) <= len(slides) else None
    return Verdict.check(got == norm(title), f"slide {number} titled {title!r}", repr(got))


@evaluator("slide_title_is")
def slide_title_is(state: FinalState, path: str, number: int, title: str, count: int | None = None,
                   kind: str | None = None, platform: str | None = None) -> Verdict:
    return _with_presentation(state, path, platform, f"slide {number} titled {title!r}",
                              lambda k, slides: check_slide_title(k, slides, int(number), title, count, kind))


def check_notes(slides: list[Slide], number: int, text: str) -> Verdict:
    """Slide `number` (1-based) has speaker notes containing `text`."""
    if not 1 <= int(number) <= len(slides):
        return Verdict.check(False, f"notes on slide {number}", f"{len(slides)} slides")
    notes = slides[int(number) - 1].notes
    return Verdict.check(norm(text) in notes, f"slide {number}'s notes containing {text!r}",
                         repr(notes) if notes else "no notes")


@evaluator("slide_notes_contain")
def slide_notes_contain(state: FinalState, path: str, number: int, text: str, platform: str | None = None) -> Verdict:
    return _with_presentation(state, path, platform, f"notes on slide {number}",
                              lambda k, slides: check_notes(slides, int(number), text))


@evaluator("pdf_matches_presentation")
def pdf_matches_presentation(state: FinalState, path: str, presentation: str, platform: str | None = None) -> Verdict:
    """`path` is a PDF with one page per slide of `presentation` (.pptx/.odp) showing every slide's title."""
    def check(slides: list[Slide]) -> Verdict:
        return pdf_has_text(state, path, [s.title for s in slides if s.title], len(slides), platform)
    return judge_file(state, presentation, f"the slides of {presentation}",
                      lambda data: read_presentation(data)[1], check, platform)
