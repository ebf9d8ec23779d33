"""Finding an agent by name: built-ins, the adapter modules under the top-level ``agents/`` folder, ``module:Class``.

``load_agent(name, options)`` is what the harness calls. ``options`` holds the ``--agent-option KEY=VALUE`` pairs
(strings) and, under ``"planner"`` and ``"grounder"``, dicts with ``base_url``, ``model`` and ``api_key`` from
the command line or the environment (see :mod:`jarvis_pytest.llm.config` for every source).

Adapter modules are plain ``.py`` files loaded by path (no package needed). A module declares what it provides:

* ``GROUNDERS = {"holo2": Holo2Grounder}`` — a grounding adapter (a :class:`Grounder` subclass); each name also
  becomes a planner–grounder agent of the same name;
* ``AGENTS = {"my-agent": factory}`` — any other agent; ``factory(options)`` returns an object with the
  :class:`~jarvis_pytest.agents.protocol.Agent` interface.
"""

from __future__ import annotations

import importlib
import json
import importlib.util
import sys
import threading
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from jarvis_pytest.agents.builtin import BUILTIN_AGENTS
from jarvis_pytest.agents.grounding import Grounder
from jarvis_pytest.agents.planner import build_planner_grounder
from jarvis_pytest.agents.protocol import Agent
from jarvis_pytest.errors import ConfigError
from jarvis_pytest.paths import AGENTS_DIR

AgentFactory = Callable[[dict[str, Any]], Agent]

#: The built-in agents (name → factory taking the options dict). The harness's oracle, noop and replay live in
#: jarvis_pytest/agents/builtin.py; add further built-ins there or here.
BUILTIN: dict[str, AgentFactory] = dict(BUILTIN_AGENTS)

#: The folder of adapter modules: the repository's top-level ``agents/``.
_MODULE_PREFIX = "jarvis_agents_"


@dataclass
class Catalog:
    """What the adapter folder provides, and which file provides it."""

    agents: dict[str, AgentFactory] = field(default_factory=dict)
    grounders: dict[str, type[Grounder]] = field(default_factory=dict)
    sources: dict[str, Path] = field(default_factory=dict)
    errors: dict[Path, str] = field(default_factory=dict)


_CACHE: dict[Path, Catalog] = {}
_LOCK = threading.Lock()


def _load_module(path: Path):
    name = _MODULE_PREFIX + path.stem
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot load {path}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses and pickling look modules up by name
    try:
        spec.loader.exec_module(module)
    except BaseException:
        sys.modules.pop(name, None)
        raise
    return module


def _planner_grounder_factory(name: str, grounder: type[Grounder]) -> AgentFactory:
    return lambda options: build_planner_grounder(name, grounder, options)


def _claim(catalog: Catalog, name: str, path: Path) -> None:
    other = catalog.sources.get(name)
    if other is not None and other != path:
        raise ConfigError(f"agent name {name!r} is declared twice: in {other} and in {path}", path=path,
                          fix="rename one of them")
    catalog.sources[name] = path


def discover(agents_dir: Path | None = None, *, refresh: bool = False) -> Catalog:
    """Load every ``*.py`` of `agents_dir` (default: the repository's ``agents/``) once and collect what they
    declare. A module that fails to import is recorded in ``errors`` (and warned about), not raised."""
    folder = (agents_dir or AGENTS_DIR).resolve()
    with _LOCK:
        if not refresh and folder in _CACHE:
            return _CACHE[folder]
        catalog = Catalog()
        for path in sorted(folder.glob("*.py")) if folder.is_dir() else []:
            if path.name.startswith("_"):
                continue
            try:
                module = _load_module(path)
            except Exception as exc:  # a broken adapter must not hide the others
                catalog.errors[path] = f"{type(exc).__name__}: {exc}"
                warnings.warn(f"agents: {path} failed to load: {exc}", stacklevel=2)
                continue
            for name, grounder in sorted((getattr(module, "GROUNDERS", None) or {}).items()):
                if not (isinstance(grounder, type) and issubclass(grounder, Grounder)):
                    raise ConfigError(f"GROUNDERS[{name!r}] is not a Grounder subclass", path=path,
                                      field="GROUNDERS", fix="map names to Grounder subclasses")
                _claim(catalog, name, path)
                catalog.grounders[name] = grounder
                catalog.agents[name] = _planner_grounder_factory(name, grounder)
            for name, factory in sorted((getattr(module, "AGENTS", None) or {}).items()):
                if not callable(factory):
                    raise ConfigError(f"AGENTS[{name!r}] is not callable", path=path, field="AGENTS",
                                      fix="map names to factories taking the options dict")
                if name not in catalog.grounders:
                    _claim(catalog, name, path)
                catalog.agents[name] = factory
        _CACHE[folder] = catalog
        return catalog


