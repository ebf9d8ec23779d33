"""Modules that third-party code imports eagerly but this harness rarely uses, loaded on first use instead.

`import docker` imports paramiko (its ssh transport), 0.19 s of CPU in every process that talks to Docker: the
controller, each xdist worker, each `jarvis` command. Only an `ssh://` engine uses it. Registered here as a
stand-in module, paramiko is imported for real when code first asks the stand-in for one of its attributes, so an
ssh:// engine works as before and every other process skips the cost. (The standard library's `LazyLoader` does
not do here: an `import paramiko` statement reads the module's `__spec__`, which loads a lazy module at once.)
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
import types

LAZY = ("paramiko",)


class _OnFirstUse(types.ModuleType):
    """Stands in for a module in `sys.modules` until an attribute it lacks is asked for; then imports the module
    (which replaces it in `sys.modules`) and answers from it."""

    def __getattr__(self, attr: str):
        real = self.__dict__.get("_real")
        if real is None:
            if sys.modules.get(self.__name__) is self:
                del sys.modules[self.__name__]
            real = importlib.import_module(self.__name__)
            self.__dict__["_real"] = real
        return getattr(real, attr)


def load_on_first_use(name: str) -> None:
    """Make `import name` return a stand-in that imports the module on first use (nothing when `name` is
    already imported or not installed)."""
    if name not in sys.modules and importlib.util.find_spec(name) is not None:
        sys.modules[name] = _OnFirstUse(name)


def install() -> None:
    """Register a stand-in for each module of `LAZY` (run by `jarvis_pytest.infra` before docker is imported)."""
    for name in LAZY:
        load_on_first_use(name)
