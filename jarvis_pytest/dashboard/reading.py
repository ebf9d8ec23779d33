"""Read result files that may be missing, half-written or corrupted: every reader returns what it could read
and the problems it met, never raises; parsed files are cached until their size or mtime changes."""

from __future__ import annotations

import json
import os
import re
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from pydantic import BaseModel, ValidationError

from jarvis_pytest.results.model import StepRecord

SCREENSHOT_RE = re.compile(r"^step_(\d+)_([A-Za-z0-9]+)\.png$")


class FileCache:
    """Small parsed forms of files keyed by (path, kind), reused while the file's (mtime, size) is unchanged;
    the oldest entries go first beyond `max_entries`."""

    def __init__(self, max_entries: int = 50_000) -> None:
        self._entries: dict[tuple[Path, str], tuple[tuple[int, int], Any]] = {}
        self._lock = threading.Lock()
        self.max_entries = max_entries

    def get(self, path: Path, kind: str, parse: Callable[[bytes], Any]) -> Any:
        """parse(contents of path), from the cache when possible; OSError when the file cannot be read."""
        st = path.stat()
        stamp = (st.st_mtime_ns, st.st_size)
        with self._lock:
            hit = self._entries.get((path, kind))
        if hit is not None and hit[0] == stamp:
            return hit[1]
        value = parse(path.read_bytes())
        with self._lock:
            self._entries.pop((path, kind), None)
            while len(self._entries) >= self.max_entries:
                self._entries.pop(next(iter(self._entries)))
            self._entries[(path, kind)] = (stamp, value)
        return value


def _short(exc: ValidationError) -> str:
    errors = exc.errors()
    first = errors[0]
    where = ".".join(str(p) for p in first["loc"]) or "(root)"
    more = f" (and {len(errors) - 1} more)" if len(errors) > 1 else ""
    return f"{where}: {first['msg']}{more}"


def _parse_json(model: type[BaseModel] | None) -> Callable[[bytes], tuple[Any, str | None]]:
    def parse(data: bytes) -> tuple[Any, str | None]:
        try:
            raw = json.loads(data)
        except (ValueError, UnicodeDecodeError) as exc:
            return None, f"not valid JSON ({exc})"
        if model is None:
            return raw, None
        try:
            return model.model_validate(raw), None
        except ValidationError as exc:
            return None, f"unexpected content: {_short(exc)}"
    return parse


def load_json(cache: FileCache, path: Path, model: type[BaseModel] | None = None) -> tuple[Any, str | None]:
    """(value, None) when readable; (None, problem) when corrupted; (None, None) when the file is absent."""
    try:
        return cache.get(path, f"json:{model.__name__ if model else ''}", _parse_json(model))
    except FileNotFoundError:
        return None, None
    except OSError as exc:
        return None, f"cannot read ({exc.strerror})"


def _parse_traj(data: bytes) -> tuple[list[StepRecord], list[str]]:
    steps: list[StepRecord] = []
    problems: list[str] = []
    text = data.decode("utf-8", errors="replace")
    lines = text.split("\n")
    for number, line in enumerate(lines, 1):
        if not line.strip():
            continue
        last = number == len(lines)  # no newline after it: the writer may be in the middle of it
        try:
            steps.append(StepRecord.model_validate_json(line))
        except ValidationError as exc:
            if last and any(e["type"] == "json_invalid" for e in exc.errors()):
                problems.append(f"line {number} is incomplete (half-written; the task may still be writing it)")
            elif any(e["type"] == "json_invalid" for e in exc.errors()):
                problems.append(f"line {number} is not valid JSON")
            else:
                problems.append(f"line {number} is not a step record: {_short(exc)}")
    return steps, problems


def load_traj(path: Path) -> tuple[list[StepRecord], list[str]]:
    """The readable steps of traj.jsonl and a problem per unreadable line; ([], []) when absent. Not cached."""
    try:
        return _parse_traj(path.read_bytes())
    except FileNotFoundError:
        return [], []
    except OSError as exc:
        return [], [f"cannot read ({exc.strerror})"]


@dataclass(frozen=True)
class TrajSummary:
    """What a task's row needs from its trajectory (kept in the cache instead of every step)."""

    count: int = 0
    last: StepRecord | None = None
    problems: tuple[str, ...] = ()


def _summarize_traj(data: bytes) -> TrajSummary:
    steps, problems = _parse_traj(data)
    return TrajSummary(len(steps), steps[-1] if steps else None, tuple(problems))


def load_traj_summary(cache: FileCache, path: Path) -> TrajSummary:
    """Step count, last step and problems of traj.jsonl, cached; empty when absent."""
    try:
        return cache.get(path, "traj-summary", _summarize_traj)
    except FileNotFoundError:
        return TrajSummary()
    except OSError as exc:
        return TrajSummary(problems=(f"cannot read ({exc.strerror})",))


def screenshots(task_dir: Path) -> dict[int, dict[str, str]]:
    """step index → platform → file name, for every `step_NNNN_<platform>.png` in the task directory."""
    found: dict[int, dict[str, str]] = {}
    try:
        entries = list(os.scandir(task_dir))
    except OSError:
        return found
    for entry in entries:
        m = SCREENSHOT_RE.match(entry.name)
        if m and entry.is_file():
            found.setdefault(int(m.group(1)), {})[m.group(2)] = entry.name
    return dict(sorted(found.items()))
