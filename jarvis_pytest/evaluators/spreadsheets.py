"""Checks of spreadsheets (.xlsx with openpyxl, .ods with odfpy, .csv with the csv module), read on the host.

`read_workbook` turns each format into {sheet name: rows of cell values}, with numbers as floats and text
stripped; formulas are read through the values LibreOffice caches in the file, so a total written as `=SUM(...)`
and one typed in are checked alike.
"""

from __future__ import annotations

import csv
import io
import re

from jarvis_pytest.evaluators.documents import office_kind
from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.state import FinalState, judge_file

Sheets = dict[str, list[list[object]]]


class NotASpreadsheet(ValueError):
    """The bytes are no spreadsheet of the expected kind."""


def cell_value(value: object) -> object:
    """Numbers as floats (numeric text too), text stripped, empty as None."""
    if value is None:
        return None
    if isinstance(value, bool):
        return value
    if isinstance(value, (int, float)):
        return float(value)
    text = str(value).strip()
    if not text:
        return None
    try:
        return float(text)
    except ValueError:
        return text


def _text(value: object) -> object:
    """Text with its runs of white space made one space (other values as they are)."""
    return " ".join(value.split()) if isinstance(value, str) else value


def _trim(rows: list[list[object]]) -> list[list[object]]:
    rows = [list(r) for r in rows]
    for r in rows:
        while r and r[-1] is None:
            r.pop()
    while rows and not rows[-1]:
        rows.pop()
    return rows


def spreadsheet_kind(data: bytes) -> str:
    """"xlsx", "ods" or "csv" (UTF-8 text) by content."""
    kind = office_kind(data)
    if kind in ("xlsx", "ods"):
        return kind
    if kind:
        raise NotASpreadsheet(f"a {kind} package, no spreadsheet")
    try:
        data.decode("utf-8")
    except UnicodeDecodeError:
        raise NotASpreadsheet("neither a spreadsheet package nor text") from None
    return "csv"


def read_workbook(data: bytes) -> tuple[str, Sheets]:
    """(kind, sheets) of .xlsx, .ods or .csv bytes."""
    kind = spreadsheet_kind(data)
    if kind == "xlsx":
        from openpyxl import load_workbook

        wb = load_workbook(io.BytesIO(data), data_only=True, read_only=True)
        return kind, {ws.title: _trim([[cell_value(v) for v in row] for row in ws.iter_rows(values_only=True)])
                      for ws in wb.worksheets}
    if kind == "ods":
        return kind, _read_ods(data)
    text = data.decode("utf-8").lstrip("\ufeff")
    return kind, {"csv": _trim([[cell_value(v) for v in row] for row in csv.reader(io.StringIO(text))])}


MAX_REPEAT = 10_000  # a value repeated further than this (a filled whole row or column) is cut here


def _read_ods(data: bytes) -> Sheets:
    """The sheets of an .ods file. Runs of empty rows and cells (LibreOffice writes the unused rest of a sheet as
    one row repeated a million times) are kept as gaps only when data follows them, so references stay right."""
    from odf.namespaces import TABLENS
    from odf.opendocument import load
    from odf.table import Table, TableRow

    doc = load(io.BytesIO(data))
    sheets: Sheets = {}
    for table in doc.spreadsheet.getElementsByType(Table):
        rows: list[list[object]] = []
        empty_rows = 0
        for tr in table.getElementsByType(TableRow):
            row: list[object] = []
            empty_cells = 0
            for cell in tr.childNodes:
                if cell.qname[1] not in ("table-cell", "covered-table-cell"):
                    continue
                repeat = int(cell.attributes.get((TABLENS, "number-columns-repeated"), 1))
                value = _ods_cell(cell)
                if value is None:
                    empty_cells += repeat
                    continue
                row.extend([None] * empty_cells + [value] * min(repeat, MAX_REPEAT))
                empty_cells = 0
            repeat_rows = int(tr.attributes.get((TABLENS, "number-rows-repeated"), 1))
            if not row:
                empty_rows += repeat_rows
                continue
            rows.extend([[] for _ in range(empty_rows)] + [list(row) for _ in range(min(repeat_rows, MAX_REPEAT))])
            empty_rows = 0
        sheets[table.getAttribute("name")] = _trim(rows)
    return sheets


