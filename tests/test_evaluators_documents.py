"""The document checks (evaluators/documents.py) and generators (generators/documents.py), without containers:
each check passes on a document as a solved Writer task leaves it and fails, naming what it expected and found, on
the document as set up. .odt files are built with odfpy in the shape Writer 7.4 saves them (a bolded line as an
automatic paragraph style P1 with fo:font-weight, a bulleted list as text:list/text:list-item, a table from
Table ▸ Insert Table with Table_20_Contents cells, header rows in table:table-header-rows); .docx files are the
generator's, edited with python-docx the way Writer writes them (w:numPr in the paragraph, w:b in the run)."""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import docx
import pytest
from docx.oxml import OxmlElement
from docx.oxml.ns import qn
from odf.opendocument import OpenDocumentText
from odf.style import Style, TextProperties
from odf.table import Table, TableCell, TableColumn, TableHeaderRows, TableRow
from odf.text import H, List, ListItem, P, Span

from jarvis_pytest.evaluators import get_evaluator
from jarvis_pytest.evaluators.documents import (NotADocument, check_document_text, check_heading,
                                                check_lines_listed, check_paragraph_bold, check_pdf_text,
                                                check_table, document_kind, office_kind, paragraph_lines,
                                                read_document)
from file_state import state_with
from jarvis_pytest.generators import generate

LINES = ["Book a room for the workshop", "Send the invitations", "Order coffee and snacks"]
TITLE = ["New Parking Rules", "This note explains the change in detail.", "Questions go to the office."]
OFFICE = Path(__file__).parent / "data" / "office"  # written by LibreOffice 7 on the device from the .html there


# --- files -------------------------------------------------------------------------------------------------------

def odt(body, styles=(), common=()) -> bytes:
    """An .odt whose office:text holds the elements `body`, with automatic `styles` and `common` (named) styles."""
    doc = OpenDocumentText()
    for style in styles:
        doc.automaticstyles.addElement(style)
    for style in common:
        doc.styles.addElement(style)
    for el in body:
        doc.text.addElement(el)
    buf = io.BytesIO()
    doc.write(buf)
    return buf.getvalue()


def bold_style(name: str, family: str = "paragraph", weight: str = "bold", parent: str | None = "Standard"):
    style = Style(name=name, family=family, **({"parentstylename": parent} if parent else {}))
    style.addElement(TextProperties(fontweight=weight, fontweightasian=weight, fontweightcomplex=weight))
    return style


def plain_p(text: str, style: str = "Standard"):
    return P(stylename=style, text=text)


def bulleted(lines: list[str]):
    lst = List(stylename="L1")
    for line in lines:
        item = ListItem()
        item.addElement(P(stylename="P1", text=line))
        lst.addElement(item)
    return lst


def odt_table(rows: list[list[str]], header_rows: int = 0):
    """A Writer table (Table ▸ Insert Table): its first `header_rows` rows inside table:table-header-rows."""
    table = Table(name="Table1")
    table.addElement(TableColumn(numbercolumnsrepeated=len(rows[0])))
    head = TableHeaderRows() if header_rows else None
    for i, cells in enumerate(rows):
        row = TableRow()
        for text in cells:
            cell = TableCell(valuetype="string")
            cell.addElement(P(stylename="Table_20_Contents", text=text) if text else P(stylename="Table_20_Contents"))
            row.addElement(cell)
        (head if head is not None and i < header_rows else table).addElement(row)
        if head is not None and i == header_rows - 1:
            table.addElement(head)
    return table


def docx_edited(edit, paragraphs: list[str] = LINES) -> bytes:
    d = docx.Document(io.BytesIO(generate("docx_document", {"paragraphs": paragraphs})))
    edit(d)
    buf = io.BytesIO()
    d.save(buf)
    return buf.getvalue()


def num_pr(paragraph, num_id: int) -> None:
    """Make `paragraph` a list item the way Writer saves a bulleted list to .docx: w:numPr in its w:pPr."""
    num = OxmlElement("w:numPr")
    for tag, val in (("w:ilvl", "0"), ("w:numId", str(num_id))):
        el = OxmlElement(tag)
        el.set(qn("w:val"), val)
        num.append(el)
    paragraph._p.get_or_add_pPr().append(num)



