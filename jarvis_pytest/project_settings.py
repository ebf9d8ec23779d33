"""The project's own settings: the `[tool.jarvis]` table of pyproject.toml in pytest's root directory (engines,
a Ray cluster), read by the options that fall back to it."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from jarvis_pytest.errors import ConfigError


def tool_table(rootdir: Path) -> tuple[Path, dict[str, Any]]:
    """rootdir/pyproject.toml and its `[tool.jarvis]` table (empty when there is no file or no table); a file that
    is not TOML is one ConfigError naming it."""
    pyproject = rootdir / "pyproject.toml"
    if not pyproject.is_file():
        return pyproject, {}
    try:
        return pyproject, tomllib.loads(pyproject.read_text(encoding="utf-8")).get("tool", {}).get("jarvis", {})
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"not valid TOML ({exc})", path=pyproject, fix="correct the file") from None
