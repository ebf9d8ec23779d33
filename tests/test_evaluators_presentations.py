"""The presentation checks (evaluators/presentations.py) and generator (generators/presentations.py), without
containers: each check passes on a presentation as a solved Impress task leaves it and fails, naming what it
expected and found, on the presentation as set up. .pptx files come from the generator and python-pptx; .odp
files are built with odfpy in the shape LibreOffice Impress writes them (title/outline frames with
presentation:class, speaker notes in a presentation:notes page holding a thumbnail and a notes frame)."""

from __future__ import annotations

import io

import pytest
from pptx import Presentation

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.evaluators import get_evaluator
from jarvis_pytest.evaluators.presentations import (check_notes, check_slide_title, check_titles,
                                                    presentation_kind, read_presentation)
from file_state import state_with
from jarvis_pytest.generators import generate

TITLES = ["Safety week overview", "Timeline", "Budget", "Risks", "Next steps"]


# --- files -------------------------------------------------------------------------------------------------------

def pptx_deck(titles=TITLES, edit=None) -> bytes:
    data = generate("pptx_presentation", {"titles": list(titles)})
    if edit is None:
        return data
    prs = Presentation(io.BytesIO(data))
    edit(prs)
    buf = io.BytesIO()
    prs.save(buf)
    return buf.getvalue()


def odp_deck(titles=TITLES, notes: dict[int, str] | None = None, bodies: dict[int, str] | None = None) -> bytes:
    """An .odp shaped like Impress's own: per slide a title frame, an outline frame with a bulleted list
    ("Point i: title" unless `bodies` has another text, "" for none, for that 1-based slide number), and a notes
    page (thumbnail + notes frame, empty unless `notes` has text for that 1-based slide number)."""
    from odf.draw import Frame, Page, PageThumbnail, TextBox
    from odf.namespaces import PRESENTATIONNS
    from odf.opendocument import OpenDocumentPresentation
    from odf.presentation import Notes
    from odf.style import MasterPage, PageLayout
    from odf.text import List, ListItem, P, Span

    doc = OpenDocumentPresentation()
    layout = PageLayout(name="PM1")
    doc.automaticstyles.addElement(layout)
    master = MasterPage(name="Default", pagelayoutname=layout)
    doc.masterstyles.addElement(master)

    def frame(role: str, *children) -> Frame:
        f = Frame(width="25cm", height="3cm", x="1cm", y="1cm")
        f.setAttrNS(PRESENTATIONNS, "class", role)
        box = TextBox()
        for child in children:
            box.addElement(child)
        f.addElement(box)
        return f

    for i, title in enumerate(titles, 1):
        page = Page(name=f"page{i}", masterpagename=master)
        head = P()
        head.addElement(Span(text=title))
        page.addElement(frame("title", head))
        item = ListItem()
        line = (bodies or {}).get(i, f"Point {i}: {title}")
        item.addElement(P(text=line) if line else P())
        bullets = List()
        bullets.addElement(item)
        page.addElement(frame("outline", bullets))
        notes_page = Notes()
        notes_page.addElement(PageThumbnail(pagenumber=i))
        text = (notes or {}).get(i)
        notes_page.addElement(frame("notes", *([P(text=text)] if text else [])))
        page.addElement(notes_page)
        doc.presentation.addElement(page)
    buf = io.BytesIO()
    doc.save(buf)
    return buf.getvalue()



def minimal_pdf(pages: list[str]) -> bytes:
    """A valid PDF with one page per text (Helvetica, one line each), built by hand with a correct xref."""
    n = len(pages)
    objs = ["<< /Type /Catalog /Pages 2 0 R >>",
            "<< /Type /Pages /Kids [%s] /Count %d >>" % (" ".join(f"{4 + 2 * i} 0 R" for i in range(n)), n),
            "<< /Type /Font /Subtype /Type1 /BaseFont /Helvetica >>"]
    for i, text in enumerate(pages):
        stream = f"BT /F1 24 Tf 72 700 Td ({text}) Tj ET"
        objs.append(f"<< /Type /Page /Parent 2 0 R /MediaBox [0 0 792 612] /Contents {5 + 2 * i} 0 R "
                    "/Resources << /Font << /F1 3 0 R >> >> >>")
        objs.append(f"<< /Length {len(stream)} >>\nstream\n{stream}\nendstream")
    out, offsets = b"%PDF-1.4\n", []
    for num, body in enumerate(objs, 1):
        offsets.append(len(out))
        out += f"{num} 0 obj\n{body}\nendobj\n".encode()
    xref = len(out)
    out += f"xref\n0 {len(objs) + 1}\n0000000000 65535 f \n".encode()
    out += "".join(f"{o:010d} 00000 n \n" for o in offsets).encode()
    out += f"trailer\n<< /Size {len(objs) + 1} /Root 1 0 R >>\nstartxref\n{xref}\n%%EOF\n".encode()
    return out


