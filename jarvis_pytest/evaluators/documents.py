"""Checks of text documents (Writer .odt and .docx) and of exported PDFs, parsed on the host.

`read_document` turns either format into the same plain model — paragraphs in order with their text, style,
bold-ness, list membership and heading level, and the tables with their cell texts — with odfpy (ODF) and
python-docx (OOXML), so each check is written once for both. PDFs are read with pypdf.
"""

from __future__ import annotations

import io
import re
import zipfile
from dataclasses import dataclass, field

from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.state import FinalState, judge_file

ODF_KINDS = {"application/vnd.oasis.opendocument.text": "odt",
             "application/vnd.oasis.opendocument.spreadsheet": "ods",
             "application/vnd.oasis.opendocument.presentation": "odp"}
OOXML_PARTS = {"word/document.xml": "docx", "xl/workbook.xml": "xlsx", "ppt/presentation.xml": "pptx"}


class NotADocument(ValueError):
    """The bytes are no .odt or .docx document."""


@dataclass
class Paragraph:
    text: str
    style: str = ""
    bold: bool = False
    listed: bool = False
    heading: int | None = None


@dataclass
class Document:
    kind: str  # "odt" or "docx"
    paragraphs: list[Paragraph] = field(default_factory=list)
    tables: list[list[list[str]]] = field(default_factory=list)  # table → rows → cell texts

    @property
    def text(self) -> str:
        cells = [c for t in self.tables for row in t for c in row]
        return "\n".join([p.text for p in self.paragraphs] + cells)

    def find(self, text: str) -> Paragraph | None:
        """The first paragraph whose text is `text` (whitespace-normalised)."""
        want = norm(text)
        return next((p for p in self.paragraphs if norm(p.text) == want), None)


def norm(text: str) -> str:
    return " ".join(str(text).split())


def office_kind(data: bytes) -> str:
    """The office format of `data` by its content, not a file name: "odt", "ods", "odp" (ODF mimetype),
    "docx", "xlsx", "pptx" (OOXML part), "zip" for another zip package, "" for no zip at all."""
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as zf:
            names = set(zf.namelist())
            mime = zf.read("mimetype").decode(errors="replace").strip() if "mimetype" in names else ""
    except zipfile.BadZipFile:
        return ""
    return ODF_KINDS.get(mime) or next((k for part, k in OOXML_PARTS.items() if part in names), "zip")


def document_kind(data: bytes) -> str:
    """"odt" or "docx" by the package's content; NotADocument otherwise."""
    kind = office_kind(data)
    if kind not in ("odt", "docx"):
        raise NotADocument(f"not a text document ({kind or 'no zip package'})")
    return kind


def read_document(data: bytes) -> Document:
    """Parse .odt or .docx bytes into a `Document`; NotADocument when they are neither."""
    kind = document_kind(data)
    return _read_odt(data) if kind == "odt" else _read_docx(data)


