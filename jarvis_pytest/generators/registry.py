"""The generator registry: name → function(**args) -> bytes."""

from __future__ import annotations

from typing import Any, Callable

from jarvis_pytest.errors import ConfigError

GeneratorFunc = Callable[..., bytes]
GENERATORS: dict[str, GeneratorFunc] = {}


def generator(name: str) -> Callable[[GeneratorFunc], GeneratorFunc]:
    """Register `func` under `name` (names are unique)."""

    def deco(func: GeneratorFunc) -> GeneratorFunc:
        if name in GENERATORS and GENERATORS[name] is not func:
            raise ValueError(f"generator {name!r} registered twice")
        GENERATORS[name] = func
        return func

    return deco


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
