"""The pure checks behind the office evaluators (documents, spreadsheets, presentations, PDFs): each passes on a
file as a solved task leaves it and fails, naming what it expected and found, on the file as set up. The files
are made with the project's generators and edited with the same libraries a person's office suite output is
read with (no containers)."""

from __future__ import annotations

import io
from pathlib import Path

import docx
import pytest
from openpyxl import load_workbook
from pptx import Presentation

from jarvis_pytest.evaluators.documents import (NotADocument, check_document_text, check_heading,
                                                check_lines_listed, check_paragraph_bold, check_pdf_text,
                                                check_table, read_document)
from jarvis_pytest.evaluators.presentations import check_notes, check_slide_title, check_titles, read_presentation
from jarvis_pytest.evaluators.spreadsheets import (cell_at, check_cell_aggregate, check_cell_equals,
                                                   check_rows_without, check_same_data, check_sheet_names,
                                                   check_sorted_from, read_workbook)
from jarvis_pytest.generators import generate

LINES = ["Book a room", "Send the invitations", "Order coffee"]


def docx_edited(edit) -> bytes:
    d = docx.Document(io.BytesIO(generate("docx_document", {"paragraphs": LINES})))
    edit(d)
    buf = io.BytesIO()
    d.save(buf)
    return buf.getvalue()


def test_documents_read_alike_in_both_formats():
    for name in ("docx_document", "odt_document"):
        doc = read_document(generate(name, {"paragraphs": LINES}))
        assert [p.text for p in doc.paragraphs] == LINES and not any(p.bold or p.listed for p in doc.paragraphs)
        assert check_document_text(doc, ["Order coffee"], ["Monday"]).passed
        verdict = check_document_text(doc, ["Order tea"], ["coffee"])
        assert not verdict.passed and "lacking ['Order tea']" in verdict.reason and "still has" in verdict.reason
    with pytest.raises(NotADocument):
        read_document(b"plain text")


def test_bullets_bold_headings_and_tables_in_docx():
    fresh = read_document(generate("docx_document", {"paragraphs": LINES}))
    assert not check_lines_listed(fresh, LINES).passed
    assert not check_paragraph_bold(fresh, LINES[0]).passed
    assert not check_table(fresh, 2, 2).passed and not check_heading(fresh, LINES[0], 1).passed

    def solve(d):
        for p in d.paragraphs:
            p.style = d.styles["List Bullet"]
        d.paragraphs[0].runs[0].bold = True
        t = d.add_table(rows=2, cols=2)
        t.cell(0, 0).text, t.cell(0, 1).text = "Name", "Role"
        d.add_heading("Summary", level=1)
    solved = read_document(docx_edited(solve))
    assert check_lines_listed(solved, LINES).passed
    assert check_paragraph_bold(solved, LINES[0], LINES[1:]).passed and not check_paragraph_bold(solved, LINES[1]).passed
    assert not check_paragraph_bold(solved, LINES[0], ["Gone"]).passed
    assert check_table(solved, 2, 2, ["Name", "Role"]).passed
    assert not check_table(solved, 2, 2, ["Role", "Name"]).passed
    assert check_heading(solved, "Summary", 1).passed


OFFICE = Path(__file__).parent / "data" / "office"  # written by LibreOffice 7 on the device from sample.html


def test_files_libreoffice_wrote():
    for name in ("libreoffice_sample.odt", "libreoffice_sample.docx"):
        doc = read_document((OFFICE / name).read_bytes())
        assert check_heading(doc, "Title here", 1).passed, name
        assert check_lines_listed(doc, ["one", "two"]).passed, name
        assert check_paragraph_bold(doc, "Bold para").passed and not check_paragraph_bold(doc, "one").passed, name
        assert check_table(doc, 2, 2, ["a", "b"]).passed, name
    pdf = (OFFICE / "libreoffice_export.pdf").read_bytes()
    assert check_pdf_text(pdf, ["Title here", "Bold para"], pages=1).passed
    verdict = check_pdf_text(pdf, ["Missing words"])
    assert not verdict.passed and "lacking ['Missing words']" in verdict.reason
    verdict = check_pdf_text(b"not a pdf", ["x"])
    assert not verdict.passed and "no PDF" in verdict.reason


