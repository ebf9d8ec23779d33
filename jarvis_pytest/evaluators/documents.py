"""Checks of text documents (Writer .odt and .docx) and of exported PDFs, parsed on the host.

`read_document` turns either format into the same plain model — paragraphs in order with their text, style,
bold-ness, list membership and heading level, and the tables with their cell texts — with odfpy (ODF) and
python-docx (OOXML), so each check is written once for both. PDFs are read with pypdf.
"""

from __future__ import annotations

import io
import re
import unicodedata
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
    marker: str | None = None  # a list item's label: "bullet", "number" or "none"; None when not known


@dataclass
class Document:
    kind: str  # "odt" or "docx"
    paragraphs: list[Paragraph] = field(default_factory=list)
    tables: list[list[list[str]]] = field(default_factory=list)  # table → rows → cell texts
    table_at: list[int] = field(default_factory=list)  # per table: how many body paragraphs come before it

    @property
    def lines(self) -> list[str]:
        """The non-empty body paragraphs (not table cells), whitespace-normalised."""
        return [norm(p.text) for p in self.paragraphs if norm(p.text)]

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
    list_styles: dict[str, object] = {}
    for container in (odf.styles, odf.automaticstyles):
        for el in container.childNodes:
            if el.qname[1] == "style" and el.getAttribute("name"):
                styles[el.getAttribute("name")] = el
            elif el.qname[1] == "list-style" and el.getAttribute("name"):
                list_styles[el.getAttribute("name")] = el

    def paragraph_list_style(name: str | None, depth: int = 0) -> str | None:
        el = styles.get(name or "")
        if el is None or depth > 10:
            return None
        return el.getAttribute("liststylename") or paragraph_list_style(el.getAttribute("parentstylename"), depth + 1)

    def list_marker(list_style: str | None, level: int) -> str | None:
        """"bullet" (a bullet or image label), "number" or "none" (a numbering without label) at `level`."""
        el = list_styles.get(list_style or "")
        if el is None:
            return None
        levels = {}
        for child in el.childNodes:
            if getattr(child, "qname", (None, ""))[1].startswith("list-level-style-"):
                levels[int(child.getAttribute("level") or 1)] = child
        child = levels.get(level) or levels.get(min(levels, key=lambda k: abs(k - level))) if levels else None
        if child is None:
            return None
        kind = child.qname[1].rsplit("-", 1)[1]
        if kind == "number":
            return "number" if child.getAttribute("numformat") else "none"
        return "bullet"

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

    def walk(el, lists: tuple[str | None, ...]) -> None:
        """`lists`: the style names of the text:list elements `el` is inside, outermost first (a nested list
        without a style of its own continues its parent's)."""
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
                marker = None
                if lists:
                    marker = list_marker(lists[-1] or paragraph_list_style(style), len(lists))
                doc.paragraphs.append(Paragraph(teletype.extractText(node), style,
                                                bool(parts) and all(b for _, b in parts), bool(lists),
                                                int(level) if level else None, marker))
            elif node.qname == (TABLENS, "table"):
                doc.table_at.append(len(doc.paragraphs))
                doc.tables.append([[norm(teletype.extractText(c)) for c in row.childNodes
                                    if c.qname == (TABLENS, "table-cell")
                                    for _ in range(min(int(c.getAttribute("numbercolumnsrepeated") or 1), 64))]
                                   for row in table_rows(node)])
            elif node.qname == (TEXTNS, "list"):
                walk(node, lists + (node.getAttribute("stylename") or (lists[-1] if lists else None),))
            else:
                walk(node, lists)

    walk(odf.text, ())
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

    def num_pr(ppr) -> tuple[str | None, str | None] | None:
        """(numId, ilvl) of the w:numPr in `ppr` (a w:pPr), None when it has none. numId "0" is Word's (and
        Writer's) way of saying "no list" over a list style."""
        num = ppr.find(qn("w:numPr")) if ppr is not None else None
        if num is None:
            return None
        num_id, ilvl = num.find(qn("w:numId")), num.find(qn("w:ilvl"))
        return (num_id.get(qn("w:val")) if num_id is not None else None,
                ilvl.get(qn("w:val")) if ilvl is not None else None)

    def style_num(style) -> tuple[str | None, str | None] | None:
        for s in style_chain(style):
            said = num_pr(s.element.find(qn("w:pPr")))
            if said is not None:
                return said
        return None

    try:
        numbering = d.part.numbering_part.element
    except (KeyError, NotImplementedError, AttributeError):
        numbering = None

    def num_marker(num_id: str | None, ilvl: str | None) -> str | None:
        """"bullet", "number" or "none" for list `num_id` at level `ilvl` (numbering.xml), None when unknown."""
        if numbering is None or num_id is None:
            return None
        level = ilvl or "0"
        num = next((n for n in numbering.findall(qn("w:num")) if n.get(qn("w:numId")) == num_id), None)
        if num is None:
            return None
        lvl = next((o.find(qn("w:lvl")) for o in num.findall(qn("w:lvlOverride"))
                    if o.get(qn("w:ilvl")) == level and o.find(qn("w:lvl")) is not None), None)
        if lvl is None:
            ref = num.find(qn("w:abstractNumId"))
            abstract = next((a for a in numbering.findall(qn("w:abstractNum"))
                             if ref is not None and a.get(qn("w:abstractNumId")) == ref.get(qn("w:val"))), None)
            lvl = next((x for x in abstract.findall(qn("w:lvl")) if x.get(qn("w:ilvl")) == level), None) \
                if abstract is not None else None
        fmt = lvl.find(qn("w:numFmt")) if lvl is not None else None
        if fmt is None:
            return None
        value = fmt.get(qn("w:val"))
        return "bullet" if value == "bullet" else "none" if value == "none" else "number"

    def run_bold(run, base: bool) -> bool:
        if run.bold is not None:  # direct formatting
            return bool(run.bold)
        if run.style is not None and run.style.name != "Default Paragraph Font":  # a character style, e.g. Strong
            own = next((s.font.bold for s in style_chain(run.style) if s.font.bold is not None), None)
            if own is not None:
                return bool(own)
        return base

    from docx.table import Table as DocxTable

    doc = Document("docx")
    for block in d.iter_inner_content():
        if isinstance(block, DocxTable):
            doc.table_at.append(len(doc.paragraphs))
            doc.tables.append([[norm(c.text) for c in row.cells] for row in block.rows])
            continue
        p = block
        base = style_bold(p.style) if p.style is not None else False
        runs = [(r.text, run_bold(r, base)) for r in p.runs if r.text.strip()]
        num = num_pr(p._p.pPr)
        if num is None and p.style is not None:
            num = style_num(p.style)
        elif num is not None and num[1] is None and p.style is not None:  # the level may come from the style
            num = (num[0], (style_num(p.style) or (None, None))[1])
        listed = num is not None and num[0] != "0"
        name = p.style.name if p.style is not None else ""
        m = re.match(r"Heading (\d)", name)
        doc.paragraphs.append(Paragraph(p.text, name, bool(runs) and all(b for _, b in runs), listed,
                                        int(m.group(1)) if m else None, num_marker(*num) if listed else None))
    return doc