# --- generator ---------------------------------------------------------------------------------------------------

def test_generator_is_deterministic_and_titled():
    a, b = pptx_deck(), pptx_deck()
    assert a == b
    kind, slides = read_presentation(a)
    assert kind == "pptx" and [s.title for s in slides] == TITLES
    assert slides[1].texts == ["Timeline", "Point 2: Timeline"] and all(not s.notes for s in slides)
    bullets = read_presentation(generate("pptx_presentation", {"titles": ["A"], "bullets": ["x", "y"]}))[1]
    assert bullets[0].texts == ["A", "x y"]  # paragraphs joined, whitespace normalised
    with pytest.raises(ConfigError, match="non-empty list"):
        generate("pptx_presentation", {"titles": []})


def test_kind_is_told_by_content():
    assert presentation_kind(pptx_deck()) == "pptx" and presentation_kind(odp_deck()) == "odp"
    for bad in (b"%PDF-1.4 not a deck", generate("docx_document", {"paragraphs": ["x"]})):
        with pytest.raises(ValueError):
            read_presentation(bad)


def test_odp_reads_like_pptx():
    kind, slides = read_presentation(odp_deck(notes={3: "Mention the pilot results"}))
    assert kind == "odp" and [s.title for s in slides] == TITLES
    assert slides[0].texts == ["Safety week overview", "Point 1: Safety week overview"]
    assert slides[2].notes == "Mention the pilot results" and not slides[0].notes
    assert "Mention the pilot results" not in slides[2].texts  # notes are not slide text


# --- checks ------------------------------------------------------------------------------------------------------

def test_change_title():
    kind, before = read_presentation(pptx_deck())
    verdict = check_slide_title(kind, before, 3, "Roadmap", 5, "pptx")
    assert not verdict.passed and "'Roadmap'" in verdict.reason and "'Budget'" in verdict.reason

    def retitle(prs):
        prs.slides[2].shapes.title.text = "Roadmap"
    kind, after = read_presentation(pptx_deck(edit=retitle))
    assert check_slide_title(kind, after, 3, "Roadmap", 5, "pptx").passed
    assert not check_slide_title(kind, after, 2, "Roadmap", 5, "pptx").passed
    assert not check_slide_title(kind, after[:4], 3, "Roadmap", 5, "pptx").passed  # a slide lost
    wrong_kind = check_slide_title("odp", after, 3, "Roadmap", 5, "pptx")
    assert not wrong_kind.passed and "a .pptx presentation" in wrong_kind.reason and ".odp" in wrong_kind.reason
    assert not check_slide_title(kind, after, 9, "Roadmap", None).passed  # no such slide: no crash


def test_add_slide_in_odp():
    want = TITLES + ["Thank you"]
    kind, before = read_presentation(odp_deck())
    verdict = check_titles(kind, before, want, "odp")
    assert not verdict.passed and "Thank you" in verdict.reason and "Next steps" in verdict.reason
    kind, after = read_presentation(odp_deck(want))
    assert check_titles(kind, after, want, "odp").passed
    assert not check_titles(kind, after, want, "pptx").passed
    kind, inserted = read_presentation(odp_deck(TITLES[:2] + ["Thank you"] + TITLES[2:]))
    assert not check_titles(kind, inserted, want, "odp").passed  # added, but not at the end


def test_speaker_notes():
    _, before = read_presentation(pptx_deck())
    verdict = check_notes(before, 5, "Keep this under two minutes")
    assert not verdict.passed and "no notes" in verdict.reason and "Keep this" in verdict.reason

    def annotate(prs):
        prs.slides[4].notes_slide.notes_text_frame.text = "Keep this  under\ntwo minutes."
    _, after = read_presentation(pptx_deck(edit=annotate))
    assert check_notes(after, 5, "Keep this under two minutes").passed  # whitespace normalised
    assert not check_notes(after, 4, "Keep this under two minutes").passed  # wrong slide
    assert not check_notes(after, 6, "x").passed
    _, odp = read_presentation(odp_deck(notes={5: "Keep this under two minutes"}))
    assert check_notes(odp, 5, "Keep this under two minutes").passed


# --- evaluators (a device holding given files) ----------------------------------------------------------------------

def test_slide_titles_are_without_a_deleted_slide():
    evaluate = get_evaluator("slide_titles_are")
    path = "/home/user/Documents/retro.pptx"

    def delete_budget(prs):
        ids = prs.slides._sldIdLst
        ids.remove(list(ids)[2])
    before, after = pptx_deck(), pptx_deck(edit=delete_budget)
    args = {"path": path, "titles": TITLES, "without": "Budget", "kind": "pptx"}
    verdict = evaluate(state_with({path: before}), **args)
    assert not verdict.passed and "'Budget'" in verdict.reason
    assert evaluate(state_with({path: after}), **args).passed
    missing = evaluate(state_with({}), **args)
    assert not missing.passed and f"no file at {path}" in missing.reason
    corrupt = evaluate(state_with({path: b"PK not really"}), **args)
    assert not corrupt.passed and "unreadable" in corrupt.reason