def _ods_cell(cell) -> object:
    """A cell's value: the number it holds (a formula's too, as LibreOffice caches it), else its paragraphs' text
    (not a comment's)."""
    from odf import teletype
    from odf.namespaces import OFFICENS

    vtype = cell.attributes.get((OFFICENS, "value-type"))
    if vtype in ("float", "percentage", "currency"):
        return cell_value(float(cell.attributes.get((OFFICENS, "value"))))
    if not vtype:
        return None
    return cell_value("\n".join(teletype.extractText(p) for p in cell.childNodes if p.qname[1] == "p"))


def cell_at(rows: list[list[object]], ref: str) -> object:
    """The value at an A1-style reference such as "C12" (None when empty or outside the data)."""
    m = re.fullmatch(r"([A-Za-z]+)(\d+)", ref.strip())
    if not m:
        raise ValueError(f"bad cell reference {ref!r}")
    col = 0
    for ch in m.group(1).upper():
        col = col * 26 + ord(ch) - 64
    r, c = int(m.group(2)) - 1, col - 1
    return rows[r][c] if r < len(rows) and c < len(rows[r]) else None


def _with_workbook(state: FinalState, path: str, platform: str | None, want: str, check) -> Verdict:
    return judge_file(state, path, want, read_workbook, lambda parsed: check(*parsed), platform)


def _baseline_workbook(state: FinalState, path: str, platform: str | None) -> tuple[str, Sheets] | None:
    """(kind, sheets) of `path` as it was right after set-up (the template lists it under `baseline`), or None
    when that is not known (e.g. an upstream subtask of a composed task made it)."""
    data = state.baseline(path, platform)
    if data is None:
        return None
    try:
        return read_workbook(data)
    except Exception:
        return None


def _kind_is(kind: str, want: str | None) -> Verdict | None:
    """A failed verdict when the file's real format `kind` is not `want` (given as "xlsx" or ".xlsx")."""
    want = str(want or "").lstrip(".").lower()
    if want and kind != want:
        return Verdict.check(False, f"a .{want} spreadsheet", f"a .{kind} file")
    return None


def same_value(a: object, b: object) -> bool:
    """Cell values alike: numbers within 1e-9 (relative), text with its runs of white space made one."""
    if isinstance(a, float) and isinstance(b, float):
        return abs(a - b) <= 1e-9 * max(1.0, abs(a), abs(b))
    return _text(a) == _text(b)


def _a1(row: int, col: int) -> str:
    """The A1 name of the 0-based (row, col)."""
    letters, col = "", col + 1
    while col:
        col, rem = divmod(col - 1, 26)
        letters = chr(65 + rem) + letters
    return f"{letters}{row + 1}"


def check_cells_kept(rows: list[list[object]], ref: list[list[object]], skip: tuple[str, ...] = ()) -> Verdict:
    """Every non-empty cell of `ref` (the sheet as set up) holds the same value in `rows`, except the cells
    `skip` (the ones the task fills). Cells the task adds elsewhere are not judged here."""
    skipped = {c.strip().upper() for c in skip}
    changed = []
    for r, row in enumerate(ref):
        for c, value in enumerate(row):
            if value is None or _a1(r, c) in skipped:
                continue
            got = rows[r][c] if r < len(rows) and c < len(rows[r]) else None
            if not same_value(got, value):
                changed.append(f"{_a1(r, c)} = {_fmt(got)} instead of {_fmt(value)}")
    return Verdict.check(not changed, "the cells of the original unchanged",
                         f"{len(changed)} changed: {', '.join(changed[:3])}" if changed else "them")


def check_unchanged(kind: str, sheets: Sheets, ref_kind: str, ref: Sheets, path: str) -> Verdict:
    """The workbook is still of its original format and holds the original sheets, cell for cell."""
    want = f"the original {path} unchanged"
    if kind != ref_kind:
        return Verdict.check(False, want, f"a .{kind} file instead of .{ref_kind}")
    if list(sheets) != list(ref):
        return Verdict.check(False, want, f"sheets {list(sheets)!r} instead of {list(ref)!r}")
    for name, rows in ref.items():
        diff = _row_diff(sheets[name], rows)
        if diff:
            return Verdict.check(False, want, f"sheet {name!r}: {diff}")
    return Verdict.check(True, want, "it")


def _row_diff(rows: list[list[object]], ref: list[list[object]]) -> str | None:
    """The first difference between two sheets' rows (trailing empty cells ignored), or None."""
    rows, ref = _trim(rows), _trim(ref)
    for i, (a, b) in enumerate(zip(rows, ref)):
        if len(a) != len(b) or not all(same_value(x, y) for x, y in zip(a, b)):
            return f"row {i + 1}: {_fmt_row(a)} instead of {_fmt_row(b)}"
    if len(rows) != len(ref):
        return f"{len(rows)} rows instead of {len(ref)}"
    return None