# --- generators ----------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("name,kind", [("docx_document", "docx"), ("odt_document", "odt")])
def test_generators_are_deterministic_plain_documents(name, kind):
    data = generate(name, {"paragraphs": LINES})
    odt([bulleted(LINES)])  # odfpy remembers every namespace it met: the bytes must not depend on that
    assert data == generate(name, {"paragraphs": LINES}) != generate(name, {"paragraphs": LINES[:2]})
    assert document_kind(data) == office_kind(data) == kind
    doc = read_document(data)
    assert doc.kind == kind and [p.text for p in doc.paragraphs] == LINES and doc.tables == []
    assert not any(p.bold or p.listed or p.heading for p in doc.paragraphs)
    assert paragraph_lines(data) == LINES
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        assert {i.date_time for i in zf.infolist()} == {(2025, 1, 6, 9, 0, 0)}
    with pytest.raises(Exception, match="paragraphs"):
        generate(name, {"paragraphs": "one line"})


def test_kinds_by_content_not_by_name():
    assert office_kind(b"plain text") == ""
    assert office_kind(generate("people_table", {"seed": 1, "rows": 3, "format": "xlsx"})) == "xlsx"
    for data in (b"plain text", generate("people_table", {"seed": 1, "rows": 3, "format": "ods"})):
        with pytest.raises(NotADocument):
            read_document(data)


# --- bold title ----------------------------------------------------------------------------------------------------

def test_bold_title_in_odt_as_writer_saves_it():
    fresh = read_document(generate("odt_document", {"paragraphs": TITLE}))
    verdict = check_paragraph_bold(fresh, TITLE[0], TITLE[1:])
    assert not verdict.passed and "expected the paragraph 'New Parking Rules' in bold" in verdict.reason
    assert "found not bold" in verdict.reason
    # Ctrl+Home, Shift+End, Ctrl+B, Ctrl+S: the whole paragraph gets an automatic paragraph style P1
    solved = read_document(odt([plain_p(TITLE[0], "P1")] + [plain_p(t) for t in TITLE[1:]], [bold_style("P1")]))
    assert check_paragraph_bold(solved, TITLE[0], TITLE[1:]).passed
    # the whole document bolded: the others are bold too
    every = read_document(odt([plain_p(t, "P1") for t in TITLE], [bold_style("P1")]))
    verdict = check_paragraph_bold(every, TITLE[0], TITLE[1:])
    assert not verdict.passed and "also bold" in verdict.reason
    # the title's text was changed or deleted
    verdict = check_paragraph_bold(read_document(odt([plain_p(t) for t in TITLE[1:]])), TITLE[0], TITLE[1:])
    assert not verdict.passed and "no such paragraph" in verdict.reason


def test_bold_in_odt_spans_and_inherited_styles():
    # only part of the title bolded (a span T1): not the paragraph in bold
    part = P(stylename="Standard")
    part.addElement(Span(stylename="T1", text="New Parking"))
    part.addText(" Rules")
    doc = read_document(odt([part], [bold_style("T1", "text", parent=None)]))
    assert doc.paragraphs[0].text == TITLE[0] and not check_paragraph_bold(doc, TITLE[0]).passed
    # every character in bold spans: bold
    whole = P(stylename="Standard")
    whole.addElement(Span(stylename="T1", text=TITLE[0]))
    assert check_paragraph_bold(read_document(odt([whole], [bold_style("T1", "text", parent=None)])), TITLE[0]).passed
    # a paragraph style inheriting bold from its (named) parent style, and a span taking it back to normal
    child = Style(name="P2", family="paragraph", parentstylename="Title_20_Bold")
    doc = read_document(odt([plain_p(TITLE[0], "P2")], [child], [bold_style("Title_20_Bold")]))
    assert check_paragraph_bold(doc, TITLE[0]).passed
    unbold = P(stylename="P1")
    unbold.addElement(Span(stylename="T2", text=TITLE[0]))
    doc = read_document(odt([unbold], [bold_style("P1"), bold_style("T2", "text", "normal", None)]))
    assert not check_paragraph_bold(doc, TITLE[0]).passed
    # numeric weights count
    assert check_paragraph_bold(read_document(odt([plain_p(TITLE[0], "P3")], [bold_style("P3", weight="700")])),
                                TITLE[0]).passed


