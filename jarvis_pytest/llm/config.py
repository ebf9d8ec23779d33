"""Where a model endpoint's settings come from: agent options, environment, ``[tool.jarvis]`` in pyproject.toml.

A role is ``planner`` or ``grounder``. For each field the first source that has a value wins:

1. the agent options the harness passes: ``options[role][field]`` (from ``--planner-base-url`` and friends)
   or a flat ``options[f"{role}_{field}"]`` (from ``--agent-option planner_model=...``);
2. the environment: ``JARVIS_PLANNER_BASE_URL``, ``JARVIS_PLANNER_MODEL``, ``JARVIS_PLANNER_API_KEY``, ...;
3. pyproject.toml (the first one found from the working directory upwards)::

       [tool.jarvis.planner]
       base_url = "https://dashscope.aliyuncs.com/compatible-mode/v1"
       model = "qwen3-vl-plus"
       api_key_env = "DASHSCOPE_API_KEY"   # the name of the variable holding the key; keep keys out of files
       timeout = 120

4. the caller's defaults (e.g. an adapter's model name).

``EndpointConfig.public()`` is what may be written to results: it never contains the key.
"""

from __future__ import annotations

import os
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.llm.client import ChatClient

FIELDS = ("base_url", "model", "api_key", "timeout", "max_retries", "max_concurrency")
_NUMERIC = {"timeout": float, "max_retries": int, "max_concurrency": int}
_DEFAULTS: dict[str, Any] = {"timeout": 120.0, "max_retries": 4, "max_concurrency": 4}


@dataclass(frozen=True)
class EndpointConfig:
    """The resolved settings of one role's endpoint."""

    role: str
    base_url: str
    model: str
    api_key: str | None = None
    timeout: float = 120.0
    max_retries: int = 4
    max_concurrency: int = 4

    def __repr__(self) -> str:
        return (f"EndpointConfig(role={self.role!r}, base_url={self.base_url!r}, model={self.model!r}, "
                f"api_key={'***' if self.api_key else None!r})")

    def public(self) -> dict[str, Any]:
        """What identifies the endpoint in results and reports: base URL and model (never the key)."""
        return {"base_url": self.base_url, "model": self.model}

    def client(self, **kwargs: Any) -> ChatClient:
        return ChatClient(self.base_url, self.model, api_key=self.api_key, timeout=self.timeout,
                          max_retries=self.max_retries, max_concurrency=self.max_concurrency, **kwargs)


def find_pyproject(start: Path | None = None) -> Path | None:
    """The nearest pyproject.toml from `start` (default: the working directory) upwards."""
    here = (start or Path.cwd()).resolve()
    for folder in (here, *here.parents):
        candidate = folder / "pyproject.toml"
        if candidate.is_file():
            return candidate
    return None


def pyproject_table(path: Path | None) -> dict[str, Any]:
    """The ``[tool.jarvis]`` table of `path` ({} when there is none)."""
    if path is None or not path.is_file():
        return {}
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"not valid TOML ({exc})", path=path, fix="fix the syntax of pyproject.toml") from None
    table = data.get("tool", {}).get("jarvis", {})
    return table if isinstance(table, dict) else {}


def resolve_endpoint(role: str, options: Mapping[str, Any] | None = None, *, defaults: Mapping[str, Any] | None = None,
                     env: Mapping[str, str] | None = None, pyproject: Path | None | bool = True) -> EndpointConfig:
    """Resolve `role`'s endpoint from the sources above; a missing base URL or model is a ConfigError that says
    every place it could be set. `pyproject=True` searches from the working directory, a Path uses that file,
    False/None skips it."""
    options = options or {}
    env = os.environ if env is None else env
    nested = options.get(role) if isinstance(options.get(role), Mapping) else {}
    path = find_pyproject() if pyproject is True else (pyproject or None)
    table = pyproject_table(path)
    file_role = table.get(role) if isinstance(table.get(role), Mapping) else {}
    values: dict[str, Any] = {}
    for name in FIELDS:
        for candidate in (nested.get(name), options.get(f"{role}_{name}"), env.get(f"JARVIS_{role.upper()}_{name.upper()}"),
                          _from_file(file_role, table, role, name, env), (defaults or {}).get(name), _DEFAULTS.get(name)):
            if candidate not in (None, ""):
                values[name] = candidate
                break
    for name in ("base_url", "model"):
        if not values.get(name):
            flag = f"--{role}-{name.replace('_', '-')}"
            raise ConfigError(f"no {role} {name.replace('_', ' ')} configured", field=f"{role}.{name}",
                              fix=f"pass {flag}, set JARVIS_{role.upper()}_{name.upper()}, or add {name} = ... "
                                  f"under [tool.jarvis.{role}] in pyproject.toml")
    base_url = str(values["base_url"])
    if not base_url.startswith(("http://", "https://")):
        raise ConfigError(f"{role} base URL {base_url!r} is not an http(s) URL", field=f"{role}.base_url",
                          fix="give the API root, e.g. http://127.0.0.1:8000/v1")
    for name, kind in _NUMERIC.items():
        try:
            values[name] = kind(values[name])
        except (TypeError, ValueError):
            raise ConfigError(f"{role} {name} must be a number, got {values[name]!r}", field=f"{role}.{name}",
                              fix=f"pass e.g. --agent-option {role}_{name}={_DEFAULTS[name]}") from None
    return EndpointConfig(role=role, base_url=base_url, model=str(values["model"]),
                          api_key=str(values["api_key"]) if values.get("api_key") else None,
                          timeout=values["timeout"], max_retries=values["max_retries"],
                          max_concurrency=values["max_concurrency"])


def _from_file(file_role: Mapping[str, Any], table: Mapping[str, Any], role: str, name: str,
               env: Mapping[str, str]) -> Any:
    if name == "api_key":
        var = file_role.get("api_key_env") or table.get(f"{role}_api_key_env")
        if var:
            return env.get(str(var))
    return file_role.get(name, table.get(f"{role}_{name}"))