def test_slide_title_is_and_notes_evaluators():
    path = "/home/user/Desktop/pitch.pptx"

    def edit(prs):
        prs.slides[1].shapes.title.text = "Key dates"
        prs.slides[0].notes_slide.notes_text_frame.text = "Pause here for questions"
    before, after = pptx_deck(), pptx_deck(edit=edit)
    title = {"path": path, "number": "2", "title": "Key dates", "count": 5, "kind": "pptx"}  # slots are text
    notes = {"path": path, "number": "1", "text": "Pause here for questions"}
    for name, args in (("slide_title_is", title), ("slide_notes_contain", notes)):
        assert not get_evaluator(name)(state_with({path: before}), **args).passed
        assert get_evaluator(name)(state_with({path: after}), **args).passed


def test_pdf_matches_presentation():
    evaluate = get_evaluator("pdf_matches_presentation")
    deck, pdf = "/home/user/Downloads/slides.pptx", "/home/user/Downloads/slides.pdf"
    good = minimal_pdf([f"{t} Point {i}: {t}" for i, t in enumerate(TITLES, 1)])
    assert evaluate(state_with({deck: pptx_deck(), pdf: good}), path=pdf, presentation=deck).passed
    assert evaluate(state_with({deck: odp_deck(), pdf: good}), path=pdf, presentation=deck).passed
    short = evaluate(state_with({deck: pptx_deck(), pdf: minimal_pdf([f"{t} Point {i}: {t}" for i, t in
                                                                      enumerate(TITLES[:4], 1)])}),
                     path=pdf, presentation=deck)
    assert not short.passed and "4 page(s)" in short.reason and "Next steps" in short.reason
    fake = evaluate(state_with({deck: pptx_deck(), pdf: pptx_deck()}), path=pdf, presentation=deck)
    assert not fake.passed and "no PDF" in fake.reason
    absent = evaluate(state_with({deck: pptx_deck()}), path=pdf, presentation=deck)
    assert not absent.passed and f"no file at {pdf}" in absent.reason


# --- near misses: the slides not asked about stay as set up (the baseline) ------------------------------------------

def with_baseline(files: dict[str, bytes], baselines: dict[str, bytes]):
    """A device holding `files`, whose `baselines` (the files right after set-up) the template listed."""
    return state_with(files, baselines=baselines)


def test_add_slide_keeps_the_other_slides():
    path = "/home/user/Documents/lecture.odp"
    want = TITLES + ["Thank you"]
    run = get_evaluator("slide_titles_are")
    args = {"path": path, "titles": want, "kind": "odp"}
    fresh = odp_deck()
    assert run(with_baseline({path: odp_deck(want, bodies={6: ""})}, {path: fresh}), **args).passed
    emptied = odp_deck(want, bodies={i: "" for i in range(1, 7)})
    assert run(state_with({path: emptied}), **args).passed  # how it passed before: titles only
    verdict = run(with_baseline({path: emptied}, {path: fresh}), **args)
    assert not verdict.passed and verdict.reason == ("expected the other slides unchanged, found slide "
                                                     "'Safety week overview' changed: text [] instead of "
                                                     "['Point 1: Safety week overview']")
    noted = odp_deck(want, notes={2: "psst"})
    verdict = run(with_baseline({path: noted}, {path: fresh}), **args)
    assert not verdict.passed and "slide 'Timeline' changed: notes 'psst' instead of ''" in verdict.reason


def test_change_title_keeps_everything_else():
    path = "/home/user/Documents/review.pptx"
    run = get_evaluator("slide_title_is")
    args = {"path": path, "number": "3", "title": "Roadmap", "count": 5, "kind": "pptx"}
    fresh = pptx_deck()

    def retitle(*more):
        def edit(prs):
            prs.slides[2].shapes.title.text = "Roadmap"
            for fn in more:
                fn(prs)
        return pptx_deck(edit=edit)
    assert run(with_baseline({path: retitle()}, {path: fresh}), **args).passed
    agenda = retitle(lambda prs: setattr(prs.slides[0].shapes.title, "text", "Agenda"))
    assert run(state_with({path: agenda}), **args).passed  # how it passed before: slide 3 only
    verdict = run(with_baseline({path: agenda}, {path: fresh}), **args)
    assert not verdict.passed and verdict.reason == ("expected the other slides unchanged, found slide 1 changed: "
                                                     "title 'Agenda' instead of 'Safety week overview'")

    def no_bodies(prs):
        for slide in prs.slides:
            slide.placeholders[1].text_frame.text = ""
    verdict = run(with_baseline({path: retitle(no_bodies)}, {path: fresh}), **args)
    assert not verdict.passed
    assert "slide 1 changed: text [] instead of ['Point 1: Safety week overview']" in verdict.reason
    own_body = retitle(lambda prs: setattr(prs.slides[2].placeholders[1].text_frame, "text", "Roadmap"))
    verdict = run(with_baseline({path: own_body}, {path: fresh}), **args)
    assert not verdict.passed and "slide 3 changed: text ['Roadmap'] instead of ['Point 3: Budget']" in verdict.reason