def test_bold_title_in_docx():
    def bold_first(d):
        d.paragraphs[0].runs[0].bold = True
    solved = read_document(docx_edited(bold_first, TITLE))
    assert check_paragraph_bold(solved, TITLE[0], TITLE[1:]).passed
    assert not check_paragraph_bold(solved, TITLE[1]).passed

    def strong(d):  # a bold character style instead of direct formatting
        d.paragraphs[0].runs[0].style = d.styles["Strong"]
    doc = read_document(docx_edited(strong, TITLE))
    assert doc.paragraphs[0].bold and not doc.paragraphs[1].bold


# --- bulleted list -------------------------------------------------------------------------------------------------

def test_bulleted_list_in_odt_as_writer_saves_it():
    fresh = read_document(generate("odt_document", {"paragraphs": LINES}))
    verdict = check_lines_listed(fresh, LINES)
    assert not verdict.passed and "expected all 3 lines as list items" in verdict.reason
    assert "not in a list: ['Book a room for the workshop'" in verdict.reason
    assert check_lines_listed(read_document(odt([bulleted(LINES)])), LINES).passed
    # only the first two lines in the list
    verdict = check_lines_listed(read_document(odt([bulleted(LINES[:2]), plain_p(LINES[2])])), LINES)
    assert not verdict.passed and "not in a list: ['Order coffee and snacks']" in verdict.reason
    # a line lost on the way
    verdict = check_lines_listed(read_document(odt([bulleted(LINES[:2])])), LINES)
    assert not verdict.passed and "missing ['Order coffee and snacks']" in verdict.reason


def test_bulleted_list_in_docx():
    fresh = read_document(generate("docx_document", {"paragraphs": LINES}))
    assert not check_lines_listed(fresh, LINES).passed

    def writer_bullets(d):  # Ctrl+A, Shift+F12, keep the Word format
        for p in d.paragraphs:
            num_pr(p, 7)
    assert check_lines_listed(read_document(docx_edited(writer_bullets)), LINES).passed

    def list_style(d):  # Word's way: the List Bullet paragraph style (its numbering in the style)
        for p in d.paragraphs:
            p.style = d.styles["List Bullet"]
    assert check_lines_listed(read_document(docx_edited(list_style)), LINES).passed

    def numbering_off(d):  # numId 0 on a list-styled paragraph: "no list" (Writer's "No List")
        for p in d.paragraphs:
            p.style = d.styles["List Bullet"]
        num_pr(d.paragraphs[2], 0)
    verdict = check_lines_listed(read_document(docx_edited(numbering_off)), LINES)
    assert not verdict.passed and "not in a list: ['Order coffee and snacks']" in verdict.reason


# --- table ---------------------------------------------------------------------------------------------------------

HEAD = ["Item", "Quantity", "Price"]


def test_table_in_odt_as_writer_saves_it():
    intro = [plain_p("Overview"), plain_p("The table below lists the details.")]
    fresh = read_document(odt(intro))
    verdict = check_table(fresh, 4, 3, HEAD)
    assert not verdict.passed and "expected a 4×3 table headed ['Item', 'Quantity', 'Price']" in verdict.reason
    assert "found no table" in verdict.reason
    rows = [HEAD] + [["", "", ""]] * 3
    for header_rows in (0, 1):  # the Insert Table dialog's "Heading" option off and on
        doc = read_document(odt(intro + [odt_table(rows, header_rows), plain_p("")]))
        assert doc.tables == [rows] and [p.text for p in doc.paragraphs][:2] == ["Overview", intro[1].firstChild.data]
        assert check_table(doc, 4, 3, HEAD).passed and check_table(doc, "4", "3").passed
        assert "Quantity" in doc.text and all(p.text != "Quantity" for p in doc.paragraphs)
    verdict = check_table(read_document(odt(intro + [odt_table(rows[:3])])), 4, 3, HEAD)
    assert not verdict.passed and "found tables 3×3" in verdict.reason
    verdict = check_table(read_document(odt([odt_table([HEAD[::-1]] + rows[1:])])), 4, 3, HEAD)
    assert not verdict.passed and "headed ['Price', 'Quantity', 'Item']" in verdict.reason
    # another table of the same shape before the right one
    doc = read_document(odt([odt_table([["a", "b", "c"]] + rows[1:]), odt_table(rows)]))
    assert check_table(doc, 4, 3, HEAD).passed