def _compared_with(state: FinalState, path: str, reference: str, platform: str | None, want: str,
                   check) -> Verdict:
    """`check(kind, rows, reference_rows)` on the first sheets of `path` and of the original `reference`: the
    reference as set up when the template lists it under `baseline` — and then `reference` must still be as it
    was (the task only reads it) — else the reference as found (one an upstream subtask made has no baseline)."""
    original = _baseline_workbook(state, reference, platform)
    if original is None:
        return judge_file(state, reference, f"the original {reference}",
                          lambda data: _first(read_workbook(data)[1]),
                          lambda ref_rows: _with_workbook(state, path, platform, want,
                                                          lambda kind, sheets: check(kind, _first(sheets), ref_rows)),
                          platform)
    ref_kind, ref_sheets = original
    verdict = _with_workbook(state, path, platform, want,
                             lambda kind, sheets: check(kind, _first(sheets), _first(ref_sheets)))
    if not verdict.passed:
        return verdict
    kept = _with_workbook(state, reference, platform, f"the original {reference} unchanged",
                          lambda kind, sheets: check_unchanged(kind, sheets, ref_kind, ref_sheets, reference))
    return verdict if kept.passed else kept


def _first(sheets: Sheets) -> list[list[object]]:
    return next(iter(sheets.values()), [])


def _fmt(v: object) -> str:
    return f"{v:g}" if isinstance(v, float) else repr(v)


def _fmt_row(row: list[object]) -> str:
    return "[" + ", ".join(_fmt(v) for v in row) + "]"


# -- checks --------------------------------------------------------------------------------------------------
def _sort_key(value: object) -> tuple:
    """Numbers before text (text case-insensitively, as Calc sorts it), empty cells last."""
    if value is None:
        return (2, 0.0, "")
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return (0, float(value), "")
    return (1, 0.0, str(value).casefold())


def descending_order(order: str) -> bool:
    """True for "descending"/"decreasing", False for "ascending"/"increasing"."""
    word = str(order).strip().lower()
    if word in ("descending", "decreasing", "desc"):
        return True
    if word in ("ascending", "increasing", "asc"):
        return False
    raise ValueError(f"unknown sort order {order!r}: use ascending, increasing, descending or decreasing")


def check_sorted_from(rows: list[list[object]], ref: list[list[object]], column: str, descending: bool) -> Verdict:
    """`rows` are the rows of `ref` (same header, same data rows) sorted by the column headed `column`."""
    want = f"the rows of the original sorted by {column} ({'descending' if descending else 'ascending'})"
    if not rows or not ref or rows[0] != ref[0]:
        return Verdict.check(False, want, f"header {rows[0] if rows else None!r}")
    if column not in ref[0]:
        return Verdict.check(False, want, f"no column {column!r} in {ref[0]!r}")
    i = ref[0].index(column)
    data = rows[1:]
    if sorted(map(repr, data)) != sorted(map(repr, ref[1:])):
        missing = next((r for r in ref[1:] if r not in data), None)
        return Verdict.check(False, want, f"{len(data)} data rows that are not the original's {len(ref) - 1}"
                             + (f" (no row {_fmt_row(missing)})" if missing else ""))
    keys = [r[i] if i < len(r) else None for r in data]
    ok = [_sort_key(k) for k in keys] == sorted(map(_sort_key, keys), reverse=bool(descending))
    return Verdict.check(ok, want, f"{column} in the order {_fmt_row(keys[:12])}")


@evaluator("sheet_sorted_from")
def sheet_sorted_from(state: FinalState, path: str, reference: str, column: str, order: str = "ascending",
                      kind: str | None = None, platform: str | None = None) -> Verdict:
    """`path` (of `kind` when given: xlsx, ods, csv) holds in its first sheet the rows of `reference`'s first
    sheet sorted by `column` in `order` ("ascending"/"increasing" or "descending"/"decreasing"). With a baseline
    of `reference` the rows come from it as set up, and `reference` must be left unchanged."""
    descending = descending_order(order)

    def check(k: str, rows: list[list[object]], ref_rows: list[list[object]]) -> Verdict:
        return _kind_is(k, kind) or check_sorted_from(rows, ref_rows, column, descending)

    return _compared_with(state, path, reference, platform, f"{path} sorted by {column}", check)


