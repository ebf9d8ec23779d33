"""The spreadsheet checks (evaluators/spreadsheets.py) and generator (generators/spreadsheets.py), without
containers: each check passes on a spreadsheet as a solved Calc task leaves it and fails, naming what it expected
and found, on the spreadsheet as set up. .xlsx files come from the generator and openpyxl, with formulas patched in
the way LibreOffice writes them (<f> with its cached <v>); .ods files are built with odfpy in the shape Calc writes
them (table:formula with a cached office:value, the unused rest of the sheet as rows and cells repeated a million
times, comments inside cells)."""

from __future__ import annotations

import io
import re
import time
import zipfile

import pytest
from openpyxl import load_workbook

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.evaluators import get_evaluator
from jarvis_pytest.evaluators.spreadsheets import (NotASpreadsheet, cell_at, check_cell_aggregate,
                                                   check_cell_equals, check_rows_without, check_same_data,
                                                   check_sheet_names, check_sorted_from, descending_order,
                                                   read_workbook, spreadsheet_kind)
from file_state import state_with
from jarvis_pytest.generators import generate
from jarvis_pytest.generators.spreadsheets import HEADER, people_rows

SEED = 306


# --- files -------------------------------------------------------------------------------------------------------

def table(fmt: str, **kw) -> bytes:
    return generate("people_table", {"seed": SEED, "rows": 10, "format": fmt, **kw})


def first_rows(data: bytes) -> list[list[object]]:
    return next(iter(read_workbook(data)[1].values()))


def xlsx_edited(edit, data: bytes | None = None) -> bytes:
    wb = load_workbook(io.BytesIO(data or table("xlsx")))
    edit(wb)
    buf = io.BytesIO()
    wb.save(buf)
    return buf.getvalue()


def xlsx_with_formula(ref: str, formula: str, cached: float | None, data: bytes | None = None) -> bytes:
    """The generated workbook with `formula` in `ref` as LibreOffice saves it: <f> plus the cached <v> (openpyxl
    itself never writes a cached value; `cached=None` leaves it out, as a file no spreadsheet app computed)."""
    data = data or table("xlsx")
    src = zipfile.ZipFile(io.BytesIO(data))
    out = io.BytesIO()
    row = int(re.search(r"\d+", ref).group(0))
    cell = f'<c r="{ref}"><f>{formula}</f>' + (f"<v>{cached:g}</v>" if cached is not None else "") + "</c>"
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as dst:
        for item in src.infolist():
            body = src.read(item.filename)
            if item.filename == "xl/worksheets/sheet1.xml":
                xml = body.decode().replace('<dimension ref="A1:D11"/>', f'<dimension ref="A1:F{max(row, 11)}"/>')
                xml = xml.replace("</sheetData>", f'<row r="{row}">{cell}</row></sheetData>')
                body = xml.encode()
            dst.writestr(item, body)
    return out.getvalue()


def ods_like_calc(rows: list[list[object]], *, formulas: dict[str, tuple[str, float]] | None = None,
                  comment: str | None = None) -> bytes:
    """An .ods in the shape LibreOffice Calc saves: `rows` (numbers as floats, text as strings), formulas
    {"C12": ("of:=SUM([.C2:.C11])", 707.0)} with cached values, a comment on A1, a run of empty rows as one
    repeated row, and the rest of the sheet as repeated empty rows and cells."""
    from odf.office import Annotation
    from odf.opendocument import OpenDocumentSpreadsheet
    from odf.table import Table, TableCell, TableRow
    from odf.text import P

    formulas = dict(formulas or {})
    grid = [list(r) for r in rows]
    for ref, (_, value) in formulas.items():
        r, c = int(ref[1:]) - 1, ord(ref[0]) - 65
        grid += [[] for _ in range(r + 1 - len(grid))]
        grid[r] += [None] * (c + 1 - len(grid[r]))
        grid[r][c] = (ref, value)

    doc = OpenDocumentSpreadsheet()
    sheet = Table(name="Sheet1")
    i = 0
    while i < len(grid):
        values = grid[i]
        if not any(v is not None for v in values):
            run = next((k for k in range(i, len(grid)) if any(v is not None for v in grid[k])), len(grid)) - i
            empty = TableRow(numberrowsrepeated=run)
            empty.addElement(TableCell(numbercolumnsrepeated=16384))
            sheet.addElement(empty)
            i += run
            continue
        tr = TableRow()
        for j, v in enumerate(values):
            if v is None:
                cell = TableCell()
            elif isinstance(v, tuple):
                formula, value = formulas[v[0]]
                cell = TableCell(formula=formula, valuetype="float", value=value)
                cell.addElement(P(text=f"{value:g}"))
            elif isinstance(v, float):
                cell = TableCell(valuetype="float", value=v)
                cell.addElement(P(text=f"{v:g}"))
            else:
                cell = TableCell(valuetype="string")
                if comment and i == 0 and j == 0:
                    note = Annotation()
                    note.addElement(P(text=comment))
                    cell.addElement(note)
                cell.addElement(P(text=str(v)))
            tr.addElement(cell)
        tr.addElement(TableCell(numbercolumnsrepeated=16384 - len(values)))
        sheet.addElement(tr)
        i += 1
    rest = TableRow(numberrowsrepeated=1048576 - len(grid))
    rest.addElement(TableCell(numbercolumnsrepeated=16384))
    sheet.addElement(rest)
    doc.spreadsheet.addElement(sheet)
    buf = io.BytesIO()
    doc.write(buf)
    return buf.getvalue()



