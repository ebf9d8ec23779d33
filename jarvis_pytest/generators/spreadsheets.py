"""Generators of spreadsheets: a seeded table of people, teams, scores and statuses written as .xlsx
(openpyxl), .ods (odfpy) or .csv, so every instance of a task gets its own rows; deterministic to the byte."""

from __future__ import annotations

import csv
import io
import random

from jarvis_pytest.generators.packages import deterministic_package
from jarvis_pytest.generators.registry import generator

HEADER = ["Name", "Team", "Score", "Status"]
NAMES = ["Ava Brown", "Ben Clark", "Chloe Diaz", "Dan Evans", "Ella Fox", "Finn Green", "Grace Hill", "Hugo Ito",
         "Isla Jones", "Jack King", "Kara Lee", "Liam Moss", "Maya Nash", "Noah Ortiz", "Olive Park", "Paul Quinn"]
TEAMS = ["North", "South", "East", "West"]
STATUSES = ["open", "done", "open", "done", "pending"]


def people_rows(seed: int, rows: int, flagged: str | None = None, every: int = 3) -> list[list]:
    """`rows` rows of [name, team, score, status]; the status of every `every`-th row is `flagged` if given."""
    if not 1 <= int(rows) <= len(NAMES):
        raise TypeError(f"`rows` must be between 1 and {len(NAMES)}")
    rnd = random.Random(int(seed))
    names = rnd.sample(NAMES, int(rows))
    out = []
    for i, name in enumerate(names):
        status = flagged if flagged and i % int(every) == 1 else STATUSES[i % len(STATUSES)]
        out.append([name, rnd.choice(TEAMS), rnd.randint(40, 99), status])
    return out


def xlsx_bytes(header: list, rows: list[list], sheet: str = "Sheet1") -> bytes:
    from openpyxl import Workbook

    wb = Workbook()
    ws = wb.active
    ws.title = sheet
    ws.append(header)
    for row in rows:
        ws.append(row)
    wb.properties.creator = "jarvis"
    buf = io.BytesIO()
    wb.save(buf)
    return deterministic_package(buf.getvalue())  # openpyxl stamps the members and `modified` with the current time


def ods_bytes(header: list, rows: list[list], sheet: str = "Sheet1") -> bytes:
    from odf.opendocument import OpenDocumentSpreadsheet
    from odf.table import Table, TableCell, TableRow
    from odf.text import P

    doc = OpenDocumentSpreadsheet()
    table = Table(name=sheet)
    for values in [header, *rows]:
        tr = TableRow()
        for v in values:
            if isinstance(v, (int, float)) and not isinstance(v, bool):
                cell = TableCell(valuetype="float", value=v)
            else:
                cell = TableCell(valuetype="string")
            cell.addElement(P(text=str(v)))
            tr.addElement(cell)
        table.addElement(tr)
    doc.spreadsheet.addElement(table)
    buf = io.BytesIO()
    doc.write(buf)
    return deterministic_package(buf.getvalue(), odf=True)


def csv_bytes(header: list, rows: list[list]) -> bytes:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows([header, *rows])
    return buf.getvalue().encode("utf-8")


@generator("people_table")
def people_table(seed: int, rows: int = 10, format: str = "xlsx", sheet: str = "Sheet1",
                 flagged: str | None = None) -> bytes:
    """A table with the header Name, Team, Score, Status and `rows` seeded rows, as `format` (xlsx, ods or
    csv); every third row (the 2nd, 5th, ...) has the status `flagged` when given."""
    header, data = HEADER, people_rows(seed, rows, flagged)
    fmt = str(format).lower()
    if fmt == "xlsx":
        return xlsx_bytes(header, data, sheet)
    if fmt == "ods":
        return ods_bytes(header, data, sheet)
    if fmt == "csv":
        return csv_bytes(header, data)
    raise TypeError("`format` must be xlsx, ods or csv")