def test_table_in_docx():
    def add_table(d):
        t = d.add_table(rows=3, cols=3)
        for i, text in enumerate(["Day", "Time", "Room"]):
            t.cell(0, i).text = text
    doc = read_document(docx_edited(add_table))
    assert check_table(doc, 3, 3, ["Day", "Time", "Room"]).passed
    verdict = check_table(doc, 5, 3, ["Day", "Time", "Room"])
    assert not verdict.passed and "found tables 3×3" in verdict.reason


# --- replaced word, heading ----------------------------------------------------------------------------------------

def test_replaced_word_in_both_formats():
    old = ["Agreement between Contoso and the client", "Contoso will deliver the service monthly."]
    new = [t.replace("Contoso", "Litware") for t in old]
    for name in ("docx_document", "odt_document"):
        fresh = read_document(generate(name, {"paragraphs": old}))
        verdict = check_document_text(fresh, new, ["Contoso"])
        assert not verdict.passed and "lacking" in verdict.reason and "still has ['Contoso']" in verdict.reason
        assert "expected text with" in verdict.reason
        assert check_document_text(read_document(generate(name, {"paragraphs": new})), new, ["Contoso"]).passed
        # replaced in the first paragraph only
        half = read_document(generate(name, {"paragraphs": [new[0], old[1]]}))
        verdict = check_document_text(half, new, ["Contoso"])
        assert not verdict.passed and "lacking ['Litware will deliver the service monthly.']" in verdict.reason
    # a word split into runs by formatting still reads as one text
    def split_runs(d):
        p = d.paragraphs[0]
        p.runs[0].text = "Agreement between Lit"
        p.add_run("ware").bold = True
        p.add_run(" and the client")
    assert check_document_text(read_document(docx_edited(split_runs, old[:1])), new[:1], ["Contoso"]).passed


def test_headings_in_both_formats():
    fresh = read_document(generate("odt_document", {"paragraphs": TITLE}))
    verdict = check_heading(fresh, TITLE[0], 1)
    assert not verdict.passed and "expected 'New Parking Rules' as a level-1 heading" in verdict.reason
    doc = read_document(odt([H(outlinelevel=1, stylename="Heading_20_1", text=TITLE[0])]))
    assert check_heading(doc, TITLE[0], 1).passed and not check_heading(doc, TITLE[0], 2).passed

    def heading(d):
        d.paragraphs[0].style = d.styles["Heading 2"]
    assert check_heading(read_document(docx_edited(heading, TITLE)), TITLE[0], 2).passed


# --- what LibreOffice wrote ----------------------------------------------------------------------------------------

def test_files_libreoffice_wrote():
    for name in ("libreoffice_sample.odt", "libreoffice_sample.docx"):
        doc = read_document((OFFICE / name).read_bytes())
        assert check_heading(doc, "Title here", 1).passed, name
        assert check_lines_listed(doc, ["one", "two"]).passed and not check_lines_listed(doc, ["Bold para"]).passed
        assert check_paragraph_bold(doc, "Bold para").passed and not check_paragraph_bold(doc, "one").passed, name
        assert check_table(doc, 2, 2, ["a", "b"]).passed, name
    pdf = (OFFICE / "libreoffice_export.pdf").read_bytes()
    assert check_pdf_text(pdf, ["Title here", "Bold para"], pages=1).passed
    verdict = check_pdf_text(pdf, ["Title here"], pages=2)
    assert not verdict.passed and "found 1 page(s)" in verdict.reason
    verdict = check_pdf_text(pdf, ["Missing words"])
    assert not verdict.passed and "lacking ['Missing words']" in verdict.reason
    verdict = check_pdf_text(b"PK\x03\x04 a zip", ["x"])
    assert not verdict.passed and "no PDF" in verdict.reason
    verdict = check_pdf_text(b"%PDF-1.7 truncated", ["x"])
    assert not verdict.passed and "unreadable PDF" in verdict.reason


def test_a_pdf_chromium_printed_reads_with_its_ligatures_unfolded():
    """Chromium prints "fi" as one ligature glyph, extracted as "ﬁ": the title "Course Certificate" of the print_pdf
    template's seed 2 failed its own oracle until the text was compared in compatibility form."""
    pdf = (OFFICE / "chromium_print.pdf").read_bytes()  # chromium --headless --print-to-pdf on the Ubuntu device
    assert check_pdf_text(pdf, ["Course Certificate", "Reference number: kestrel-24105", "Total: 690 EUR"]).passed
    assert not check_pdf_text(pdf, ["Course Certificates"]).passed
    assert not check_pdf_text(pdf, ["Total: 691 EUR"]).passed