def sorted_rows(rows, column: str, descending: bool):
    i = rows[0].index(column)
    return [rows[0]] + sorted(rows[1:], key=lambda r: r[i] if isinstance(r[i], float) else str(r[i]).lower(),
                              reverse=descending)


def csv_of(rows) -> bytes:
    return "\n".join(",".join("" if v is None else f"{v:g}" if isinstance(v, float) else v for v in r)
                     for r in rows).encode() + b"\n"


# --- the generator -------------------------------------------------------------------------------------------------

def test_people_table_is_seeded_and_reads_alike_in_three_formats():
    rows = {fmt: first_rows(table(fmt)) for fmt in ("xlsx", "ods", "csv")}
    assert rows["xlsx"] == rows["ods"] == rows["csv"]
    assert rows["xlsx"][0] == HEADER and len(rows["xlsx"]) == 11
    assert all(isinstance(r[2], float) and 40 <= r[2] <= 99 for r in rows["xlsx"][1:])
    packages = {fmt: table(fmt) for fmt in ("xlsx", "ods")}
    time.sleep(2.1)  # past the 2-second resolution of a zip member's time: a stamp of the clock would show
    assert {fmt: table(fmt) for fmt in ("xlsx", "ods")} == packages  # deterministic bytes
    assert people_rows(SEED, 10) == people_rows(SEED, 10) != people_rows(SEED + 1, 10)
    assert [spreadsheet_kind(table(fmt)) for fmt in ("xlsx", "ods", "csv")] == ["xlsx", "ods", "csv"]


def test_people_table_flags_every_third_row_and_names_its_sheet():
    rows = first_rows(table("ods", flagged="duplicate"))
    assert [i for i, r in enumerate(rows[1:]) if r[3] == "duplicate"] == [1, 4, 7]
    assert "duplicate" not in [r[3] for r in first_rows(table("ods"))]
    for fmt in ("xlsx", "ods"):
        assert list(read_workbook(table(fmt, sheet="Raw data"))[1]) == ["Raw data"]
    with pytest.raises(ConfigError, match="format"):
        table("numbers")
    with pytest.raises(ConfigError, match="rows"):
        generate("people_table", {"seed": 1, "rows": 40})


# --- reading what LibreOffice writes -------------------------------------------------------------------------------

def test_ods_formulas_gaps_comments_and_the_repeated_rest_of_the_sheet():
    rows = first_rows(table("ods"))
    total = sum(r[2] for r in rows[1:])
    data = ods_like_calc(rows, formulas={"C12": ("of:=SUM([.C2:.C11])", total)}, comment="checked by HR")
    got = first_rows(data)
    assert got[:11] == rows and len(got) == 12  # the million repeated empty rows are not rows
    assert cell_at(got, "C12") == total and cell_at(got, "A1") == "Name"  # the comment is not the cell's text
    # a run of empty rows before data is kept whole, so later cells keep their references
    far = first_rows(ods_like_calc(rows, formulas={"C2000": ("of:=SUM([.C2:.C11])", total)}))
    assert len(far) == 2000 and cell_at(far, "C2000") == total and cell_at(far, "C12") is None


