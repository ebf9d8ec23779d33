"""Task cases for pytest: atomic instances of the template library and composed tasks of dataset files,
each a `pytest.param` with a readable id and markers for platform, category and application."""

from __future__ import annotations

import re
from typing import Any

import pytest

from jarvis_pytest.plugin.options import JarvisOptions

CATEGORY_MARKERS = ("atomic", "sw", "mi", "md")


def app_marker(app: str) -> str:
    """The marker name of an application, e.g. `LibreOffice Calc` → `app_libreoffice_calc`."""
    return "app_" + re.sub(r"[^a-z0-9]+", "_", app.lower()).strip("_")


def _param(task: dict[str, Any]) -> Any:
    marks = [getattr(pytest.mark, p) for p in sorted({s["platform"] for s in task["formatted_subtasks"]})]
    marks.append(getattr(pytest.mark, task.get("category", "atomic")))
    for app in sorted({s.get("app") for s in task["formatted_subtasks"] if s.get("app")}):
        marks.append(getattr(pytest.mark, app_marker(app)))
    return pytest.param(task, id=task["id"], marks=marks)


def atomic_params(options: JarvisOptions) -> list[Any]:
    """One param per seeded instance of every template under the library folder (sorted by id)."""
    from jarvis_pytest.tasks import harness_api

    return [_param(t) for t in harness_api.atomic_tasks(options.library, options.instances)]


def composed_params(options: JarvisOptions) -> list[Any]:
    """One param per composed task of the dataset files (sorted by id)."""
    from jarvis_pytest.tasks import harness_api

    return [_param(t) for t in harness_api.composed_tasks(options.datasets)]


def register_markers(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Declare the application markers actually used, so `-m app_...` works without warnings."""
    seen = sorted({m.name for i in items for m in i.iter_markers() if m.name.startswith("app_")})
    for name in seen:
        config.addinivalue_line("markers", f"{name}: tasks of this application")