def test_delete_slide_keeps_the_others():
    path = "/home/user/Documents/retro.pptx"
    run = get_evaluator("slide_titles_are")
    args = {"path": path, "titles": TITLES, "without": "Budget", "kind": "pptx"}
    fresh = pptx_deck()

    def delete_budget(*more):
        def edit(prs):
            for fn in more:
                fn(prs)
            ids = prs.slides._sldIdLst
            ids.remove(list(ids)[2])
        return pptx_deck(edit=edit)
    assert run(with_baseline({path: delete_budget()}, {path: fresh}), **args).passed
    hit = delete_budget(lambda prs: setattr(prs.slides[3].placeholders[1].text_frame, "text", ""))
    assert run(state_with({path: hit}), **args).passed  # how it passed before: titles only
    verdict = run(with_baseline({path: hit}, {path: fresh}), **args)
    assert not verdict.passed and "slide 'Risks' changed: text [] instead of ['Point 4: Risks']" in verdict.reason


def test_speaker_notes_on_one_slide_in_the_format_asked():
    path = "/home/user/Documents/townhall.pptx"
    run = get_evaluator("slide_notes_contain")
    args = {"path": path, "number": "3", "text": "Mention the pilot results", "kind": "pptx"}
    fresh = pptx_deck()

    def noted(*numbers):
        def edit(prs):
            for n in numbers:
                prs.slides[n - 1].notes_slide.notes_text_frame.text = "Mention the pilot results"
        return pptx_deck(edit=edit)
    assert run(with_baseline({path: noted(3)}, {path: fresh}), **args).passed
    everywhere = noted(1, 2, 3, 4, 5)
    assert run(state_with({path: everywhere}), **args).passed  # how it passed before: slide 3 only
    verdict = run(with_baseline({path: everywhere}, {path: fresh}), **args)
    assert not verdict.passed and verdict.reason == ("expected the other slides unchanged, found slide 1 changed: "
                                                     "notes 'Mention the pilot results' instead of ''")
    as_odp = odp_deck(notes={3: "Mention the pilot results"})
    verdict = run(with_baseline({path: as_odp}, {path: fresh}), **args)
    assert not verdict.passed and verdict.reason == "expected a .pptx presentation, found a .odp file"
    in_body = pptx_deck(edit=lambda prs: setattr(prs.slides[2].placeholders[1].text_frame, "text",
                                                 "Point 3: Budget Mention the pilot results"))
    verdict = run(with_baseline({path: in_body}, {path: fresh}), **args)
    assert not verdict.passed and "no notes" in verdict.reason


def test_pdf_of_the_deck_as_set_up():
    deck, pdf = "/home/user/Downloads/slides.pptx", "/home/user/Downloads/slides.pdf"
    evaluate = get_evaluator("pdf_matches_presentation")
    fresh = pptx_deck()
    good = minimal_pdf([f"{t} Point {i}: {t}" for i, t in enumerate(TITLES, 1)])
    assert evaluate(with_baseline({deck: fresh, pdf: good}, {deck: fresh}), path=pdf, presentation=deck).passed
    titles_only = minimal_pdf(TITLES)
    verdict = evaluate(with_baseline({deck: fresh, pdf: titles_only}, {deck: fresh}), path=pdf, presentation=deck)
    assert not verdict.passed and "lacking ['Point 1: Safety week overview'" in verdict.reason
    # the deck cut to its first slide and a PDF of that
    one, one_pdf = pptx_deck(TITLES[:1]), minimal_pdf([f"{TITLES[0]} Point 1: {TITLES[0]}"])
    assert evaluate(state_with({deck: one, pdf: one_pdf}), path=pdf, presentation=deck).passed  # before: as found
    verdict = evaluate(with_baseline({deck: one, pdf: one_pdf}, {deck: fresh}), path=pdf, presentation=deck)
    assert not verdict.passed and "on 5 pages" in verdict.reason and "found 1 page(s)" in verdict.reason
    verdict = evaluate(with_baseline({deck: one, pdf: good}, {deck: fresh}), path=pdf, presentation=deck)
    assert not verdict.passed and f"expected the other slides unchanged, found 1 slides instead of 5" in verdict.reason