def test_xlsx_formulas_are_read_through_the_value_libreoffice_cached():
    rows = first_rows(table("xlsx"))
    total = sum(r[2] for r in rows[1:])
    assert cell_at(first_rows(xlsx_with_formula("C12", "SUM(C2:C11)", total)), "C12") == total
    assert cell_at(first_rows(xlsx_with_formula("C12", "SUM(C2:C11)", None)), "C12") is None  # never computed


def test_not_a_spreadsheet():
    docx = generate("docx_document", {"paragraphs": ["Hello"]})
    with pytest.raises(NotASpreadsheet, match="docx"):
        read_workbook(docx)
    with pytest.raises(NotASpreadsheet):
        read_workbook(b"\x89PNG\r\n\x1a\n\xff\xfe")
    with pytest.raises(ValueError, match="cell reference"):
        cell_at([], "12C")


# --- the checks ----------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("column", ["Score", "Name", "Team", "Status"])
@pytest.mark.parametrize("descending", [False, True])
def test_sorted_from(column, descending):
    ref = first_rows(table("xlsx"))
    good = sorted_rows(ref, column, descending)
    assert check_sorted_from(good, ref, column, descending).passed
    bad = check_sorted_from(sorted_rows(ref, column, not descending), ref, column, descending)
    assert not bad.passed and f"sorted by {column}" in bad.reason and f"found {column} in the order" in bad.reason


def test_sorted_from_keeps_rows_together_and_the_header_on_top():
    ref = first_rows(table("xlsx"))
    assert not check_sorted_from(ref, ref, "Score", True).passed  # the seeded rows are not in order
    scores = sorted(r[2] for r in ref[1:])
    torn = [ref[0]] + [r[:2] + [s] + r[3:] for r, s in zip(ref[1:], scores)]
    v = check_sorted_from(torn, ref, "Score", False)
    assert not v.passed and "not the original's 10" in v.reason
    good = sorted_rows(ref, "Score", False)
    v = check_sorted_from(good[1:6] + [good[0]] + good[6:], ref, "Score", False)  # header sorted into the data
    assert not v.passed and "found header" in v.reason
    v = check_sorted_from(good[:-1], ref, "Score", False)
    assert not v.passed and "9 data rows" in v.reason
    assert not check_sorted_from(good, ref, "Points", False).passed
    # a text cell among numbers is a finding, not a crash
    odd = [ref[0]] + [r[:2] + ["n/a" if k == 0 else r[2]] + r[3:] for k, r in enumerate(ref[1:])]
    v = check_sorted_from([odd[0]] + odd[2:] + odd[1:2], odd, "Score", True)  # text counts after numbers
    assert not v.passed and "'n/a'" in v.reason
    numbers_first = [odd[0]] + sorted(odd[2:], key=lambda r: r[2]) + odd[1:2]
    assert check_sorted_from(numbers_first, odd, "Score", False).passed


def test_sort_order_words():
    assert [descending_order(w) for w in ("ascending", "increasing", "Descending", "decreasing")] == \
        [False, False, True, True]
    with pytest.raises(ValueError, match="sort order"):
        descending_order("random")


def test_sheet_sorted_from_on_the_device_with_the_kind_asked_for():
    ref = table("xlsx")
    rows = first_rows(ref)
    good_csv = csv_of(sorted_rows(rows, "Score", True))
    state = state_with({"/d/scores.xlsx": ref, "/d/out.csv": good_csv, "/d/raw.csv": csv_of(rows)})
    check = get_evaluator("sheet_sorted_from")
    assert check(state, "/d/out.csv", "/d/scores.xlsx", "Score", "decreasing", kind="csv").passed
    assert not check(state, "/d/out.csv", "/d/scores.xlsx", "Score", "increasing", kind="csv").passed
    assert not check(state, "/d/raw.csv", "/d/scores.xlsx", "Score", "decreasing", kind="csv").passed
    v = check(state, "/d/out.csv", "/d/scores.xlsx", "Score", "descending", kind="xlsx")
    assert not v.passed and "expected a .xlsx spreadsheet, found a .csv file" in v.reason
    v = check(state, "/d/none.csv", "/d/scores.xlsx", "Score", "descending", kind="csv")
    assert not v.passed and "no file at /d/none.csv" in v.reason