# --- the evaluators on a device's files ----------------------------------------------------------------------------

def test_evaluators_pull_the_file_and_check_its_kind():
    path = "/home/user/Documents/todo.docx"
    listed = docx_edited(lambda d: [num_pr(p, 7) for p in d.paragraphs])
    run = get_evaluator("document_lines_listed")
    assert run(state_with({path: listed}), path=path, lines=LINES, kind="docx").passed
    verdict = run(state_with({}), path=path, lines=LINES, kind="docx")
    assert not verdict.passed and f"no file at {path}" in verdict.reason
    verdict = run(state_with({path: b"not a zip"}), path=path, lines=LINES)
    assert not verdict.passed and "unreadable" in verdict.reason
    # saved as ODF under the .docx name (the agent chose "Use ODF Format!")
    verdict = run(state_with({path: odt([bulleted(LINES)])}), path=path, lines=LINES, kind="docx")
    assert not verdict.passed and "expected a .docx document, found a .odt document" in verdict.reason

    bold = get_evaluator("document_paragraph_bold")
    doc = odt([plain_p(TITLE[0], "P1")] + [plain_p(t) for t in TITLE[1:]], [bold_style("P1")])
    assert bold(state_with({"/d.odt": doc}), path="/d.odt", text=TITLE[0], others=TITLE[1:], kind="odt").passed
    assert not bold(state_with({"/d.odt": doc}), path="/d.odt", text=TITLE[0], kind="docx").passed

    has = get_evaluator("document_text_has")
    data = generate("docx_document", {"paragraphs": ["Litware will deliver."]})
    assert has(state_with({"/c.docx": data}), path="/c.docx", contains=["Litware"], absent=["Contoso"]).passed
    assert not has(state_with({"/c.docx": data}), path="/c.docx", absent=["Litware"]).passed

    table = get_evaluator("document_has_table")
    data = odt([odt_table([HEAD, ["", "", ""]])])
    assert table(state_with({"/t.odt": data}), path="/t.odt", rows="2", cols=3, header=HEAD).passed
    assert not table(state_with({"/t.odt": data}), path="/t.odt", rows=3, cols=3).passed

    heading = get_evaluator("document_heading_is")
    data = odt([H(outlinelevel=1, stylename="Heading_20_1", text="Intro")])
    assert heading(state_with({"/h.odt": data}), path="/h.odt", text="Intro").passed


def test_same_text_and_pdf_evaluators_compare_with_the_source():
    src, out = "/home/user/Documents/handbook.docx", "/home/user/Documents/handbook.odt"
    lines = ["Guide to fire safety", "Read this before your first week."]
    source = generate("docx_document", {"paragraphs": lines})
    same = get_evaluator("document_same_text")
    verdict = same(state_with({src: source}), path=out, reference=src, kind="odt")
    assert not verdict.passed and f"no file at {out}" in verdict.reason
    as_odt = odt([plain_p(t) for t in lines] + [plain_p("")])  # a trailing empty paragraph does not matter
    assert same(state_with({src: source, out: as_odt}), path=out, reference=src, kind="odt").passed
    verdict = same(state_with({src: source, out: source}), path=out, reference=src, kind="odt")  # a renamed copy
    assert not verdict.passed and "found a .docx document" in verdict.reason
    verdict = same(state_with({src: source, out: odt([plain_p(lines[0])])}), path=out, reference=src, kind="odt")
    assert not verdict.passed and "expected the 2 paragraphs" in verdict.reason and "found 1 paragraphs" in verdict.reason

    pdf_of = get_evaluator("pdf_matches_document")
    sample, pdf = (OFFICE / "libreoffice_sample.docx").read_bytes(), (OFFICE / "libreoffice_export.pdf").read_bytes()
    assert pdf_of(state_with({"/s.docx": sample, "/s.pdf": pdf}), path="/s.pdf", document="/s.docx").passed
    verdict = pdf_of(state_with({"/s.docx": source, "/s.pdf": pdf}), path="/s.pdf", document="/s.docx")
    assert not verdict.passed and "lacking ['Guide to fire safety'" in verdict.reason
    verdict = pdf_of(state_with({"/s.docx": sample}), path="/s.pdf", document="/s.docx")
    assert not verdict.passed and "no file at /s.pdf" in verdict.reason


