"""Task cases for pytest: atomic instances of the template library and composed tasks of dataset files,
each a `pytest.param` with a readable id and markers for platform, category and application.

An atomic case is made lazily: what collection, `-k`/`-m` selection and scheduling read (id, category, platforms,
applications, number of subtasks) comes from the template, and the instance itself (inputs drawn, every field
rendered) is made on first use. Making every instance in every pytest process only to deselect most of them cost
each xdist worker seconds of CPU at start (7.5 CPU-s for `--instances 48`).
"""

from __future__ import annotations

import functools
import re
from typing import Any, Callable

import pytest

from jarvis_pytest.plugin.options import JarvisOptions
from jarvis_pytest.results.model import result_key
from jarvis_pytest.tasks.model import Task

CATEGORY_MARKERS = ("atomic", "sw", "mi", "md")
PROPERTY = "jarvis"  # the name of the compact task result in `report.user_properties`


def app_marker(app: str) -> str:
    """The marker name of an application, e.g. `LibreOffice Calc` → `app_libreoffice_calc`."""
    return "app_" + re.sub(r"[^a-z0-9]+", "_", app.lower()).strip("_")


class TaskCase:
    """The parameter of a task case: its id, category, platforms, applications and number of subtasks, which of
    the run's `trials` it is, and the `Task` (made on first use, once for all its trials; a bad instance raises its
    `ConfigError` then)."""

    __slots__ = ("id", "category", "platforms", "apps", "size", "trial", "trials", "_make", "_task")

    def __init__(self, id: str, category: str, platforms: list[str], apps: list[str], size: int,
                 make: Callable[[], Task], trial: int = 1, trials: int = 1):
        self.id, self.category, self.size = id, category, size
        self.platforms, self.apps = sorted(set(platforms)), sorted(set(apps))
        self._make, self._task = make, None
        self.trial, self.trials = trial, trials

    def trial_cases(self, trials: int) -> list["TaskCase"]:
        """This case once per trial, 1 to `trials`; they share one `Task`, made on first use."""
        return [TaskCase(self.id, self.category, self.platforms, self.apps, self.size, lambda: self.task, n, trials)
                for n in range(1, trials + 1)]

    @property
    def key(self) -> str:
        """Where its result is kept in the run (`results.model.result_key`)."""
        return result_key(self.id, self.trial)

    @property
    def param_id(self) -> str:
        """Its pytest id: the task id, with `-trial<n>` after it when the run has more than one trial."""
        return self.id if self.trials == 1 else f"{self.id}-trial{self.trial}"

    @classmethod
    def of(cls, task: Task) -> "TaskCase":
        """The case of a task already made (a composed task of a dataset file)."""
        return cls(task.id, task.category, [s.platform for s in task.formatted_subtasks],
                   [s.app for s in task.formatted_subtasks if s.app], len(task.formatted_subtasks), lambda: task)

    @property
    def task(self) -> Task:
        if self._task is None:
            self._task = self._make()
        return self._task

    def __repr__(self) -> str:
        return f"TaskCase({self.id!r})"


def _param(case: TaskCase) -> Any:
    marks = [getattr(pytest.mark, p) for p in case.platforms]
    marks.append(getattr(pytest.mark, case.category))
    marks.extend(getattr(pytest.mark, app_marker(app)) for app in case.apps)
    return pytest.param(case, id=case.param_id, marks=marks)


def params(kind: str, options: JarvisOptions, config: pytest.Config) -> list[Any]:
    """One param (a `TaskCase`) per atomic instance of every template under the library folder, or per composed
    task of the dataset files; the application markers they use are declared first, so `-m app_...` works
    quietly. The library's and datasets' files are read and checked now; atomic instances are made on use."""
    from jarvis_pytest.tasks.dataset import load_tasks
    from jarvis_pytest.tasks.instances import atomic_task, instance_id, with_gui_solutions
    from jarvis_pytest.tasks.library import load_library

    if kind == "atomic":
        library = load_library(options.library)
        found = [TaskCase(instance_id(t.id, n), "atomic", [t.platform], [t.app] if t.app else [], 1,
                          functools.partial(atomic_task, t, n, source=library.sources.get(t.id)))
                 for t in library.templates for n in range(options.instances)]
    else:  # each subtask with its template's current GUI solution (`with_gui_solutions`)
        library = load_library(options.library)
        found = [TaskCase.of(with_gui_solutions(t, library)) for t in load_tasks(options.datasets)]
    if options.trials > 1:
        found = [trial for case in found for trial in case.trial_cases(options.trials)]
    for app in sorted({app for c in found for app in c.apps}):
        config.addinivalue_line("markers", f"{app_marker(app)}: tasks of the application {app}")
    return [_param(c) for c in found]