AGGREGATES = {"SUM": sum, "AVERAGE": lambda xs: sum(xs) / len(xs), "MAX": max, "MIN": min}


def check_cell_aggregate(rows: list[list[object]], cell: str, function: str, cells: str,
                         source: list[list[object]] | None = None) -> Verdict:
    """The value at `cell` equals the SUM/AVERAGE/MAX/MIN of the numbers in the column range `cells` (e.g.
    C2:C11) of `source` (the sheet as set up; by default `rows` itself), whether it was typed in (rounded to 2
    decimals is enough) or is a formula whose value LibreOffice cached in the file."""
    m = re.fullmatch(r"\s*([A-Za-z]+)(\d+)\s*:\s*\1(\d+)\s*", cells, re.IGNORECASE)
    if not m or function.upper() not in AGGREGATES:
        raise ValueError(f"need a one-column range such as C2:C11 and one of {sorted(AGGREGATES)}, "
                         f"not {function!r} of {cells!r}")
    col, first, last = m.group(1), int(m.group(2)), int(m.group(3))
    src = rows if source is None else source
    numbers = [v for v in (cell_at(src, f"{col}{r}") for r in range(first, last + 1)) if isinstance(v, float)]
    if not numbers:
        return Verdict.check(False, f"{cell} = {function.upper()}({cells})", f"no numbers in {cells}")
    want = AGGREGATES[function.upper()](numbers)
    got = cell_at(rows, cell)
    ok = isinstance(got, float) and abs(got - want) <= 0.005 + 1e-9
    of = "" if source is None else " of the original"
    return Verdict.check(ok, f"{cell} = {function.upper()}({cells}){of} = {want:g} (within 0.005)",
                         f"{cell} = {_fmt(got)}")


@evaluator("sheet_cell_aggregate")
def sheet_cell_aggregate(state: FinalState, path: str, cell: str, function: str, cells: str,
                         kind: str | None = None, platform: str | None = None) -> Verdict:
    """In the first sheet (of a workbook of `kind`, e.g. "ods", when given), `cell` holds the `function` (SUM,
    AVERAGE, MAX, MIN) of the range `cells`. With a baseline of `path` the expected value comes from the sheet
    as set up and every cell it had must be unchanged; without one (a sheet an upstream subtask made) it is
    computed from the sheet as found."""
    original = _baseline_workbook(state, path, platform)
    source = _first(original[1]) if original else None

    def check(k: str, sheets: Sheets) -> Verdict:
        rows = _first(sheets)
        verdict = _kind_is(k, kind) or check_cell_aggregate(rows, cell, function, cells, source)
        if not verdict.passed or source is None:
            return verdict
        kept = check_cells_kept(rows, source, (cell,))
        return verdict if kept.passed else kept
    return _with_workbook(state, path, platform, f"{cell} = {function}({cells})", check)


def check_sheet_names(sheets: Sheets, present: str, absent: str | None, min_rows: int = 0,
                      original: Sheets | None = None) -> Verdict:
    """A sheet named `present` with at least `min_rows` rows (its data kept), and none named `absent`. With the
    `original` sheets: the workbook holds exactly them, in order, `absent` renamed `present`, each with its
    original cells."""
    names = list(sheets)
    rows = len(sheets.get(present, []))
    ok = present in names and (absent is None or absent not in names) and rows >= int(min_rows)
    want = f"a sheet named {present!r}" + (f" with its {min_rows} rows" if min_rows else "") + \
        (f" and none named {absent!r}" if absent else "")
    verdict = Verdict.check(ok, want, f"sheets {names!r}"
                            + (f", {rows} rows in {present!r}" if present in names else ""))
    if not ok or original is None:
        return verdict
    renamed = [present if n == absent else n for n in original]
    if names != renamed:
        return Verdict.check(False, f"the sheets {renamed!r}", f"sheets {names!r}")
    for old, new in zip(original, renamed):
        diff = _row_diff(sheets[new], original[old])
        if diff:
            return Verdict.check(False, f"sheet {new!r} holding the original data of {old!r}", diff)
    return verdict