# --- near misses: what was not asked stays as set up (the baseline), list labels, the table's place ---------------

def with_baseline(files: dict[str, bytes], baselines: dict[str, bytes]):
    """A device holding `files`, whose `baselines` (the files right after set-up) the template listed."""
    return state_with(files, baselines=baselines)


def list_style(name: str, numbered: bool):
    from odf.text import ListLevelStyleBullet, ListLevelStyleNumber, ListStyle
    style = ListStyle(name=name)
    style.addElement(ListLevelStyleNumber(level=1, numformat="1") if numbered else
                     ListLevelStyleBullet(level=1, bulletchar="•"))
    return style


def test_list_labels_bullets_or_numbers_in_both_formats():
    bullets = read_document(odt([bulleted(LINES)], [list_style("L1", numbered=False)]))
    numbers = read_document(odt([bulleted(LINES)], [list_style("L1", numbered=True)]))
    assert [p.marker for p in bullets.paragraphs] == ["bullet"] * 3 and numbers.paragraphs[0].marker == "number"
    assert check_lines_listed(bullets, LINES, "bullet").passed
    verdict = check_lines_listed(numbers, LINES, "bullet")
    assert not verdict.passed and "expected all 3 lines as list items of a bulleted list" in verdict.reason
    assert "labelled 'number' instead of 'bullet'" in verdict.reason
    assert check_lines_listed(numbers, LINES).passed  # no label asked for: any list

    def styled(name):
        def edit(d):
            for p in d.paragraphs:
                p.style = d.styles[name]
        return edit
    assert check_lines_listed(read_document(docx_edited(styled("List Bullet"))), LINES, "bullet").passed
    verdict = check_lines_listed(read_document(docx_edited(styled("List Number"))), LINES, "bullet")
    assert not verdict.passed and "labelled 'number'" in verdict.reason
    # what Writer 7.4 wrote from <ul> and <ol>: numbering.xml's numFmt bullet / decimal
    doc = read_document((OFFICE / "libreoffice_sample.docx").read_bytes())
    assert check_lines_listed(doc, ["one", "two"], "bullet").passed
    assert not check_lines_listed(doc, ["one", "two"], "number").passed


def test_bullet_list_keeps_the_document_as_set_up():
    path = "/home/user/Documents/todo.docx"
    fresh = generate("docx_document", {"paragraphs": LINES})
    run = get_evaluator("document_lines_listed")
    args = {"path": path, "lines": LINES, "kind": "docx", "marker": "bullet"}

    def bullets(extra=None):
        def edit(d):
            if extra:
                d.add_paragraph(extra)
            for p in d.paragraphs:
                p.style = d.styles["List Bullet"]
        return docx_edited(edit)
    assert run(with_baseline({path: bullets()}, {path: fresh}), **args).passed
    verdict = run(with_baseline({path: bullets("Call the caterer")}, {path: fresh}), **args)
    assert not verdict.passed and "expected the rest of the text unchanged (3 paragraphs as set up)" in verdict.reason
    assert "added ['Call the caterer']" in verdict.reason
    # fed by an upstream subtask (no baseline): only the lines are judged
    assert run(state_with({path: bullets("Call the caterer")}), **args).passed


def test_bold_title_with_a_line_added_or_reworded():
    path = "/home/user/Documents/memo.odt"
    fresh = generate("odt_document", {"paragraphs": TITLE})
    run = get_evaluator("document_paragraph_bold")
    args = {"path": path, "text": TITLE[0], "others": TITLE[1:], "kind": "odt"}
    solved = odt([plain_p(TITLE[0], "P1")] + [plain_p(t) for t in TITLE[1:]], [bold_style("P1")])
    assert run(with_baseline({path: solved}, {path: fresh}), **args).passed
    draft = odt([plain_p(TITLE[0], "P1")] + [plain_p(t) for t in TITLE[1:]] + [plain_p("DRAFT - do not circulate")],
                [bold_style("P1")])
    verdict = run(with_baseline({path: draft}, {path: fresh}), **args)
    assert not verdict.passed and "added ['DRAFT - do not circulate']" in verdict.reason
    reworded = odt([plain_p(TITLE[0], "P1"), plain_p("This note explains it."), plain_p(TITLE[2])], [bold_style("P1")])
    verdict = run(with_baseline({path: reworded}, {path: fresh}), **{**args, "others": None})
    assert not verdict.passed and "missing ['This note explains the change in detail.']" in verdict.reason
    # a Word file under the .odt name fails on its format
    word = docx_edited(lambda d: setattr(d.paragraphs[0].runs[0], "bold", True), TITLE)
    verdict = run(with_baseline({path: word}, {path: fresh}), **args)
    assert not verdict.passed and "expected a .odt document, found a .docx document" in verdict.reason