# -- ODF (odfpy) ---------------------------------------------------------------------------------------------
def _read_odt(data: bytes) -> Document:
    from odf.namespaces import TABLENS, TEXTNS
    from odf import teletype
    from odf.opendocument import load

    odf = load(io.BytesIO(data))
    styles: dict[str, object] = {}
    for container in (odf.styles, odf.automaticstyles):
        for el in container.childNodes:
            if el.qname[1] == "style" and el.getAttribute("name"):
                styles[el.getAttribute("name")] = el

    def weight_bold(name: str | None, depth: int = 0) -> bool | None:
        el = styles.get(name or "")
        if el is None or depth > 10:
            return None
        for child in el.childNodes:
            if child.qname[1] == "text-properties" and child.getAttribute("fontweight"):
                return child.getAttribute("fontweight") in ("bold", "700", "800", "900")
        return weight_bold(el.getAttribute("parentstylename"), depth + 1)

    def pieces(el, bold: bool) -> list[tuple[str, bool]]:
        out = []
        for node in el.childNodes:
            if node.nodeType == node.TEXT_NODE:
                out.append((str(node.data), bold))
            elif node.qname == (TEXTNS, "span"):
                own = weight_bold(node.getAttribute("stylename"))
                out += pieces(node, bold if own is None else own)
            elif node.qname in ((TEXTNS, "s"), (TEXTNS, "tab"), (TEXTNS, "line-break")):
                out.append((" ", bold))
            else:
                out += pieces(node, bold)
        return out

    def table_rows(el) -> list:
        """The rows of a table, header rows included, not those of tables nested in its cells."""
        rows = []
        for child in el.childNodes:
            if child.qname == (TABLENS, "table-row"):
                rows.append(child)
            elif child.qname in ((TABLENS, "table-header-rows"), (TABLENS, "table-rows"),
                                 (TABLENS, "table-row-group")):
                rows += table_rows(child)
        return rows

    doc = Document("odt")

    def walk(el, listed: bool) -> None:
        for node in el.childNodes:
            if node.nodeType != node.ELEMENT_NODE:
                continue
            if node.qname in ((TEXTNS, "p"), (TEXTNS, "h")):
                style = node.getAttribute("stylename") or ""
                base = bool(weight_bold(style))
                parts = [(t, b) for t, b in pieces(node, base) if t.strip()]
                level = node.getAttribute("outlinelevel") if node.qname[1] == "h" else None
                if level is None and re.match(r"Heading_20_(\d)", style):
                    level = re.match(r"Heading_20_(\d)", style).group(1)
                doc.paragraphs.append(Paragraph(teletype.extractText(node), style,
                                                bool(parts) and all(b for _, b in parts), listed,
                                                int(level) if level else None))
            elif node.qname == (TABLENS, "table"):
                doc.tables.append([[norm(teletype.extractText(c)) for c in row.childNodes
                                    if c.qname == (TABLENS, "table-cell")
                                    for _ in range(min(int(c.getAttribute("numbercolumnsrepeated") or 1), 64))]
                                   for row in table_rows(node)])
            else:
                walk(node, listed or node.qname == (TEXTNS, "list"))

    walk(odf.text, False)
    return doc


# -- OOXML (python-docx) -------------------------------------------------------------------------------------
def _read_docx(data: bytes) -> Document:
    import docx
    from docx.oxml.ns import qn

    d = docx.Document(io.BytesIO(data))

    def style_chain(style):
        while style is not None:
            yield style
            style = style.base_style

    def style_bold(style) -> bool:
        return next((bool(s.font.bold) for s in style_chain(style) if s.font.bold is not None), False)

    def numbered(ppr) -> bool | None:
        """True/False when `ppr` (a w:pPr) says whether its paragraph is a list item, None when it is silent.
        A w:numPr with numId 0 is Word's (and Writer's) way of saying "no list" over a list style."""
        num = ppr.find(qn("w:numPr")) if ppr is not None else None
        if num is None:
            return None
        num_id = num.find(qn("w:numId"))
        return num_id is None or num_id.get(qn("w:val")) != "0"

    def style_listed(style) -> bool:
        for s in style_chain(style):
            said = numbered(s.element.find(qn("w:pPr")))
            if said is not None:
                return said
        return False

    def run_bold(run, base: bool) -> bool:
        if run.bold is not None:  # direct formatting
            return bool(run.bold)
        if run.style is not None and run.style.name != "Default Paragraph Font":  # a character style, e.g. Strong
            own = next((s.font.bold for s in style_chain(run.style) if s.font.bold is not None), None)
            if own is not None:
                return bool(own)
        return base

    doc = Document("docx")
    for p in d.paragraphs:
        base = style_bold(p.style) if p.style is not None else False
        runs = [(r.text, run_bold(r, base)) for r in p.runs if r.text.strip()]
        direct = numbered(p._p.pPr)
        listed = direct if direct is not None else (p.style is not None and style_listed(p.style))
        name = p.style.name if p.style is not None else ""
        m = re.match(r"Heading (\d)", name)
        doc.paragraphs.append(Paragraph(p.text, name, bool(runs) and all(b for _, b in runs), listed,
                                        int(m.group(1)) if m else None))
    for t in d.tables:
        doc.tables.append([[norm(c.text) for c in row.cells] for row in t.rows])
    return doc


def _with_document(state: FinalState, path: str, platform: str | None, want: str, check) -> Verdict:
    return judge_file(state, path, want, read_document, check, platform)