def _with_document(state: FinalState, path: str, platform: str | None, want: str, check) -> Verdict:
    return judge_file(state, path, want, read_document, check, platform)


def _baseline_document(state: FinalState, path: str, platform: str | None) -> Document | None:
    """The document `path` as it was right after set-up (the template lists it under `baseline`), or None when
    that is not known (e.g. an upstream subtask of a composed task made it)."""
    data = state.baseline(path, platform)
    if data is None:
        return None
    try:
        return read_document(data)
    except Exception:
        return None


def _first_failure(*checks) -> Verdict:
    """The first failed verdict of `checks` (functions returning a Verdict or None), else the last verdict."""
    last = None
    for check in checks:
        verdict = check()
        if verdict is not None and not verdict.passed:
            return verdict
        last = verdict or last
    return last


def diff_lines(got: list[str], want: list[str]) -> str:
    """How the paragraphs `got` differ from `want` (both whitespace-normalised), for a reason."""
    added = [line for line in got if line not in want]
    removed = [line for line in want if line not in got]
    parts = ([f"added {added[:3]!r}"] if added else []) + ([f"missing {removed[:3]!r}"] if removed else [])
    if not parts:
        parts = [f"{len(got)} paragraphs instead of {len(want)}" if len(got) != len(want) else
                 "the paragraphs in another order"]
    return "; ".join(parts)