def test_replace_word_is_the_original_with_the_word_replaced():
    path = "/home/user/Documents/contract.docx"
    original = ["Agreement between Contoso and the client", "Contoso will deliver the service monthly.",
                "Invoices are sent by Contoso at the end of each month."]
    new = [t.replace("Contoso", "Litware") for t in original]
    fresh = generate("docx_document", {"paragraphs": original})
    run = get_evaluator("document_text_has")
    args = {"path": path, "contains": new[:2], "absent": ["Contoso"], "kind": "docx",
            "replace": [["Contoso", "Litware"]]}
    assert run(with_baseline({path: generate("docx_document", {"paragraphs": new})}, {path: fresh}), **args).passed
    assert not run(with_baseline({path: fresh}, {path: fresh}), **args).passed
    # the mousepad-style cheap state: only the sentences the check names, the third paragraph gone
    two = generate("docx_document", {"paragraphs": new[:2]})
    verdict = run(with_baseline({path: two}, {path: fresh}), **args)
    assert not verdict.passed and "missing ['Invoices are sent by Litware at the end of each month.']" in verdict.reason
    assert "expected the original text with only the replacements made (3 paragraphs as set up)" in verdict.reason
    assert run(state_with({path: two}), **args).passed  # without a baseline only contains/absent can be judged
    signed = generate("docx_document", {"paragraphs": new + ["Signed: Litware"]})
    verdict = run(with_baseline({path: signed}, {path: fresh}), **args)
    assert not verdict.passed and "added ['Signed: Litware']" in verdict.reason
    # {old: new} works as well as [[old, new]]
    as_dict = {**args, "replace": {"Contoso": "Litware"}}
    assert run(with_baseline({path: generate("docx_document", {"paragraphs": new})}, {path: fresh}), **as_dict).passed
    assert not run(with_baseline({path: signed}, {path: fresh}), **as_dict).passed


INTRO = ["Overview", "The table below lists the details."]


@pytest.mark.parametrize("rows", [3, 5])
def test_table_at_the_end_with_the_header_row_counted(rows):
    """The fair reading of "a table with 3 columns and N rows in total (the header row counts as one)": N rows
    with the header passes; N + 1 (the header not counted) does not; nor does a table at the top, or the
    document's own paragraphs deleted, or a Word file under the .odt name."""
    path = "/home/user/Documents/schedule.odt"
    fresh = generate("odt_document", {"paragraphs": INTRO})
    run = get_evaluator("document_has_table")
    args = {"path": path, "rows": str(rows), "cols": 3, "header": HEAD, "kind": ".odt", "at_end": True}
    table = [HEAD] + [["", "", ""]] * (rows - 1)
    intro = [plain_p(t) for t in INTRO]
    good = odt(intro + [odt_table(table, header_rows=1), plain_p("")])
    assert run(with_baseline({path: good}, {path: fresh}), **args).passed
    longer = odt(intro + [odt_table(table + [["", "", ""]]), plain_p("")])
    verdict = run(with_baseline({path: longer}, {path: fresh}), **args)
    assert not verdict.passed and f"found tables {rows + 1}×3" in verdict.reason
    verdict = run(with_baseline({path: odt([odt_table(table)] + intro)}, {path: fresh}), **args)
    assert not verdict.passed and "at the end" in verdict.reason and "text after it: ['Overview'" in verdict.reason
    verdict = run(with_baseline({path: odt([odt_table(table), plain_p("")])}, {path: fresh}), **args)
    assert not verdict.passed and "missing ['Overview', 'The table below lists the details.']" in verdict.reason

    def word_table(d):
        t = d.add_table(rows=rows, cols=3)
        for i, text in enumerate(HEAD):
            t.cell(0, i).text = text
        d.add_paragraph("")
    word = docx_edited(word_table, INTRO)
    verdict = run(with_baseline({path: word}, {path: fresh}), **args)
    assert not verdict.passed and "expected a .odt document, found a .docx document" in verdict.reason
    assert run(with_baseline({path: word}, {path: fresh}), **{**args, "kind": ".docx"}).passed  # a fed .docx


