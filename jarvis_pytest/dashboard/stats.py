"""TSR/SSR for the dashboard, from the project's rollup (`jarvis_pytest.report.rollup.rollup(results) -> Summary`).

Nothing is computed here: the rollup's summary is turned into what the viewer draws: the headline rates, its
tables (any nesting of mappings and lists of records becomes tables), and the success rate against the number of
subtasks (the paper's figure). Works on the finished results of a run in progress too. Results are memoised by
content, so polling the dashboard does not rerun the rollup (bootstrap intervals can be slow) until a task ends.
"""

from __future__ import annotations

import dataclasses
import hashlib
import threading
from typing import Any

from jarvis_pytest.results.model import TaskResult

RATE_KEYS = ("rate", "value", "mean", "point", "estimate")
RATE_WORDS = ("tsr", "ssr", "rate", "mean", "pass_")  # a column of shares, shown as percentages (pass@K, pass^K)
_memo: dict[str, dict[str, Any]] = {}
_memo_lock = threading.Lock()
_MEMO_SIZE = 64


def _plain(obj: Any) -> Any:
    """A summary object as JSON-like data (pydantic model, dataclass, mapping, list)."""
    if hasattr(obj, "model_dump"):
        return obj.model_dump(mode="json")
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return _plain(dataclasses.asdict(obj))
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    return obj


def _rate(value: Any) -> float | None:
    """A rate in [0, 1] from a number (a percentage above 1) or a record holding one (`rate`, `value`...)."""
    if isinstance(value, dict):
        value = next((value[k] for k in RATE_KEYS if isinstance(value.get(k), (int, float))), None)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return value / 100 if value > 1 else float(value)


def _find(data: Any, name: str) -> Any:
    """The value of key `name` at the top of the summary or in its overall/total section."""
    if not isinstance(data, dict):
        return None
    for section in (data, data.get("overall"), data.get("total"), data.get("all"), data.get("composed")):
        if isinstance(section, dict):
            for k, v in section.items():
                if k.lower() == name:
                    return v
    return None


def _scalar(v: Any) -> bool:
    return v is None or isinstance(v, (str, int, float, bool))


def _cell(key: str, v: Any) -> str:
    if v is None:
        return "–"
    if isinstance(v, float):
        if any(w in key.lower() for w in RATE_WORDS) and 0 <= v <= 1:
            return f"{100 * v:.1f}%"
        return f"{v:.3g}"
    if isinstance(v, (list, tuple)) and len(v) == 2 and all(isinstance(x, (int, float)) for x in v):
        return f"[{_cell(key, v[0])}, {_cell(key, v[1])}]"  # an interval
    return str(v)


def _records_table(title: str, rows: list[tuple[str, dict[str, Any]]]) -> dict[str, Any]:
    columns: list[str] = []
    for _, rec in rows:
        columns += [k for k in rec if k not in columns]
    first = "" if all(label == "" for label, _ in rows) else title.split(" / ")[-1]
    body = [([label] if first else []) + [_cell(c, rec.get(c)) for c in columns] for label, rec in rows]
    return {"title": title, "columns": ([first] if first else []) + columns, "rows": body}


def _tables(data: Any, title: str = "Summary") -> list[dict[str, Any]]:
    """Every part of the summary as a table: scalars together, mappings or lists of records as rows."""
    flat = lambda v: _scalar(v) or (isinstance(v, list) and all(_scalar(x) for x in v))  # noqa: E731
    if isinstance(data, list):
        if data and all(isinstance(r, dict) and all(flat(v) for v in r.values()) for r in data):
            return [_records_table(title, [("", r) for r in data])]
        return [t for i, item in enumerate(data) for t in _tables(item, f"{title} / {i}")]
    if not isinstance(data, dict):
        return []
    tables: list[dict[str, Any]] = []
    scalars = {k: v for k, v in data.items() if flat(v)}
    if scalars:
        tables.append({"title": title, "columns": ["", "value"], "rows": [[k, _cell(k, v)] for k, v in scalars.items()]})
    nested = {k: v for k, v in data.items() if not flat(v)}
    if nested and all(isinstance(v, dict) and all(flat(x) for x in v.values()) for v in nested.values()):
        return tables + [_records_table(title, list(nested.items()))]
    for k, v in nested.items():
        tables += _tables(v, k if title == "Summary" else f"{title} / {k}")
    return tables


def _curve(data: Any) -> list[dict[str, Any]]:
    """Success rate by number of subtasks, from the summary's `by_subtasks` records."""
    rows = data.get("by_subtasks") if isinstance(data, dict) else None
    return [{"subtasks": r["subtasks"], "rate": r["tsr"], "ssr": r["ssr"], "tasks": r["n"], "passed": r["k"]}
            for r in sorted(rows or [], key=lambda r: r["subtasks"])]


def _key(results: list[TaskResult]) -> str:
    h = hashlib.sha1()
    for r in sorted(results, key=lambda r: r.task_id):
        h.update(r.model_dump_json().encode())
    return h.hexdigest()


def _summarize(results: list[TaskResult]) -> dict[str, Any]:
    if not results:
        return {"available": False, "message": "No finished task yet.", "headline": {}, "tables": [], "curve": []}
    try:
        from jarvis_pytest.report.rollup import rollup

        data = _plain(rollup(results))
    except ImportError as exc:
        return {"available": False, "message": f"the rollup is not available ({exc})", "headline": {}, "tables": [],
                "curve": []}
    except Exception as exc:  # the rollup failing on odd results must not take the dashboard down
        return {"available": False, "message": f"the rollup failed: {exc.__class__.__name__}: {exc}",
                "headline": {}, "tables": [], "curve": []}
    headline = {"tsr": _rate(_find(data, "tsr")), "ssr": _rate(_find(data, "ssr")), "timing": data.get("timing")}
    return {"available": True, "message": "", "headline": headline, "tables": _tables(data), "curve": _curve(data)}


def summary(results: list[TaskResult]) -> dict[str, Any]:
    """{"available", "message", "headline": {"tsr", "ssr"}, "tables": [{"title", "columns", "rows"}],
    "curve": [{"subtasks", "rate", "tasks", "passed"}]} for the finished `results`."""
    key = _key(results)
    with _memo_lock:
        hit = _memo.get(key)
    if hit is not None:
        return hit
    value = _summarize(results)
    with _memo_lock:
        if len(_memo) >= _MEMO_SIZE:
            _memo.pop(next(iter(_memo)))
        _memo[key] = value
    return value


def headline(results: list[TaskResult]) -> dict[str, Any]:
    """{"tsr", "ssr", "tasks", "timing"}: the run's overall rates (None when unknown) over its finished tasks, and
    the time per task and per step (the rollup's `Timing`, or None)."""
    head = summary(results).get("headline") or {}
    return {"tsr": head.get("tsr"), "ssr": head.get("ssr"), "tasks": len(results), "timing": head.get("timing")}