def sheet(fmt: str, **kw) -> bytes:
    return generate("people_table", {"seed": 5, "rows": 10, "format": fmt, **kw})


def test_spreadsheets_read_alike_in_three_formats():
    rows = {fmt: read_workbook(sheet(fmt))[1] for fmt in ("xlsx", "ods", "csv")}
    first = [next(iter(s.values())) for s in rows.values()]
    assert first[0] == first[1] == first[2] and first[0][0] == ["Name", "Team", "Score", "Status"]
    assert check_same_data("xlsx", first[0], "xlsx", first[2]).passed
    assert not check_same_data("csv", first[2], "xlsx", first[2]).passed
    assert not check_same_data("xlsx", first[0][:-1], None, first[2]).passed


def test_sorting_totals_names_and_deleted_rows():
    kind, sheets = read_workbook(sheet("xlsx", flagged="cancelled"))
    rows = sheets["Sheet1"]
    by_score = [rows[0]] + sorted(rows[1:], key=lambda r: r[2], reverse=True)
    assert check_sorted_from(by_score, rows, "Score", True).passed
    assert not check_sorted_from(rows, rows, "Score", True).passed  # seeded rows are not in order
    shuffled_column = [rows[0]] + [r[:2] + [s] + r[3:] for r, s in zip(rows[1:], sorted(r[2] for r in rows[1:]))]
    assert not check_sorted_from(shuffled_column, rows, "Score", False).passed  # rows must stay together

    assert not check_cell_aggregate(rows, "C12", "SUM", "C2:C11").passed
    wb = load_workbook(io.BytesIO(sheet("xlsx")))
    wb.active["C12"] = sum(wb.active[f"C{i}"].value for i in range(2, 12))
    buf = io.BytesIO()
    wb.save(buf)
    totals = read_workbook(buf.getvalue())[1]["Sheet1"]
    assert check_cell_aggregate(totals, "C12", "SUM", "C2:C11").passed
    assert not check_cell_aggregate(totals, "C12", "AVERAGE", "C2:C11").passed
    assert cell_at(totals, "A1") == "Name" and check_cell_equals(totals, "A1", "Name").passed

    assert check_sheet_names({"Team List": rows}, "Team List", "Sheet1", min_rows=11).passed
    assert not check_sheet_names({"Sheet1": rows}, "Team List", "Sheet1").passed
    assert not check_sheet_names({"Team List": rows[:1]}, "Team List", "Sheet1", min_rows=11).passed  # data lost

    assert not check_rows_without(rows, "Status", "cancelled", 7).passed
    kept = [r for r in rows if r[3] != "cancelled"]
    assert check_rows_without(kept, "Status", "cancelled", 7).passed
    assert not check_rows_without(kept[:-1], "Status", "cancelled", 7).passed


def test_presentations_titles_and_notes():
    data = generate("pptx_presentation", {"titles": ["Intro", "Plan", "Budget"]})
    kind, slides = read_presentation(data)
    assert kind == "pptx" and [s.title for s in slides] == ["Intro", "Plan", "Budget"]
    assert check_titles(kind, slides, ["Intro", "Plan", "Budget"]).passed
    assert not check_titles(kind, slides, ["Intro", "Budget"]).passed
    assert not check_titles(kind, slides, ["Intro", "Plan", "Budget"], "odp").passed
    assert not check_slide_title(kind, slides, 2, "Roadmap", 3).passed
    assert not check_notes(slides, 1, "Pause here").passed
    prs = Presentation(io.BytesIO(data))
    prs.slides[1].shapes.title.text = "Roadmap"
    prs.slides[0].notes_slide.notes_text_frame.text = "Pause here for questions"
    buf = io.BytesIO()
    prs.save(buf)
    kind, slides = read_presentation(buf.getvalue())
    assert check_slide_title(kind, slides, 2, "Roadmap", 3).passed
    assert check_notes(slides, 1, "Pause here").passed and not check_notes(slides, 4, "x").passed


