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


def _baseline_slides(state: FinalState, path: str, platform: str | None) -> list[Slide] | None:
    """The slides of `path` as it was right after set-up (the template lists it under `baseline`), or None when
    that is not known (e.g. an upstream subtask of a composed task made the deck)."""
    data = state.baseline(path, platform)
    if data is None:
        return None
    try:
        return read_presentation(data)[1]
    except Exception:
        return None


def _kind_is(kind: str, want: str | None) -> Verdict | None:
    """A failed verdict when the deck's real format `kind` is not `want` ("pptx" or ".pptx")."""
    want = str(want or "").lstrip(".").lower()
    if want and kind != want:
        return Verdict.check(False, f"a .{want} presentation", f"a .{kind} file")
    return None


def body(slide: Slide) -> list[str]:
    """The slide's texts other than its title."""
    texts = list(slide.texts)
    if slide.title in texts:
        texts.remove(slide.title)
    return texts


def slide_diff(slide: Slide, original: Slide, title: bool = True, notes: bool = True) -> str | None:
    """How `slide` differs from `original` (its title when `title`, its other texts, its notes when `notes`), or
    None when it does not."""
    if title and slide.title != original.title:
        return f"title {slide.title!r} instead of {original.title!r}"
    if body(slide) != body(original):
        return f"text {body(slide)!r} instead of {body(original)!r}"
    if notes and slide.notes != original.notes:
        return f"notes {slide.notes!r} instead of {original.notes!r}"
    return None


def check_slides_kept(slides: list[Slide], original: list[Slide], skip: tuple[int, ...] = (),
                      notes_skip: tuple[int, ...] = (), title_skip: tuple[int, ...] = ()) -> Verdict:
    """Slide for slide (same count), `slides` are the `original` ones: titles, texts and notes — except the slides
    (0-based) in `skip` (not compared), the notes of `notes_skip` and the titles of `title_skip`."""
    want = "the other slides unchanged"
    if len(slides) != len(original):
        return Verdict.check(False, want, f"{len(slides)} slides instead of {len(original)}")
    for i, (s, o) in enumerate(zip(slides, original)):
        if i in skip:
            continue
        diff = slide_diff(s, o, title=i not in title_skip, notes=i not in notes_skip)
        if diff:
            return Verdict.check(False, want, f"slide {i + 1} changed: {diff}")
    return Verdict.check(True, want, "them")


def check_titles(kind: str, slides: list[Slide], titles: list[str], want_kind: str | None = None,
                 original: list[Slide] | None = None) -> Verdict:
    """The slides' titles are exactly `titles`, in order (and the file is of `want_kind`, when given). With the
    `original` slides, each slide titled as an original one keeps that slide's texts and notes."""
    wrong = _kind_is(kind, want_kind)
    if wrong:
        return wrong
    got, want = [s.title for s in slides], [norm(t) for t in titles]
    verdict = Verdict.check(got == want, f"slides titled {want!r}", repr(got))
    if not verdict.passed or original is None:
        return verdict
    by_title = {o.title: o for o in original}
    for s in slides:
        o = by_title.get(s.title)
        diff = slide_diff(s, o) if o is not None else None
        if diff:
            return Verdict.check(False, "the other slides unchanged", f"slide {s.title!r} changed: {diff}")
    return verdict


@evaluator("slide_titles_are")
def slide_titles_are(state: FinalState, path: str, titles: list[str], without: str | None = None,
                     kind: str | None = None, platform: str | None = None) -> Verdict:
    """The presentation's slides have exactly these titles, in this order (leaving out `without`, the title of a
    slide that should be gone). With a baseline of `path`, every slide titled as one of the original slides must
    keep that slide's texts and notes (a new slide is free); without one only the titles are checked."""
    titles = [t for t in titles if without is None or norm(t) != norm(without)]
    original = _baseline_slides(state, path, platform)
    return _with_presentation(state, path, platform, f"slides titled {titles!r}",
                              lambda k, slides: check_titles(k, slides, titles, kind, original))