@evaluator("sheet_names_are")
def sheet_names_are(state: FinalState, path: str, present: str, absent: str | None = None, min_rows: int = 0,
                    kind: str | None = None, platform: str | None = None) -> Verdict:
    """The workbook (of `kind` when given) has a sheet named `present` holding at least `min_rows` rows (and
    none named `absent`). With a baseline of `path`, its sheets are the original ones with `absent` renamed, each
    holding its original cells; without one only the names and the row count are checked."""
    original = _baseline_workbook(state, path, platform)
    return _with_workbook(state, path, platform, f"a sheet named {present!r}",
                          lambda k, sheets: _kind_is(k, kind) or check_sheet_names(
                              sheets, present, absent, min_rows, original[1] if original else None))


def check_same_data(kind: str, rows: list[list[object]], want_kind: str | None, ref: list[list[object]]) -> Verdict:
    """The workbook is of `want_kind` and its first sheet has the cell values of `ref`."""
    wrong = _kind_is(kind, want_kind)
    if wrong:
        return wrong
    diff = _row_diff(rows, ref)
    return Verdict.check(diff is None, f"the {len(ref)} rows of the original", diff or "them")


@evaluator("sheet_same_data")
def sheet_same_data(state: FinalState, path: str, reference: str, kind: str | None = None,
                    platform: str | None = None) -> Verdict:
    """`path` (of `kind`: xlsx, ods, csv) holds the same cell values as `reference`'s first sheet — as set up
    when `reference` has a baseline (and then `reference` must be left unchanged), else as found."""
    return _compared_with(state, path, reference, platform, f"a copy of {reference}",
                          lambda k, rows, ref_rows: check_same_data(k, rows, kind, ref_rows))


def check_rows_without(rows: list[list[object]], column: str, value: str, count: int,
                       original: list[list[object]] | None = None) -> Verdict:
    """No data row has `value` in the column headed `column`, and `count` data rows are left. With the
    `original` rows (the sheet as set up): the sheet is exactly them without those rows, in order, no gap left."""
    if not rows or column not in rows[0]:
        return Verdict.check(False, f"a column {column!r}", f"header {rows[0] if rows else None!r}")
    i, want = rows[0].index(column), _text(cell_value(value))
    data = [r for r in rows[1:] if any(v is not None for v in r)]
    hits = [r for r in data if i < len(r) and _text(r[i]) == want]
    verdict = Verdict.check(not hits and len(data) == int(count),
                            f"{count} data rows, none with {column} = {value!r}",
                            f"{len(data)} rows, {len(hits)} with it")
    if not verdict.passed or original is None or not original or column not in original[0]:
        return verdict
    j = original[0].index(column)
    kept = [original[0]] + [r for r in original[1:] if not (j < len(r) and _text(r[j]) == want)]
    diff = _row_diff(rows, kept)
    return Verdict.check(diff is None, f"the other {len(kept) - 1} rows of the original, in order, no gaps",
                         diff or "them")


@evaluator("sheet_rows_without")
def sheet_rows_without(state: FinalState, path: str, column: str, value: str, count: int,
                       kind: str | None = None, platform: str | None = None) -> Verdict:
    """In the first sheet (of a workbook of `kind` when given) no data row has `value` in the column headed
    `column`, and `count` data rows are left. With a baseline of `path` the sheet must be exactly the original
    rows without those (other rows unchanged and in order, no empty rows left as gaps); without one, empty rows
    do not count and the remaining rows are not compared."""
    original = _baseline_workbook(state, path, platform)
    return _with_workbook(state, path, platform, f"no rows with {column} = {value!r}",
                          lambda k, sheets: _kind_is(k, kind) or check_rows_without(
                              _first(sheets), column, value, int(count), _first(original[1]) if original else None))


def check_cell_equals(rows: list[list[object]], cell: str, expected: object) -> Verdict:
    """`cell` holds `expected`: numbers compared as numbers, text with its runs of white space made one."""
    got, want = cell_at(rows, cell), cell_value(expected)
    ok = _text(got) == _text(want) if not isinstance(want, float) else \
        isinstance(got, float) and abs(got - want) < 1e-9
    return Verdict.check(ok, f"{cell} = {_fmt(want)}", f"{cell} = {_fmt(got)}")


@evaluator("sheet_cell_equals")
def sheet_cell_equals(state: FinalState, path: str, cell: str, expected: object, kind: str | None = None,
                      platform: str | None = None) -> Verdict:
    """In the first sheet (of a workbook of `kind` when given), `cell` holds `expected` (numbers compared as
    numbers, text with white space normalised)."""
    return _with_workbook(state, path, platform, f"{cell} = {expected!r}",
                          lambda k, sheets: _kind_is(k, kind) or check_cell_equals(_first(sheets), cell, expected))