def check_same_lines(doc: Document, want: list[str], what: str = "the rest of the text unchanged") -> Verdict:
    """The document's non-empty body paragraphs are exactly `want`, in order (nothing added, removed or
    changed)."""
    got = doc.lines
    want = [norm(w) for w in want if norm(w)]
    return Verdict.check(got == want, f"{what} ({len(want)} paragraphs as set up)",
                         "them" if got == want else diff_lines(got, want))


def _unchanged(state: FinalState, path: str, platform: str | None, doc: Document,
               edit=lambda line: line, what: str = "the rest of the text unchanged") -> Verdict | None:
    """A failed verdict when the paragraphs of `doc` are not those of `path`'s baseline (each passed through
    `edit`, the change the task asks for); None when they are, or when no baseline is known."""
    original = _baseline_document(state, path, platform)
    if original is None:
        return None
    verdict = check_same_lines(doc, [edit(line) for line in original.lines], what)
    return verdict if not verdict.passed else None


# -- checks --------------------------------------------------------------------------------------------------
def check_lines_listed(doc: Document, lines: list[str], marker: str | None = None) -> Verdict:
    """Every line of `lines` is a paragraph of the document that is an item of a list — of a bulleted one when
    `marker` is "bullet", a numbered one when "number" (a list whose label cannot be told passes)."""
    missing = [line for line in lines if doc.find(line) is None]
    unlisted = [line for line in lines if doc.find(line) is not None and not doc.find(line).listed]
    other = [(line, doc.find(line).marker) for line in lines if doc.find(line) is not None and doc.find(line).listed
             and marker and doc.find(line).marker not in (None, marker)]
    found = " ".join(x for x in (f"missing {missing!r}" if missing else "",
                                 f"not in a list: {unlisted!r}" if unlisted else "",
                                 f"labelled {other[0][1]!r} instead of {marker!r}: {[o for o, _ in other]!r}"
                                 if other else "") if x)
    label = {"bullet": "bulleted", "number": "numbered"}.get(marker or "", marker)
    want = f"all {len(lines)} lines as list items" + (f" of a {label} list" if marker else "")
    return Verdict.check(not missing and not unlisted and not other, want, found or "all listed")


@evaluator("document_lines_listed")
def document_lines_listed(state: FinalState, path: str, lines: list[str], kind: str | None = None,
                          marker: str | None = None, platform: str | None = None) -> Verdict:
    """Every line of `lines` is a list item of the document (of `kind`: odt or docx, when given; of a list
    labelled `marker`, "bullet" or "number", when given). When the template lists `path` under `baseline`, the
    document's paragraphs must be the original ones (nothing added, removed or reworded); without a baseline (a
    document an upstream subtask made) only the lines are checked."""
    def check(doc: Document) -> Verdict:
        return _first_failure(lambda: _of_kind(doc, kind), lambda: check_lines_listed(doc, lines, marker),
                              lambda: _unchanged(state, path, platform, doc))
    return _with_document(state, path, platform, f"{path} with its lines in a list", check)