# --- the three cheap Calc states, through the templates themselves ----------------------------------------

LIBRARY = Path(__file__).resolve().parents[1] / "tasks" / "ubuntu"


def instance(name: str, seed: int):
    """Seeded instance `seed` of template `name`: its subtask, and the file its set-up uploads, made on the host
    from the same generator and arguments."""
    from jarvis_pytest.tasks.instances import atomic_task
    from jarvis_pytest.tasks.library import read_template_file

    [template] = read_template_file(LIBRARY / f"{name}.json")
    sub = atomic_task(template, seed).formatted_subtasks[0]
    upload = next(s for s in sub.config if getattr(s, "generator", None))
    assert upload.path in sub.baseline, f"{name}: the set-up file {upload.path} is not under baseline"
    return sub, upload.path, generate(upload.generator, dict(upload.args))


def judge(sub, files: dict[str, bytes], baselines: dict[str, bytes]) -> list:
    from file_state import state_with
    from jarvis_pytest.evaluators import get_evaluator

    state = state_with(files, baselines=baselines)
    return [get_evaluator(spec.func)(state, **spec.args) for spec in sub.evaluate]


def ods_of(rows: list[list[object]]) -> bytes:
    from jarvis_pytest.generators.spreadsheets import ods_bytes
    return ods_bytes(rows[0], rows[1:])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_calc_sum_total_csv_over_the_ods(seed):
    sub, path, fresh = instance("calc_sum_total", seed)
    cell = sub.input["cell"].value
    rows = next(iter(read_workbook(fresh)[1].values()))
    r, c = int(cell[1:]) - 1, ord(cell[0]) - 65
    solved = [list(x) + [None] * (c + 1 - len(x)) for x in rows] + [[None] * (c + 1) for _ in range(r + 1 - len(rows))]
    solved[r][c] = sum(x[2] for x in rows[1:])
    assert all(v.passed for v in judge(sub, {path: ods_of(solved)}, {path: fresh}))
    grid = [[""] * 6 for _ in range(max(r + 1, 3))]
    grid[0][:3], grid[1][2], grid[r][c] = ["name", "team", "score"], "1", "1"
    artefact = ("\n".join(",".join(x) for x in grid) + "\n").encode()
    [verdict] = judge(sub, {path: artefact}, {path: fresh})
    assert not verdict.passed and verdict.reason == "expected a .ods spreadsheet, found a .csv file"


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_calc_delete_rows_header_and_seven_junk_rows(seed):
    sub, path, fresh = instance("calc_delete_rows", seed)
    status = sub.input["status"].value
    rows = next(iter(read_workbook(fresh)[1].values()))
    kept = [r for r in rows if r[3] != status]
    assert all(v.passed for v in judge(sub, {path: ods_of(kept)}, {path: fresh}))
    junk = ods_of(rows[:1] + [[f"x{i}", "North", i, "open"] for i in range(7)])
    [verdict] = judge(sub, {path: junk}, {path: fresh})
    assert not verdict.passed and "expected the other 7 rows of the original, in order, no gaps" in verdict.reason


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_calc_sort_rows_header_only_csv_copied_over_the_original(seed):
    from jarvis_pytest.evaluators.spreadsheets import _sort_key, descending_order

    sub, path, fresh = instance("calc_sort_rows", seed)
    out, column = sub.output["sorted"].value, sub.input["column"].value
    rows = next(iter(read_workbook(fresh)[1].values()))
    i = rows[0].index(column)
    ordered = [rows[0]] + sorted(rows[1:], key=lambda r: _sort_key(r[i]),
                                 reverse=descending_order(sub.input["order"].value))
    good = ("\n".join(",".join(f"{v:g}" if isinstance(v, float) else str(v) for v in r) for r in ordered)
            + "\n").encode()
    assert all(v.passed for v in judge(sub, {path: fresh, out: good}, {path: fresh}))
    header = b"Name,Team,Score,Status\n"
    [verdict] = judge(sub, {path: header, out: header}, {path: fresh})
    assert not verdict.passed and "found 0 data rows that are not the original's 10" in verdict.reason