def known_agents(agents_dir: Path | None = None) -> list[str]:
    """Every agent name `load_agent` resolves without a ``module:Class`` path."""
    return sorted(set(BUILTIN) | set(discover(agents_dir).agents))


def _unknown(kind: str, name: str, names: list[str], catalog: Catalog) -> ConfigError:
    broken = "".join(f"; {path} failed to load ({err})" for path, err in sorted(catalog.errors.items()))
    return ConfigError(f"unknown {kind} {name!r}; known: {', '.join(names) or '(none)'}{broken}",
                       fix=f"use one of the known names, or module:Class for your own {kind}")


def _import_object(spec: str) -> Any:
    module_name, _, attr = spec.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise ConfigError(f"cannot import {module_name!r} ({exc})", field="--agent",
                          fix="make the module importable (installed or on PYTHONPATH)") from None
    obj = module
    for part in attr.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise ConfigError(f"{module_name!r} has no {attr!r}", field="--agent",
                              fix="give module:Class with an existing class or factory") from None
    return obj


def load_agent(name: str, options: dict[str, Any] | None = None, *, agents_dir: Path | None = None) -> Agent:
    """The agent `name` built with `options`: a built-in, a name from the adapter folder, or ``module:Class``
    (called with the options dict). Unknown names raise ConfigError listing the known ones."""
    options = dict(options or {})
    if name in BUILTIN:
        return _checked(name, lambda: BUILTIN[name](options))
    catalog = discover(agents_dir)
    if name in catalog.agents:
        return _checked(name, lambda: catalog.agents[name](options))
    if ":" in name:
        obj = _import_object(name)
        if isinstance(obj, type) and issubclass(obj, Grounder):
            return _checked(name, lambda: build_planner_grounder(obj.name or name, obj, options))
        return _checked(name, lambda: obj(options))
    raise _unknown("agent", name, known_agents(agents_dir), catalog)


def _checked(name: str, build: Callable[[], Any]) -> Agent:
    """The agent `build` makes, once it is shown to be one: built without raising, with callable `reset`, `act`
    and `config`, and a `config()` that gives a dict of plain JSON (recorded with every result). Otherwise one ConfigError
    naming the agent, never a traceback."""
    def fail(problem: str) -> ConfigError:
        return ConfigError(f"agent {name!r}: {problem}", field="--agent",
                           fix="fix the adapter (see agents/README.md for the protocol) or choose another agent")

    try:
        agent = build()
    except ConfigError:
        raise
    except Exception as exc:
        raise fail(f"building it raised {exc.__class__.__name__}: {exc}") from None
    missing = [m for m in ("reset", "act", "config") if not callable(getattr(agent, m, None))]
    if missing:
        raise fail(f"it has no {', '.join(missing)} method (a {type(agent).__name__})")
    try:
        config = agent.config()
    except Exception as exc:
        raise fail(f"its config() raised {exc.__class__.__name__}: {exc}") from None
    if not isinstance(config, dict):
        raise fail(f"its config() gave a {type(config).__name__}, not a dict")
    try:
        json.dumps(config, allow_nan=False)
    except (TypeError, ValueError, RecursionError) as exc:
        raise fail(f"its config() is not plain JSON ({exc})") from None
    return agent


def load_grounder_class(name: str, *, agents_dir: Path | None = None) -> type[Grounder]:
    """The grounding adapter class `name` (``holo2``, ...) or ``module:Class``."""
    catalog = discover(agents_dir)
    if name in catalog.grounders:
        return catalog.grounders[name]
    if ":" in name:
        obj = _import_object(name)
        if isinstance(obj, type) and issubclass(obj, Grounder):
            return obj
        raise ConfigError(f"{name!r} is not a Grounder subclass", field="--model",
                          fix="give module:Class of a Grounder subclass")
    raise _unknown("grounding model", name, sorted(catalog.grounders), catalog)