@pytest.mark.parametrize("fmt", ["xlsx", "ods"])
def test_cell_aggregate_typed_in_or_a_formula(fmt):
    rows = first_rows(table(fmt))
    scores = [r[2] for r in rows[1:]]
    total, mean = sum(scores), sum(scores) / len(scores)
    v = check_cell_aggregate(rows, "C12", "SUM", "C2:C11")
    assert not v.passed and v.reason == f"expected C12 = SUM(C2:C11) = {total:g} (within 0.005), found C12 = None"
    if fmt == "xlsx":
        typed = first_rows(xlsx_edited(lambda wb: wb.active.__setitem__("E2", total)))
        formula = first_rows(xlsx_with_formula("F12", "SUM(C2:C11)", total))
    else:
        typed = first_rows(ods_like_calc(rows + [[None, None, None, None, total]]))
        formula = first_rows(ods_like_calc(rows, formulas={"F12": ("of:=SUM([.C2:.C11])", total)}))
    assert check_cell_aggregate(typed, "E12" if fmt == "ods" else "E2", "SUM", "C2:C11").passed
    assert check_cell_aggregate(formula, "F12", "SUM", "C2:C11").passed
    assert not check_cell_aggregate(formula, "F12", "AVERAGE", "C2:C11").passed
    rounded = first_rows(xlsx_edited(lambda wb: wb.active.__setitem__("F2", round(mean + 0.004, 2))))
    assert check_cell_aggregate(rounded, "F2", "average", "C2:C11").passed
    off = first_rows(xlsx_edited(lambda wb: wb.active.__setitem__("F2", mean + 0.01)))
    assert not check_cell_aggregate(off, "F2", "AVERAGE", "C2:C11").passed
    text = first_rows(xlsx_edited(lambda wb: wb.active.__setitem__("F2", "=AVERAGE(C2:C11)")))
    assert not check_cell_aggregate(text, "F2", "AVERAGE", "C2:C11").passed  # a formula never computed
    with pytest.raises(ValueError, match="one-column range"):
        check_cell_aggregate(rows, "F2", "MEDIAN", "C2:C11")
    with pytest.raises(ValueError, match="one-column range"):
        check_cell_aggregate(rows, "F2", "SUM", "C2:D11")
    assert not check_cell_aggregate(rows, "F2", "SUM", "E2:E11").passed  # no numbers there


def test_cell_equals():
    rows = first_rows(xlsx_edited(lambda wb: (wb.active.__setitem__("F1", "  Mean   score "),
                                              wb.active.__setitem__("F3", 12))))
    assert check_cell_equals(rows, "F1", "Mean score").passed
    v = check_cell_equals(rows, "F1", "Average")
    assert not v.passed and v.reason == "expected F1 = 'Average', found F1 = 'Mean   score'"  # as typed
    assert check_cell_equals(rows, "F3", "12").passed and check_cell_equals(rows, "F3", 12.0).passed
    assert not check_cell_equals(rows, "F3", 13).passed
    assert not check_cell_equals(first_rows(table("xlsx")), "F1", "Mean score").passed


def test_sheet_names():
    sheets = read_workbook(table("xlsx", sheet="Export"))[1]
    renamed = {"Team List": sheets["Export"]}
    assert check_sheet_names(renamed, "Team List", "Export", min_rows=11).passed
    v = check_sheet_names(sheets, "Team List", "Export", min_rows=11)
    assert not v.passed and v.reason == ("expected a sheet named 'Team List' with its 11 rows and none named "
                                         "'Export', found sheets ['Export']")
    assert not check_sheet_names({"Team List": [], "Export": sheets["Export"]}, "Team List", "Export").passed
    v = check_sheet_names({"Team List": sheets["Export"][:1]}, "Team List", "Export", min_rows=11)
    assert not v.passed and "1 rows in 'Team List'" in v.reason  # the data went missing


@pytest.mark.parametrize("fmt", ["xlsx", "ods"])
def test_rows_without(fmt):
    rows = first_rows(table(fmt, flagged="cancelled"))
    v = check_rows_without(rows, "Status", "cancelled", 7)
    assert not v.passed and v.reason == "expected 7 data rows, none with Status = 'cancelled', found 10 rows, 3 with it"
    kept = [r for r in rows if r[3] != "cancelled"]
    assert check_rows_without(first_rows(ods_like_calc(kept)), "Status", "cancelled", 7).passed
    blanked = [r if r[3] != "cancelled" else [None] * 4 for r in rows]  # contents cleared, rows left: still 7
    assert check_rows_without(blanked, "Status", "cancelled", 7).passed
    v = check_rows_without(kept[:-1], "Status", "cancelled", 7)
    assert not v.passed and "found 6 rows, 0 with it" in v.reason  # one row too many deleted
    assert not check_rows_without([["Name", "Team"]], "Status", "cancelled", 0).passed