def check_slide_title(kind: str, slides: list[Slide], number: int, title: str, count: int | None,
                      want_kind: str | None = None, original: list[Slide] | None = None) -> Verdict:
    """Slide `number` (1-based) is titled `title`, and there are `count` slides (when given). With the
    `original` slides, everything else (the other slides, this slide's other texts and notes) is unchanged."""
    wrong = _kind_is(kind, want_kind)
    if wrong:
        return wrong
    if count is not None and len(slides) != int(count):
        return Verdict.check(False, f"{count} slides", f"{len(slides)} slides")
    got = slides[int(number) - 1].title if 1 <= int(number) <= len(slides) else None
    verdict = Verdict.check(got == norm(title), f"slide {number} titled {title!r}", repr(got))
    if not verdict.passed or original is None:
        return verdict
    kept = check_slides_kept(slides, original, title_skip=(int(number) - 1,))
    return verdict if kept.passed else kept


@evaluator("slide_title_is")
def slide_title_is(state: FinalState, path: str, number: int, title: str, count: int | None = None,
                   kind: str | None = None, platform: str | None = None) -> Verdict:
    """Slide `number` is titled `title` (in a deck of `count` slides and of `kind`, when given). With a
    baseline of `path` nothing else may change (other slides, this slide's body and notes)."""
    original = _baseline_slides(state, path, platform)
    return _with_presentation(state, path, platform, f"slide {number} titled {title!r}",
                              lambda k, slides: check_slide_title(k, slides, int(number), title, count, kind,
                                                                  original))


def check_notes(slides: list[Slide], number: int, text: str, original: list[Slide] | None = None) -> Verdict:
    """Slide `number` (1-based) has speaker notes containing `text`. With the `original` slides, every slide
    keeps its title and texts and every other slide its notes."""
    if not 1 <= int(number) <= len(slides):
        return Verdict.check(False, f"notes on slide {number}", f"{len(slides)} slides")
    notes = slides[int(number) - 1].notes
    verdict = Verdict.check(norm(text) in notes, f"slide {number}'s notes containing {text!r}",
                            repr(notes) if notes else "no notes")
    if not verdict.passed or original is None:
        return verdict
    kept = check_slides_kept(slides, original, notes_skip=(int(number) - 1,))
    return verdict if kept.passed else kept


@evaluator("slide_notes_contain")
def slide_notes_contain(state: FinalState, path: str, number: int, text: str, kind: str | None = None,
                        platform: str | None = None) -> Verdict:
    """Slide `number`'s speaker notes contain `text` (in a deck of `kind`, when given). With a baseline of
    `path`, the slides' titles and texts and the other slides' notes are unchanged."""
    original = _baseline_slides(state, path, platform)
    return _with_presentation(state, path, platform, f"notes on slide {number}",
                              lambda k, slides: _kind_is(k, kind) or check_notes(slides, int(number), text, original))


@evaluator("pdf_matches_presentation")
def pdf_matches_presentation(state: FinalState, path: str, presentation: str, platform: str | None = None) -> Verdict:
    """`path` is a PDF with one page per slide of `presentation` (.pptx/.odp) showing every slide's texts (title
    and body). With a baseline of `presentation` the slides are those it was set up with, and the deck must be
    left unchanged; without one (a deck an upstream subtask made) they are the deck's as found."""
    def pdf_of(slides: list[Slide]) -> Verdict:
        return pdf_has_text(state, path, [t for s in slides for t in s.texts], len(slides), platform)

    original = _baseline_slides(state, presentation, platform)
    if original is None:
        return judge_file(state, presentation, f"the slides of {presentation}",
                          lambda data: read_presentation(data)[1], pdf_of, platform)
    verdict = pdf_of(original)
    if not verdict.passed:
        return verdict
    kept = _with_presentation(state, presentation, platform, f"the original {presentation} unchanged",
                              lambda k, slides: check_slides_kept(slides, original))
    return verdict if kept.passed else kept