def _of_kind(doc: Document, kind: str | None) -> Verdict | None:
    """A failed verdict when the document is not of `kind` (e.g. saved as .odt under a .docx name); `kind` may
    be given as an extension (".odt")."""
    kind = str(kind or "").lstrip(".").lower()
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
    """The paragraph `text` is bold and only it, of `others` (in a document of `kind`, when given). With a
    baseline of `path`, the document's paragraphs must be the original ones (no line added, removed or
    reworded); without one, `text` and `others` must be there."""
    def check(doc: Document) -> Verdict:
        return _first_failure(lambda: _of_kind(doc, kind), lambda: check_paragraph_bold(doc, text, others),
                              lambda: _unchanged(state, path, platform, doc))
    return _with_document(state, path, platform, f"{text!r} in bold", check)


def check_document_text(doc: Document, contains: list[str], absent: list[str]) -> Verdict:
    body = norm(doc.text)
    lacking = [t for t in contains if norm(t) not in body]
    present = [t for t in absent if norm(t) in body]
    want = " and ".join(x for x in (f"text with {contains!r}" if contains else "",
                                    f"without {absent!r}" if absent else "") if x)
    found = "; ".join(x for x in (f"lacking {lacking!r}" if lacking else "",
                                  f"still has {present!r}" if present else "") if x)
    return Verdict.check(not lacking and not present, want, found or f"it ({len(body)} characters)")


def replaced(line: str, replace: dict[str, str] | list[list[str]]) -> str:
    """`line` with each `old` replaced by its `new` ({old: new} or [[old, new], ...])."""
    for old, new in (replace.items() if isinstance(replace, dict) else replace):
        line = line.replace(norm(old), norm(new))
    return line


@evaluator("document_text_has")
def document_text_has(state: FinalState, path: str, contains: list[str] | None = None,
                      absent: list[str] | None = None, kind: str | None = None,
                      replace: dict[str, str] | list[list[str]] | None = None,
                      platform: str | None = None) -> Verdict:
    """The document (.odt/.docx, of `kind` when given) contains every text of `contains` and none of `absent`.
    With `replace` ({old: new}, or [[old, new], ...] when the words are slot values) and a baseline of `path`,
    its paragraphs must be exactly the original ones with every `old` replaced by `new` (nothing else added,
    dropped or changed); without a baseline only `contains` and `absent` are checked."""
    def check(doc: Document) -> Verdict:
        return _first_failure(lambda: _of_kind(doc, kind),
                              lambda: check_document_text(doc, contains or [], absent or []),
                              lambda: _unchanged(state, path, platform, doc, lambda line: replaced(line, replace),
                                                 "the original text with only the replacements made")
                              if replace else None)
    return _with_document(state, path, platform, f"{path} with the right text", check)


def check_table(doc: Document, rows: int, cols: int, header: list[str] | None = None,
                at_end: bool = False) -> Verdict:
    """The document has a table of `rows` × `cols` (all its rows, a header row included) whose first row reads
    `header` (when given; whitespace normalised), placed after every non-empty paragraph of the body when
    `at_end`. Any of the document's tables may be the one."""
    rows, cols = int(rows), int(cols)
    want = f"a {rows}×{cols} table" + (f" headed {header!r}" if header else "") + (" at the end" if at_end else "")
    shaped = [i for i, t in enumerate(doc.tables) if len(t) == rows and all(len(r) == cols for r in t)]
    if not shaped:
        shapes = [f"{len(t)}×{max((len(r) for r in t), default=0)}" for t in doc.tables]
        return Verdict.check(False, want, f"tables {', '.join(shapes)}" if shapes else "no table")
    headed = [i for i in shaped if header is None or doc.tables[i][0] == [norm(h) for h in header]]
    if not headed:
        return Verdict.check(False, want, " / ".join(f"headed {doc.tables[i][0]!r}" for i in shaped))
    if at_end:
        after = {i: [norm(p.text) for p in doc.paragraphs[doc.table_at[i]:] if norm(p.text)]
                 for i in headed if i < len(doc.table_at)}
        if after and not any(not rest for rest in after.values()):
            return Verdict.check(False, want, f"text after it: {next(iter(after.values()))[:2]!r}")
    return Verdict.check(True, want, f"{len(headed)} such table(s)")