def test_same_data():
    ref = first_rows(table("csv"))
    assert check_same_data("xlsx", first_rows(table("xlsx")), "xlsx", ref).passed
    v = check_same_data("ods", first_rows(table("ods")), "xlsx", ref)
    assert not v.passed and v.reason == "expected a .xlsx spreadsheet, found a .ods file"
    one_col = [[",".join("" if x is None else f"{x:g}" if isinstance(x, float) else x for x in r)] for r in ref]
    v = check_same_data("xlsx", one_col, "xlsx", ref)  # the CSV read without splitting at commas
    assert not v.passed and v.reason.startswith("expected the 11 rows of the original, found row 1:")
    v = check_same_data("xlsx", ref[:-1], None, ref)
    assert not v.passed and "10 rows instead of 11" in v.reason


# --- near misses: expectations from the sheet as set up (the baseline), the rest of it unchanged -------------------

def with_baseline(files: dict[str, bytes], baselines: dict[str, bytes]):
    """A device holding `files`, whose `baselines` (the files right after set-up) the template listed."""
    return state_with(files, baselines=baselines)


def csv_over(cells: dict[str, str], width: int = 6, height: int = 3) -> bytes:
    """The cheap artefact: a CSV text with a few cells set (A1 names), to be written over a workbook."""
    grid = [[""] * width for _ in range(height)]
    for ref, value in cells.items():
        grid[int(ref[1:]) - 1][ord(ref[0]) - 65] = value
    return "\n".join(",".join(r) for r in grid).encode() + b"\n"


def test_sum_total_expected_from_the_sheet_as_set_up():
    path = "/home/user/Documents/points.ods"
    fresh = table("ods")
    rows = first_rows(fresh)
    total = sum(r[2] for r in rows[1:])
    run = get_evaluator("sheet_cell_aggregate")
    args = {"path": path, "cell": "E2", "function": "SUM", "cells": "C2:C11", "kind": "ods"}
    solved = ods_like_calc(rows, formulas={"E2": ("of:=SUM([.C2:.C11])", total)})
    assert run(with_baseline({path: solved}, {path: fresh}), **args).passed
    labelled = ods_like_calc([r + ([None, "Total"] if i == 0 else []) for i, r in enumerate(rows)],
                             formulas={"E2": ("of:=SUM([.C2:.C11])", total)})
    assert run(with_baseline({path: labelled}, {path: fresh}), **args).passed  # a label beside it is harmless
    # the cheap state: a CSV text over the .ods, E2 = 1 and C2 = 1, the rest gone
    artefact = csv_over({"A1": "name", "B1": "team", "C1": "score", "C2": "1", "E2": "1"})
    assert run(state_with({path: artefact}), **{**args, "kind": None}).passed  # how it passed before: no baseline
    verdict = run(with_baseline({path: artefact}, {path: fresh}), **args)
    assert not verdict.passed and verdict.reason == "expected a .ods spreadsheet, found a .csv file"
    verdict = run(with_baseline({path: artefact}, {path: fresh}), **{**args, "kind": None})
    assert not verdict.passed and f"of the original = {total:g} (within 0.005), found E2 = 1" in verdict.reason
    # a score overwritten with 0 and the total of the changed scores
    changed = [list(r) for r in rows]
    changed[1][2] = 0.0
    damaged = ods_like_calc(changed, formulas={"E2": ("of:=SUM([.C2:.C11])", total - rows[1][2])})
    assert run(state_with({path: damaged}), **args).passed  # (no baseline: computed from the sheet as found)
    verdict = run(with_baseline({path: damaged}, {path: fresh}), **args)
    assert not verdict.passed and f"found E2 = {total - rows[1][2]:g}" in verdict.reason
    right_total = ods_like_calc(changed, formulas={"E2": ("of:=SUM([.C2:.C11])", total)})  # typed-in total, data hit
    verdict = run(with_baseline({path: right_total}, {path: fresh}), **args)
    assert not verdict.passed and "expected the cells of the original unchanged" in verdict.reason
    assert f"C2 = 0 instead of {rows[1][2]:g}" in verdict.reason


