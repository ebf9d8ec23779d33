"""Task cases for pytest: atomic instances of the template library and composed tasks of dataset files,
each a `pytest.param` with a readable id and markers for platform, category and application."""

from __future__ import annotations

import re
from typing import Any

import pytest

from jarvis_pytest.plugin.options import JarvisOptions
from jarvis_pytest.tasks.model import Task

CATEGORY_MARKERS = ("atomic", "sw", "mi", "md")
PROPERTY = "jarvis"  # the name of the compact task result in `report.user_properties`


def app_marker(app: str) -> str:
    """The marker name of an application, e.g. `LibreOffice Calc` → `app_libreoffice_calc`."""
    return "app_" + re.sub(r"[^a-z0-9]+", "_", app.lower()).strip("_")


def _param(task: Task) -> Any:
    marks = [getattr(pytest.mark, p) for p in sorted({s.platform for s in task.formatted_subtasks})]
    marks.append(getattr(pytest.mark, task.category))
    for app in sorted({s.app for s in task.formatted_subtasks if s.app}):
        marks.append(getattr(pytest.mark, app_marker(app)))
    return pytest.param(task, id=task.id, marks=marks)


def params(kind: str, options: JarvisOptions, config: pytest.Config) -> list[Any]:
    """One param (a `Task` model) per atomic instance of every template under the library folder, or per
    composed task of the dataset files; the application markers they use are declared first, so `-m app_...`
    works quietly."""
    from jarvis_pytest.tasks.dataset import load_tasks
    from jarvis_pytest.tasks.instances import atomic_instances
    from jarvis_pytest.tasks.library import load_library

    if kind == "atomic":
        tasks = atomic_instances(load_library(options.library), options.instances)
    else:
        tasks = load_tasks(options.datasets)
    for app in sorted({s.app for t in tasks for s in t.formatted_subtasks if s.app}):
        config.addinivalue_line("markers", f"{app_marker(app)}: tasks of the application {app}")
    return [_param(t) for t in tasks]