def test_insert_table_instruction_says_the_header_row_counts():
    from jarvis_pytest.tasks.instances import atomic_task
    from jarvis_pytest.tasks.library import read_template_file

    library = Path(__file__).resolve().parents[1] / "tasks" / "ubuntu"
    [template] = read_template_file(library / "writer_insert_table.json")
    for seed in range(3):
        sub = atomic_task(template, seed).formatted_subtasks[0]
        rows = int(sub.input["rows"].value)
        assert f"3 columns and {rows} rows in total (its first row, the header row, counts as one" in sub.instruction
        setup = next(s for s in sub.config if getattr(s, "generator", None) == "odt_document")
        fresh = generate("odt_document", dict(setup.args))
        [spec] = sub.evaluate
        head = [sub.input[c].value for c in ("col1", "col2", "col3")]
        made = odt([plain_p(t) for t in paragraph_lines(fresh)] + [odt_table([head] + [["", "", ""]] * (rows - 1), 1),
                                                                   plain_p("")])
        path = spec.args["path"]
        assert get_evaluator(spec.func)(with_baseline({path: made}, {path: fresh}), **spec.args).passed
        assert not get_evaluator(spec.func)(with_baseline({path: fresh}, {path: fresh}), **spec.args).passed


def test_copies_and_pdfs_compare_with_the_source_as_set_up():
    src, out = "/home/user/Documents/handbook.docx", "/home/user/Documents/handbook.odt"
    lines = ["Guide to fire safety", "Read this before your first week.", "Ask your manager if anything is unclear."]
    source = generate("docx_document", {"paragraphs": lines})
    one = generate("docx_document", {"paragraphs": lines[:1]})
    one_odt = odt([plain_p(lines[0])])
    same = get_evaluator("document_same_text")
    good = odt([plain_p(t) for t in lines])
    assert same(with_baseline({src: source, out: good}, {src: source}), path=out, reference=src, kind="odt").passed
    # the source cut down to one line and a copy made of that: passes only when the original is not known
    assert same(state_with({src: one, out: one_odt}), path=out, reference=src, kind="odt").passed
    verdict = same(with_baseline({src: one, out: one_odt}, {src: source}), path=out, reference=src, kind="odt")
    assert not verdict.passed and "expected the 3 paragraphs of" in verdict.reason and "missing [" in verdict.reason
    # a right copy, but the source emptied afterwards
    verdict = same(with_baseline({src: one, out: good}, {src: source}), path=out, reference=src, kind="odt")
    assert not verdict.passed and f"the original {src} unchanged" in verdict.reason
    verdict = same(with_baseline({out: good}, {src: source}), path=out, reference=src, kind="odt")
    assert not verdict.passed and f"no file at {src}" in verdict.reason

    pdf_of = get_evaluator("pdf_matches_document")
    sample, pdf = (OFFICE / "libreoffice_sample.docx").read_bytes(), (OFFICE / "libreoffice_export.pdf").read_bytes()
    assert pdf_of(with_baseline({"/s.docx": sample, "/s.pdf": pdf}, {"/s.docx": sample}),
                  path="/s.pdf", document="/s.docx").passed
    # a document cut down to what the PDF shows: the original's text is still asked for
    cut = generate("docx_document", {"paragraphs": ["Title here", "Bold para"]})
    assert pdf_of(state_with({"/s.docx": cut, "/s.pdf": pdf}), path="/s.pdf", document="/s.docx").passed
    verdict = pdf_of(with_baseline({"/s.docx": cut, "/s.pdf": pdf}, {"/s.docx": source}), path="/s.pdf",
                     document="/s.docx")
    assert not verdict.passed and "lacking ['Guide to fire safety'" in verdict.reason
    verdict = pdf_of(with_baseline({"/s.docx": cut, "/s.pdf": pdf}, {"/s.docx": sample}), path="/s.pdf",
                     document="/s.docx")
    assert not verdict.passed and "the original /s.docx unchanged" in verdict.reason