def test_average_expected_from_the_sheet_as_set_up():
    path = "/home/user/Documents/exam.xlsx"
    fresh = table("xlsx")
    rows = first_rows(fresh)
    mean = sum(r[2] for r in rows[1:]) / 10
    avg, label = get_evaluator("sheet_cell_aggregate"), get_evaluator("sheet_cell_equals")
    a_args = {"path": path, "cell": "F2", "function": "AVERAGE", "cells": "C2:C11", "kind": "xlsx"}
    l_args = {"path": path, "cell": "F1", "expected": "Avg", "kind": "xlsx"}
    solved = xlsx_edited(lambda wb: (wb.active.__setitem__("F1", "Avg"), wb.active.__setitem__("F2", round(mean, 2))))
    state = with_baseline({path: solved}, {path: fresh})
    assert avg(state, **a_args).passed and label(state, **l_args).passed
    artefact = csv_over({"A1": "Name", "C2": "1", "F1": "Avg", "F2": "1"})
    state = with_baseline({path: artefact}, {path: fresh})
    for run, args in ((avg, a_args), (label, l_args)):
        verdict = run(state, **args)
        assert not verdict.passed and verdict.reason == "expected a .xlsx spreadsheet, found a .csv file"

    def fifty(wb):
        for r in range(2, 12):
            wb.active[f"C{r}"] = 50
        wb.active["F1"] = "Avg"
        wb.active["F2"] = 50
    damaged = xlsx_edited(fifty)
    verdict = avg(with_baseline({path: damaged}, {path: fresh}), **a_args)
    assert not verdict.passed and f"= {mean:g} (within 0.005), found F2 = 50" in verdict.reason


@pytest.mark.parametrize("fmt", ["xlsx", "ods"])
def test_rows_deleted_and_nothing_else(fmt):
    path = f"/home/user/Documents/orders.{fmt}"
    fresh = table(fmt, flagged="cancelled")
    rows = first_rows(fresh)
    kept = [r for r in rows if r[3] != "cancelled"]
    run = get_evaluator("sheet_rows_without")
    args = {"path": path, "column": "Status", "value": "cancelled", "count": 7, "kind": fmt}
    assert run(with_baseline({path: ods_like_calc(kept)}, {path: fresh}), **{**args, "kind": "ods"}).passed
    # the cheap state: the header and 7 junk rows
    junk = ods_like_calc(rows[:1] + [[f"x{i}", "North", float(i), "open"] for i in range(7)])
    assert run(state_with({path: junk}), **{**args, "kind": "ods"}).passed  # how it passed before: no baseline
    verdict = run(with_baseline({path: junk}, {path: fresh}), **{**args, "kind": "ods"})
    assert not verdict.passed and "expected the other 7 rows of the original, in order, no gaps" in verdict.reason
    assert "found row 2: ['x0', 'North', 0, 'open'] instead of" in verdict.reason
    # the rows' contents cleared instead of the rows deleted: gaps left
    gaps = ods_like_calc([r if r[3] != "cancelled" else [None] * 4 for r in rows])
    verdict = run(with_baseline({path: gaps}, {path: fresh}), **{**args, "kind": "ods"})
    assert not verdict.passed and "found row 3: [] instead of" in verdict.reason
    # another row deleted too, a made-up one added to keep the count
    swapped = ods_like_calc([kept[0]] + kept[2:] + [["Zoe Young", "West", 77.0, "open"]])
    verdict = run(with_baseline({path: swapped}, {path: fresh}), **{**args, "kind": "ods"})
    assert not verdict.passed and "found row 2:" in verdict.reason
    verdict = run(with_baseline({path: csv_of(kept)}, {path: fresh}), **args)
    assert not verdict.passed and verdict.reason == f"expected a .{fmt} spreadsheet, found a .csv file"