# -- checks --------------------------------------------------------------------------------------------------
def check_lines_listed(doc: Document, lines: list[str]) -> Verdict:
    """Every line of `lines` is a paragraph of the document that is an item of a (bulleted or numbered) list."""
    missing = [line for line in lines if doc.find(line) is None]
    unlisted = [line for line in lines if doc.find(line) is not None and not doc.find(line).listed]
    found = (f"missing {missing!r}" if missing else "") + (f" not in a list: {unlisted!r}" if unlisted else "")
    return Verdict.check(not missing and not unlisted, f"all {len(lines)} lines as list items",
                         found.strip() or "all listed")


@evaluator("document_lines_listed")
def document_lines_listed(state: FinalState, path: str, lines: list[str], kind: str | None = None,
                          platform: str | None = None) -> Verdict:
    """Every line of `lines` is a list item of the document (of `kind`: odt or docx, when given)."""
    return _with_document(state, path, platform, f"{path} with its lines in a list",
                          lambda doc: _of_kind(doc, kind) or check_lines_listed(doc, lines))


def _of_kind(doc: Document, kind: str | None) -> Verdict | None:
    """A failed verdict when the document is not of `kind` (e.g. saved as .odt under a .docx name)."""
    if kind and doc.kind != kind:
        return Verdict.check(False, f"a .{kind} document", f"a .{doc.kind} document")
    return None


def check_paragraph_bold(doc: Document, text: str, others: list[str] | None = None) -> Verdict:
    """The paragraph `text` is bold, and the paragraphs `others` are still there and not bold."""
    want = f"the paragraph {text!r} in bold" + (f", the {len(others)} others kept and not bold" if others else "")
    para = doc.find(text)
    if para is None:
        return Verdict.check(False, want, "no such paragraph")
    missing = [o for o in others or [] if doc.find(o) is None]
    bolded = [o for o in others or [] if doc.find(o) is not None and doc.find(o).bold]
    if missing or bolded:
        return Verdict.check(False, want, f"missing {missing!r}" if missing else f"also bold: {bolded!r}")
    return Verdict.check(para.bold, want, "bold" if para.bold else f"not bold (style {para.style or 'default'})")


@evaluator("document_paragraph_bold")
def document_paragraph_bold(state: FinalState, path: str, text: str, others: list[str] | None = None,
                            kind: str | None = None, platform: str | None = None) -> Verdict:
    """The paragraph `text` is bold and only it, of `others` (in a document of `kind`, when given)."""
    return _with_document(state, path, platform, f"{text!r} in bold",
                          lambda doc: _of_kind(doc, kind) or check_paragraph_bold(doc, text, others))


def check_document_text(doc: Document, contains: list[str], absent: list[str]) -> Verdict:
    body = norm(doc.text)
    lacking = [t for t in contains if norm(t) not in body]
    present = [t for t in absent if norm(t) in body]
    want = " and ".join(x for x in (f"text with {contains!r}" if contains else "",
                                    f"without {absent!r}" if absent else "") if x)
    found = "; ".join(x for x in (f"lacking {lacking!r}" if lacking else "",
                                  f"still has {present!r}" if present else "") if x)
    return Verdict.check(not lacking and not present, want, found or f"it ({len(body)} characters)")


@evaluator("document_text_has")
def document_text_has(state: FinalState, path: str, contains: list[str] | None = None,
                      absent: list[str] | None = None, kind: str | None = None,
                      platform: str | None = None) -> Verdict:
    """The document (.odt/.docx, of `kind` when given) contains every text of `contains` and none of `absent`."""
    def check(doc: Document) -> Verdict:
        return _of_kind(doc, kind) or check_document_text(doc, contains or [], absent or [])
    return _with_document(state, path, platform, f"{path} with the right text", check)


def check_table(doc: Document, rows: int, cols: int, header: list[str] | None = None) -> Verdict:
    """The document has a table of `rows` × `cols` whose first row reads `header` (when given; whitespace
    normalised). Any of the document's tables may be the one."""
    rows, cols = int(rows), int(cols)
    want = f"a {rows}×{cols} table" + (f" headed {header!r}" if header else "")
    shaped = [t for t in doc.tables if len(t) == rows and all(len(r) == cols for r in t)]
    if not shaped:
        shapes = [f"{len(t)}×{max((len(r) for r in t), default=0)}" for t in doc.tables]
        return Verdict.check(False, want, f"tables {', '.join(shapes)}" if shapes else "no table")
    if header is None:
        return Verdict.check(True, want, f"{len(shaped)} such table(s)")
    heads = [t[0] for t in shaped]
    ok = [norm(h) for h in header] in heads
    return Verdict.check(ok, want, "it" if ok else " / ".join(f"headed {h!r}" for h in heads))