@evaluator("document_has_table")
def document_has_table(state: FinalState, path: str, rows: int, cols: int, header: list[str] | None = None,
                       kind: str | None = None, at_end: bool = False, platform: str | None = None) -> Verdict:
    """A `rows`×`cols` table headed `header` (at the end of the document when `at_end`; in a document of
    `kind`, e.g. ".odt", when given). With a baseline of `path`, the document's own paragraphs must be the
    original ones; without one, the text outside the table is not checked."""
    def check(doc: Document) -> Verdict:
        return _first_failure(lambda: _of_kind(doc, kind), lambda: check_table(doc, int(rows), int(cols), header,
                                                                            bool(at_end)),
                              lambda: _unchanged(state, path, platform, doc))
    return _with_document(state, path, platform, f"a {rows}×{cols} table", check)


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
    """`data` is a PDF whose extracted text has every text of `contains` (and `pages` pages, when given). The text
    is compared in compatibility form (NFKC): a PDF writer's typographic ligatures ("ﬁ" in "Certiﬁcate", as Chromium
    prints) and full-width forms read as the letters they stand for."""
    from pypdf import PdfReader
    from pypdf.errors import PdfReadError

    want = f"a PDF with {contains!r}" + (f" on {pages} pages" if pages else "")
    if not data.startswith(b"%PDF"):
        return Verdict.check(False, want, f"no PDF (starts {data[:8]!r})")
    try:
        reader = PdfReader(io.BytesIO(data))
        text = norm(unicodedata.normalize("NFKC", " ".join(page.extract_text() or "" for page in reader.pages)))
    except (PdfReadError, Exception) as exc:
        return Verdict.check(False, want, f"an unreadable PDF ({exc})")
    lacking = [t for t in contains if norm(unicodedata.normalize("NFKC", t)) not in text]
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


def _from_source(state: FinalState, reference: str, platform: str | None, use) -> Verdict:
    """`use(lines)` with the paragraphs of the source document `reference`: those it had right after set-up when
    the template lists it under `baseline` — and then `reference` must still hold them (the task reads it, it does
    not change it) — else those of the file as found (a source an upstream subtask made has no baseline)."""
    original = _baseline_document(state, reference, platform)
    if original is None:
        return judge_file(state, reference, f"the text of {reference}", paragraph_lines, use, platform)
    verdict = use(original.lines)
    if not verdict.passed:
        return verdict
    kept = _with_document(state, reference, platform, f"the original {reference} unchanged",
                          lambda doc: check_same_lines(doc, original.lines, f"the original {reference} unchanged"))
    return verdict if kept.passed else kept


@evaluator("document_same_text")
def document_same_text(state: FinalState, path: str, reference: str, kind: str | None = None,
                       platform: str | None = None) -> Verdict:
    """`path` is a document (of `kind`, when given) with the same non-empty paragraphs as `reference` — as it was
    set up when it has a baseline (and then `reference` itself must be unchanged), else as found."""
    def check(doc: Document, source: list[str]) -> Verdict:
        wrong = _of_kind(doc, kind)
        if wrong:
            return wrong
        got = doc.lines
        return Verdict.check(got == source, f"the {len(source)} paragraphs of {reference}",
                             f"{len(got)} paragraphs" + ("" if got == source else f": {diff_lines(got, source)}"))
    return _from_source(state, reference, platform,
                        lambda source: _with_document(state, path, platform, f"a copy of {reference}",
                                                      lambda doc: check(doc, source)))


@evaluator("pdf_matches_document")
def pdf_matches_document(state: FinalState, path: str, document: str, platform: str | None = None) -> Verdict:
    """`path` is a PDF showing the text of every paragraph of `document` (an .odt/.docx) — as it was set up when
    it has a baseline (and then `document` itself must be unchanged), else as found."""
    return _from_source(state, document, platform,
                        lambda source: pdf_has_text(state, path, source, platform=platform))
