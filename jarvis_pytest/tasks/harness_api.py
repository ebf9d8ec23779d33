"""What the pytest plugin calls to collect tasks, as plain dicts in the dataset format, in a stable order."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterable

from jarvis_pytest.tasks.dataset import load_tasks
from jarvis_pytest.tasks.instances import atomic_instances
from jarvis_pytest.tasks.library import load_library


def atomic_tasks(library: Path | str, instances: int) -> list[dict[str, Any]]:
    """`instances` seeded instances of every template under the `library` folder, ids `<template>[seed<n>]`,
    ordered by template id, then seed."""
    lib = load_library(library)
    return [t.to_json() for t in atomic_instances(lib, instances)]


def composed_tasks(datasets: Iterable[Path | str]) -> list[dict[str, Any]]:
    """Every composed task of the dataset files, validated."""
    return [t.to_json() for t in load_tasks(datasets)]