@evaluator("document_has_table")
def document_has_table(state: FinalState, path: str, rows: int, cols: int, header: list[str] | None = None,
                       platform: str | None = None) -> Verdict:
    return _with_document(state, path, platform, f"a {rows}×{cols} table",
                          lambda doc: check_table(doc, int(rows), int(cols), header))


def check_heading(doc: Document, text: str, level: int) -> Verdict:
    para = doc.find(text)
    if para is None:
        return Verdict.check(False, f"{text!r} as a level-{level} heading", "no such paragraph")
    return Verdict.check(para.heading == int(level), f"{text!r} as a level-{level} heading",
                         f"style {para.style or 'default'} (heading level {para.heading})")


@evaluator("document_heading_is")
def document_heading_is(state: FinalState, path: str, text: str, level: int = 1,
                        platform: str | None = None) -> Verdict:
    return _with_document(state, path, platform, f"{text!r} as a heading", lambda doc: check_heading(doc, text, level))


def check_pdf_text(data: bytes, contains: list[str], pages: int | None = None) -> Verdict:
    """`data` is a PDF whose extracted text has every text of `contains` (and `pages` pages, when given)."""
    from pypdf import PdfReader
    from pypdf.errors import PdfReadError

    want = f"a PDF with {contains!r}" + (f" on {pages} pages" if pages else "")
    if not data.startswith(b"%PDF"):
        return Verdict.check(False, want, f"no PDF (starts {data[:8]!r})")
    try:
        reader = PdfReader(io.BytesIO(data))
        text = norm(" ".join(page.extract_text() or "" for page in reader.pages))
    except (PdfReadError, Exception) as exc:
        return Verdict.check(False, want, f"an unreadable PDF ({exc})")
    lacking = [t for t in contains if norm(t) not in text]
    wrong_pages = pages is not None and len(reader.pages) != int(pages)
    found = f"{len(reader.pages)} page(s)" + (f", lacking {lacking!r}" if lacking else "")
    return Verdict.check(not lacking and not wrong_pages, want, found)


@evaluator("pdf_has_text")
def pdf_has_text(state: FinalState, path: str, contains: list[str], pages: int | None = None,
                 platform: str | None = None) -> Verdict:
    return judge_file(state, path, f"a PDF at {path}", bytes, lambda data: check_pdf_text(data, contains, pages),
                      platform)


def paragraph_lines(data: bytes) -> list[str]:
    """The non-empty paragraphs of an .odt/.docx, whitespace-normalised."""
    return [norm(p.text) for p in read_document(data).paragraphs if norm(p.text)]


@evaluator("document_same_text")
def document_same_text(state: FinalState, path: str, reference: str, kind: str | None = None,
                       platform: str | None = None) -> Verdict:
    """`path` is a document (of `kind`, when given) with the same non-empty paragraphs as `reference`."""
    def check(doc: Document, source: list[str]) -> Verdict:
        wrong = _of_kind(doc, kind)
        if wrong:
            return wrong
        got = [norm(p.text) for p in doc.paragraphs if norm(p.text)]
        return Verdict.check(got == source, f"the {len(source)} paragraphs of {reference}",
                             f"{len(got)} paragraphs" + ("" if got == source else f", first {got[:2]!r}"))
    return judge_file(state, reference, f"the text of {reference}", paragraph_lines,
                      lambda source: _with_document(state, path, platform, f"a copy of {reference}",
                                                    lambda doc: check(doc, source)), platform)


@evaluator("pdf_matches_document")
def pdf_matches_document(state: FinalState, path: str, document: str, platform: str | None = None) -> Verdict:
    """`path` is a PDF showing the text of every paragraph of `document` (an .odt/.docx)."""
    return judge_file(state, document, f"the text of {document}", paragraph_lines,
                      lambda source: pdf_has_text(state, path, source, platform=platform), platform)
