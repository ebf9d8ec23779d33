"""`{{slot}}` placeholders in instructions, setup steps, evaluator arguments and oracle solutions (paper §4.2).

Syntax: ``{{name}}`` is the value of slot ``name``; ``{{name.attr}}`` is a part of a path-valued slot: ``name``
(``report.xlsx``), ``stem`` (``report``), ``ext`` (``.xlsx``) or ``dir`` (``/home/user/Documents``). Windows
paths (``C:\\...``) are split at backslashes, all others at slashes. Rendering is a single pass: a value is never
rendered again. In nested data (evaluator arguments, steps), a string that is exactly one placeholder becomes the
slot's value with its own type (``"{{count}}"`` → ``3``); elsewhere values are written as text. An unknown or
unbound placeholder, or stray ``{{``/``}}``, is a ConfigError naming the file, the task, the field and the
placeholder.
"""

from __future__ import annotations

import ntpath
import posixpath
import re
from dataclasses import dataclass
from collections.abc import Iterator, Mapping
from typing import Any

from jarvis_pytest.errors import ConfigError

Scalar = str | int | float
PLACEHOLDER = re.compile(r"\{\{\s*([A-Za-z_][A-Za-z0-9_]*)(?:\.([A-Za-z_]+))?\s*\}\}")
STRAY_BRACES = re.compile(r"\{\{|\}\}")
PATH_ATTRS = ("dir", "ext", "folder", "name", "stem")
WINDOWS_PATH = re.compile(r"^[A-Za-z]:\\|\\")


@dataclass(frozen=True)
class Where:
    """Where a template text comes from, for error messages."""

    path: object = None
    task: str | None = None
    field: str | None = None

    def at(self, field: str) -> "Where":
        return Where(self.path, self.task, f"{self.field}.{field}" if self.field else field)

    def error(self, message: str, fix: str) -> ConfigError:
        head = f"task {self.task!r}: " if self.task else ""
        return ConfigError(head + message, path=self.path, field=self.field, fix=fix)


@dataclass(frozen=True)
class Placeholder:
    name: str
    attr: str | None
    text: str


def find_placeholders(text: str, where: Where = Where()) -> list[Placeholder]:
    """The placeholders of `text`, in order; malformed ones (stray braces, bad attribute) raise."""
    found = [Placeholder(m.group(1), m.group(2), m.group(0)) for m in PLACEHOLDER.finditer(text)]
    rest = PLACEHOLDER.sub("", text)
    stray = STRAY_BRACES.search(rest)
    if stray:
        near = rest[max(0, stray.start() - 15): stray.end() + 15]
        raise where.error(f"malformed placeholder near {near!r}",
                          "write placeholders as {{slot}} or {{slot.name|stem|ext|dir}} with a slot name")
    for ph in found:
        if ph.attr is not None and ph.attr not in PATH_ATTRS:
            raise where.error(f"placeholder {ph.text} has an unknown attribute {ph.attr!r}",
                              f"use one of {', '.join(PATH_ATTRS)}")
    return found


def walk_strings(obj: Any, where: Where) -> Iterator[tuple[str, Where]]:
    """Every string inside nested dicts/lists (not the keys), with its location."""
    if isinstance(obj, str):
        yield obj, where
    elif isinstance(obj, Mapping):
        for key in obj:
            yield from walk_strings(obj[key], where.at(str(key)))
    elif isinstance(obj, (list, tuple)):
        for i, item in enumerate(obj):
            yield from walk_strings(item, Where(where.path, where.task, f"{where.field}[{i}]"))


def path_part(value: Scalar, attr: str) -> str:
    """One part (name, stem, ext, dir, or folder: the name of the folder that holds it) of a path value."""
    text = str(value)
    mod = ntpath if WINDOWS_PATH.search(text) else posixpath
    if attr == "dir":
        return mod.dirname(text)
    if attr == "folder":
        return mod.basename(mod.dirname(text))
    name = mod.basename(text)
    stem, ext = posixpath.splitext(name)
    return {"name": name, "stem": stem, "ext": ext}[attr]


def _lookup(ph: Placeholder, values: Mapping[str, Scalar], where: Where) -> Scalar:
    if ph.name not in values:
        known = ", ".join(sorted(values)) or "none"
        raise where.error(f"placeholder {ph.text} is unknown or unbound (bound slots: {known})",
                          f"declare a slot {ph.name!r} or fix the spelling")
    value = values[ph.name]
    if ph.attr is None:
        return value
    if not isinstance(value, str):
        raise where.error(f"placeholder {ph.text} takes a path part of a non-path value {value!r}",
                          f"use {{{{{ph.name}}}}} without .{ph.attr}")
    return path_part(value, ph.attr)


def render_text(text: str, values: Mapping[str, Scalar], where: Where = Where()) -> str:
    """`text` with every placeholder replaced by its value as text."""
    find_placeholders(text, where)

    def sub(m: re.Match[str]) -> str:
        return str(_lookup(Placeholder(m.group(1), m.group(2), m.group(0)), values, where))

    return PLACEHOLDER.sub(sub, text)


def render_data(obj: Any, values: Mapping[str, Scalar], where: Where = Where(), *, keep_types: bool = True) -> Any:
    """Nested data with every string rendered; a string that is one whole placeholder keeps the value's type
    (without `keep_types`, as for GUI steps, where typed text and shown text stay text, it becomes its text)."""
    if isinstance(obj, str):
        whole = PLACEHOLDER.fullmatch(obj)
        if whole and keep_types:
            return _lookup(Placeholder(whole.group(1), whole.group(2), whole.group(0)), values, where)
        return render_text(obj, values, where)
    if isinstance(obj, Mapping):
        return {key: render_data(item, values, where.at(str(key)), keep_types=keep_types)
                for key, item in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [render_data(item, values, Where(where.path, where.task, f"{where.field}[{i}]"), keep_types=keep_types)
                for i, item in enumerate(obj)]
    return obj


def has_placeholder(obj: Any) -> bool:
    """Whether any string in `obj` still contains `{{` or `}}` (an unrendered placeholder). Keys are not
    looked at, as in `walk_strings`; no locations are made (every composed task is checked at each start)."""
    if isinstance(obj, str):
        return STRAY_BRACES.search(obj) is not None
    if isinstance(obj, Mapping):
        return any(has_placeholder(v) for v in obj.values())
    if isinstance(obj, (list, tuple)):
        return any(has_placeholder(v) for v in obj)
    return False