def test_rename_keeps_the_sheet_data():
    path = "/home/user/Documents/staff.xlsx"
    fresh = table("xlsx", sheet="Export")
    run = get_evaluator("sheet_names_are")
    args = {"path": path, "present": "Team List", "absent": "Export", "min_rows": 9, "kind": "xlsx"}

    def rename(wb):
        wb["Export"].title = "Team List"
    assert run(with_baseline({path: xlsx_edited(rename, fresh)}, {path: fresh}), **args).passed

    def junk(wb):
        ws = wb["Export"]
        ws.title = "Team List"
        ws.delete_rows(1, ws.max_row)
        for i in range(9):
            ws.append([f"junk{i}", i])
    artefact = xlsx_edited(junk, fresh)
    assert run(state_with({path: artefact}), **args).passed  # how it passed before: no baseline
    verdict = run(with_baseline({path: artefact}, {path: fresh}), **args)
    assert not verdict.passed and "expected sheet 'Team List' holding the original data of 'Export'" in verdict.reason

    def zeroed(wb):
        rename(wb)
        wb["Team List"]["C2"] = 0
    verdict = run(with_baseline({path: xlsx_edited(zeroed, fresh)}, {path: fresh}), **args)
    assert not verdict.passed and "found row 2:" in verdict.reason and ", 0, " in verdict.reason

    def added(wb):
        rename(wb)
        wb.create_sheet("Notes")
    verdict = run(with_baseline({path: xlsx_edited(added, fresh)}, {path: fresh}), **args)
    assert not verdict.passed
    assert "expected the sheets ['Team List'], found sheets ['Team List', 'Notes']" in verdict.reason


def test_sorted_from_the_original_which_stays_unchanged():
    sheet, out = "/home/user/Documents/scores.xlsx", "/home/user/Documents/scores_by_Score.csv"
    fresh = table("xlsx")
    rows = first_rows(fresh)
    good = csv_of(sorted_rows(rows, "Score", True))
    run = get_evaluator("sheet_sorted_from")
    args = {"path": out, "reference": sheet, "column": "Score", "order": "descending", "kind": "csv"}
    assert run(with_baseline({sheet: fresh, out: good}, {sheet: fresh}), **args).passed
    # the cheap state: a header-only CSV, copied over the original too
    header = b"Name,Team,Score,Status\n"
    assert run(state_with({sheet: header, out: header}), **args).passed  # how it passed before: no baseline
    verdict = run(with_baseline({sheet: header, out: header}, {sheet: fresh}), **args)
    assert not verdict.passed and "found 0 data rows that are not the original's 10" in verdict.reason
    # the sorted CSV right, the original overwritten with the sorted rows (as .xlsx) or deleted
    def sort_in_place(wb):
        wb.active.delete_rows(2, 10)
        for r in sorted_rows(rows, "Score", True)[1:]:
            wb.active.append(r)
    resorted = xlsx_edited(sort_in_place, fresh)
    verdict = run(with_baseline({sheet: resorted, out: good}, {sheet: fresh}), **args)
    assert not verdict.passed
    assert f"expected the original {sheet} unchanged, found sheet 'Sheet1': row 2:" in verdict.reason
    verdict = run(with_baseline({sheet: good, out: good}, {sheet: fresh}), **args)
    assert not verdict.passed and "found a .csv file instead of .xlsx" in verdict.reason


def test_copy_compared_with_the_csv_as_set_up():
    src, out = "/home/user/Downloads/export.csv", "/home/user/Downloads/export.xlsx"
    fresh = generate("people_table", {"seed": SEED, "rows": 12, "format": "csv"})
    good = generate("people_table", {"seed": SEED, "rows": 12, "format": "xlsx"})
    run = get_evaluator("sheet_same_data")
    args = {"path": out, "reference": src, "kind": "xlsx"}
    assert run(with_baseline({src: fresh, out: good}, {src: fresh}), **args).passed
    cut_csv = b"".join(fresh.splitlines(keepends=True)[:2])
    cut_xlsx = generate("people_table", {"seed": SEED, "rows": 12, "format": "xlsx"})
    cut_xlsx = xlsx_edited(lambda wb: wb.active.delete_rows(3, 20), cut_xlsx)
    assert run(state_with({src: cut_csv, out: cut_xlsx}), **args).passed  # how it passed before: no baseline
    verdict = run(with_baseline({src: cut_csv, out: cut_xlsx}, {src: fresh}), **args)
    assert not verdict.passed and verdict.reason == "expected the 13 rows of the original, found 2 rows instead of 13"
    verdict = run(with_baseline({src: cut_csv, out: good}, {src: fresh}), **args)
    assert not verdict.passed
    assert f"expected the original {src} unchanged, found sheet 'csv': 2 rows instead of 13" in verdict.reason
