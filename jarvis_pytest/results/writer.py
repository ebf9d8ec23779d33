"""Write a task's results as it runs, so an interrupted run keeps everything finished so far."""

from __future__ import annotations

import json
import os
import re
from datetime import datetime, timezone
from pathlib import Path

from jarvis_pytest.results.model import StepRecord, TaskResult


def safe_name(task_id: str) -> str:
    """A file-system-safe directory name for a task id (`ubuntu-calc-sort[seed0]` → `ubuntu-calc-sort_seed0`)."""
    return re.sub(r"[^A-Za-z0-9._-]+", "_", task_id).strip("_")


def now_iso() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="milliseconds")


def escape_surrogates(value: object) -> object:
    """`value` (JSON data) with each lone surrogate in its strings written as its escape, the text `\\udXXX`: a
    model's raw answer may hold one, and UTF-8 (and so every JSON reader) takes none."""
    if isinstance(value, str):
        return value.encode("utf-8", "backslashreplace").decode("utf-8") if _SURROGATE.search(value) else value
    if isinstance(value, dict):
        return {escape_surrogates(k): escape_surrogates(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [escape_surrogates(v) for v in value]
    return value


_SURROGATE = re.compile("[\ud800-\udfff]")


def write_json_atomic(path: Path, data: object) -> None:
    """Write JSON through a temporary file and a rename: readers never see half a file."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(json.dumps(escape_surrogates(data), indent=2, sort_keys=True, ensure_ascii=False) + "\n",
                       encoding="utf-8")
        os.replace(tmp, path)
    except BaseException:  # a full or read-only disk: no half-written temporary file left beside the old one
        try:
            tmp.unlink(missing_ok=True)
        except OSError:
            pass
        raise


def task_dir(run_dir: Path, key: str) -> Path:
    """The folder of a result (`result_key`): `tasks/<safe id>`, `tasks/<safe id>_trial<n>` for the n-th trial."""
    return run_dir / "tasks" / safe_name(key)


def read_result(run_dir: Path, key: str) -> TaskResult | None:
    """The stored result of a task's trial (`result_key`: the task id for the first), or None when absent or
    unreadable."""
    path = task_dir(run_dir, key) / "result.json"
    try:
        return TaskResult.model_validate_json(path.read_text())
    except (OSError, ValueError):
        return None


class TaskRecorder:
    """Appends trajectory lines and screenshots, and (re)writes result.json, for one task."""

    def __init__(self, run_dir: Path, result: TaskResult):
        self.dir = task_dir(run_dir, result.key)
        if self.dir.exists():  # a rerun of this task replaces its earlier files
            for p in self.dir.iterdir():
                if p.is_file():
                    p.unlink()
        self.dir.mkdir(parents=True, exist_ok=True)
        self.result = result
        self.acted_on: set[str] = set()  # platforms the agent sent at least one action to
        self.result.started = self.result.started or now_iso()
        self._traj = open(self.dir / "traj.jsonl", "a", encoding="utf-8")
        self.save_result()

    def screenshot(self, step: int, platform: str, png: bytes) -> str:
        name = f"step_{step:04d}_{platform}.png"
        (self.dir / name).write_bytes(png)
        if self.result.first_screenshot is None:
            self.result.first_screenshot = name
        self.result.last_screenshot = name
        return name

    def step(self, record: StepRecord) -> None:
        try:
            line = record.model_dump_json()
        except ValueError:  # a lone surrogate (in a model's raw answer, say): written escaped
            line = json.dumps(escape_surrogates(record.model_dump(mode="json")), ensure_ascii=False)
        self._traj.write(line + "\n")
        self._traj.flush()
        if record.action is not None and record.platform:
            self.acted_on.add(record.platform)

    def drive_ledger(self, records: list[dict]) -> None:
        """What the transfer drive received and served during the agent's turn (`drive_ledger.jsonl`)."""
        with open(self.dir / "drive_ledger.jsonl", "w", encoding="utf-8") as f:
            f.writelines(json.dumps(r, sort_keys=True) + "\n" for r in records)

    def save_result(self) -> None:
        write_json_atomic(self.dir / "result.json", self.result.model_dump(mode="json"))

    def finish(self) -> None:
        self.result.finished = now_iso()
        self.save_result()
        self._traj.close()
