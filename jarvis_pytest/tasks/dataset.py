"""Dataset files in the paper's format (appendix "Configuration File Details"): one JSON object with `tasks`.

Each task has `id`, `category`, `devices`, `instruction`, `edges` (``{"from": [i, out], "to": [j, in]}``) and
`formatted_subtasks` (each with `template`, `platform`, `app`, `instruction`, `input`/`output` as slot name →
``{"type", "value"}``, `config` (setup steps), `evaluate`, `solution`, ...). We add `meta` (how the file was
made). Files are written with sorted keys, two-space indentation and a final newline, so equal inputs give
byte-identical files. Reading validates the schema and every task graph (``graph.task_problems``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Iterable, Sequence

from pydantic import ValidationError

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.tasks.graph import task_problems
from jarvis_pytest.devices.platforms import spec
from jarvis_pytest.tasks.library import check_names, fixture_problem, pydantic_error
from jarvis_pytest.tasks.templating import Where
from jarvis_pytest.tasks.model import Dataset, Task
from jarvis_pytest.tasks.types import TypeSystem, load_types


def dumps_dataset(tasks: Sequence[Task], meta: dict[str, Any] | None = None) -> str:
    """The dataset file's text: deterministic JSON with a trailing newline."""
    data = {"meta": dict(meta or {}), "tasks": [t.to_json() for t in tasks]}
    return json.dumps(data, indent=2, sort_keys=True, ensure_ascii=False) + "\n"


def write_dataset(path: Path | str, tasks: Sequence[Task], meta: dict[str, Any] | None = None) -> Path:
    """Write a dataset file (creating its folder)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(dumps_dataset(tasks, meta), encoding="utf-8")
    return path


def load_dataset(path: Path | str, types: TypeSystem | None = None, *, check: bool = True) -> Dataset:
    """Read and validate a dataset file; each problem is a ConfigError naming the file, the task and the field.

    `types` defaults to the repository's type system; `check=False` skips the graph checks.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError("no such dataset file", path=path, fix="run `jarvis compose --out FILE` first") from None
    except json.JSONDecodeError as exc:
        raise ConfigError(f"not valid JSON: {exc.msg} at line {exc.lineno} column {exc.colno}", path=path,
                          fix="fix the JSON syntax or compose the file again") from None
    if not isinstance(data, dict) or not isinstance(data.get("tasks"), list):
        raise ConfigError('expected an object with a "tasks" list', path=path, field="tasks",
                          fix="write the dataset as {\"tasks\": [...]}")
    for i, item in enumerate(data["tasks"]):
        task_id = item.get("id") if isinstance(item, dict) and isinstance(item.get("id"), str) else None
        try:
            Task.model_validate(item)
        except ValidationError as exc:
            raise pydantic_error(exc, path=path, task=task_id, prefix=f"tasks[{i}].") from None
    try:
        dataset = Dataset.model_validate(data)
    except ValidationError as exc:
        raise pydantic_error(exc, path=path, task=None) from None
    seen: dict[str, int] = {}
    for i, task in enumerate(dataset.tasks):
        if task.id in seen:
            raise ConfigError(f"duplicate task id {task.id!r} (also tasks[{seen[task.id]}])", path=path,
                              field=f"tasks[{i}].id", fix="give every task its own id")
        seen[task.id] = i
    for i, task in enumerate(dataset.tasks):
        for j, sub in enumerate(task.formatted_subtasks):
            where = Where(path, task.id, f"tasks[{i}].formatted_subtasks[{j}]")
            check_names(sub.evaluate, sub.config, where)
            for k, step in enumerate(sub.config):
                if step.type == "upload_file" and step.fixture is not None and fixture_problem(step.fixture):
                    raise where.at(f"config[{k}].fixture").error(fixture_problem(step.fixture),
                                                                 "use a file under fixtures/files/")
                if step.type == "upload_file" and not spec(step.platform or sub.platform).may_write(step.path):
                    raise where.at(f"config[{k}].path").error(
                        f"upload path {step.path!r} is not where a task may write",
                        f"use a path under {' or '.join(spec(step.platform or sub.platform).writable_roots)}")
    if check:
        types = types or load_types()
        for i, task in enumerate(dataset.tasks):
            problems = task_problems(task, types)
            if problems:
                raise ConfigError(f"task {task.id!r}: {problems[0]}", path=path, field=f"tasks[{i}]",
                                  fix="compose the file again with `jarvis compose`, or fix the task by hand")
    return dataset


def load_tasks(paths: Iterable[Path | str], types: TypeSystem | None = None) -> list[Task]:
    """The tasks of several dataset files, sorted by id; an id used in two files is an error."""
    types = types or load_types()
    found: dict[str, tuple[Task, Path]] = {}
    for path in sorted(Path(p) for p in paths):
        for task in load_dataset(path, types).tasks:
            if task.id in found:
                raise ConfigError(f"task id {task.id!r} is also in {found[task.id][1]}", path=path, field="tasks.id",
                                  fix="compose the datasets with distinct ids or load one of them")
            found[task.id] = (task, path)
    return [found[k][0] for k in sorted(found)]
