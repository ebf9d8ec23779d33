"""The generator registry: name → function(**args) -> bytes."""

from __future__ import annotations

from typing import Any, Callable

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.naming import Registry

GeneratorFunc = Callable[..., bytes]
GENERATORS: Registry = Registry("generator")
generator = GENERATORS.register  # @generator("name") registers a file generator under a unique name


def generate(name: str, args: dict[str, Any]) -> bytes:
    """The bytes of generator `name` for `args`; a clear error for an unknown name or bad arguments."""
    if name not in GENERATORS:
        raise ConfigError(f"unknown file generator {name!r}", field="config.upload_file.generator",
                          fix=f"use one of {sorted(GENERATORS)}")
    try:
        return GENERATORS[name](**args)
    except TypeError as exc:
        raise ConfigError(f"generator {name!r}: {exc}", field="config.upload_file.args",
                          fix="pass the generator's keyword arguments (see its docstring)") from None
