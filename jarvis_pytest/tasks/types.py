"""The slot type system (paper §4.1): a tree of named types read from one data file, `tasks/types.json`.

File format: ``{"types": {"<type>": "<parent>" | null, ...}}`` (an optional ``"$comment"`` string aside).
``t ⪯ u`` holds iff ``u`` is ``t`` or one of its ancestors; an output of type ``t`` may feed an input of type
``u`` iff ``t ⪯ u``. Every file type must descend from ``file`` (:data:`FILE_TYPE`), the widest file type: the
built-in file-transfer task accepts a ``file`` and hands on the same, more specific, type (see ``transfer.py``),
which is how "the transfer accepts any file" is modelled. Only file-typed slots may cross platforms.
"""

from __future__ import annotations

import difflib
import json
import re
from pathlib import Path
from typing import Mapping

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.paths import TYPES_FILE as REPO_TYPES_FILE

FILE_TYPE = "file"
TYPE_NAME = re.compile(r"^[a-z][a-z0-9_]*$")


class TypeSystem:
    """A validated type tree: `parents` maps every declared type to its parent (None for a root)."""

    def __init__(self, parents: Mapping[str, str | None], source: Path | str | None = None):
        self.source = None if source is None else Path(source)
        self.parents: dict[str, str | None] = {name: parents[name] for name in sorted(parents)}
        self._validate()

    @classmethod
    def load(cls, path: Path | str) -> "TypeSystem":
        """Read and validate a types file; every problem is a ConfigError naming the file and the type."""
        path = Path(path)
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise ConfigError("no such types file", path=path,
                              fix="create tasks/types.json or pass --types FILE") from None
        except json.JSONDecodeError as exc:
            raise ConfigError(f"not valid JSON: {exc.msg} at line {exc.lineno} column {exc.colno}", path=path,
                              fix="fix the JSON syntax") from None
        if not isinstance(data, dict) or not isinstance(data.get("types"), dict):
            raise ConfigError('expected an object {"types": {"<type>": "<parent>" | null}}', path=path,
                              field="types", fix="put the type tree under a top-level `types` object")
        extra = sorted(set(data) - {"types", "$comment"})
        if extra:
            raise ConfigError(f"unexpected top-level key {extra[0]!r}", path=path, field=extra[0],
                              fix="keep only `types` (and `$comment`)")
        return cls(data["types"], source=path)

    # -- validation ---------------------------------------------------------------------------------------
    def _error(self, message: str, name: str, fix: str) -> ConfigError:
        return ConfigError(message, path=self.source, field=f"types.{name}", fix=fix)

    def _validate(self) -> None:
        for name, parent in self.parents.items():
            if not isinstance(name, str) or not TYPE_NAME.match(name):
                raise self._error(f"bad type name {name!r}", str(name), "use lower_snake_case names")
            if parent is not None and not isinstance(parent, str):
                raise self._error(f"the parent of {name!r} must be a type name or null, not {parent!r}", name,
                                  "write the parent's name as a string, or null for a root")
            if parent is not None and parent not in self.parents:
                raise self._error(f"type {name!r} has an undeclared parent {parent!r}", name,
                                  f"declare {parent!r} too{self._suggest(parent)}")
        for name in self.parents:
            chain = [name]
            node = self.parents[name]
            while node is not None:
                if node in chain:
                    cycle = " → ".join(chain[chain.index(node):] + [node])
                    raise self._error(f"cycle in the type hierarchy: {cycle}", name,
                                      "make one of these types a root (parent null) or re-parent it")
                chain.append(node)
                node = self.parents[node]
        if FILE_TYPE not in self.parents or self.parents[FILE_TYPE] is not None:
            raise ConfigError(f"the root file type {FILE_TYPE!r} must be declared with parent null",
                              path=self.source, field=f"types.{FILE_TYPE}",
                              fix=f'add "{FILE_TYPE}": null and make every file type descend from it')

    def _suggest(self, name: str) -> str:
        close = difflib.get_close_matches(name, list(self.parents), n=1)
        return f" (or did you mean {close[0]!r}?)" if close else ""

    # -- queries ------------------------------------------------------------------------------------------
    def __contains__(self, name: object) -> bool:
        return name in self.parents

    @property
    def names(self) -> list[str]:
        """Every declared type, sorted."""
        return list(self.parents)

    def ancestors(self, name: str) -> list[str]:
        """`name` and its ancestors, nearest first."""
        self._known(name)
        out = []
        node: str | None = name
        while node is not None:
            out.append(node)
            node = self.parents[node]
        return out

    def is_subtype(self, t: str, u: str) -> bool:
        """t ⪯ u: `u` is `t` or an ancestor of `t`."""
        self._known(u)
        return u in self.ancestors(t)

    def is_file(self, t: str) -> bool:
        """Whether `t` is a file type (t ⪯ file)."""
        return self.is_subtype(t, FILE_TYPE)

    def _known(self, name: str) -> None:
        if name not in self.parents:
            raise ConfigError(f"unknown slot type {name!r}", path=self.source,
                              fix=f"declare it in the types file{self._suggest(name)}")

    def require(self, name: str, *, path: object = None, field: str | None = None, task: str | None = None) -> None:
        """Raise a ConfigError naming the task file, field and task when `name` is not a declared type."""
        if name not in self.parents:
            where = f"task {task!r}: " if task else ""
            raise ConfigError(f"{where}unknown slot type {name!r}", path=path, field=field,
                              fix=f"declare it in {self.source or 'tasks/types.json'}{self._suggest(name)}")

    def to_json(self) -> dict[str, str | None]:
        """`{"type": "parent" | None}` for every declared type, sorted by name."""
        return dict(self.parents)

    def tree(self) -> str:
        """The hierarchy as an indented text tree."""
        children: dict[str | None, list[str]] = {}
        for name, parent in self.parents.items():
            children.setdefault(parent, []).append(name)
        lines: list[str] = []

        def walk(node: str, depth: int) -> None:
            lines.append("  " * depth + node)
            for child in children.get(node, []):
                walk(child, depth + 1)

        for root in children.get(None, []):
            walk(root, 0)
        return "\n".join(lines)


def default_types_path(library: Path | str | None = None) -> Path:
    """The types file for a library: `<library>/types.json` if present, else the repository's `tasks/types.json`."""
    if library is not None:
        candidate = Path(library) / "types.json"
        if candidate.is_file():
            return candidate
    return REPO_TYPES_FILE


def load_types(path: Path | str | None = None, library: Path | str | None = None) -> TypeSystem:
    """Load the type system from `path`, or the default one for `library` (see :func:`default_types_path`)."""
    return TypeSystem.load(path if path is not None else default_types_path(library))
