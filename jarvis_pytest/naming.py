"""Registries of functions by unique name (evaluators, file generators)."""

from __future__ import annotations

from typing import Callable, TypeVar

F = TypeVar("F", bound=Callable)


class Registry(dict):
    """name → function; `register(name)` is a decorator that refuses a second function under one name."""

    def __init__(self, kind: str):
        super().__init__()
        self.kind = kind

    def register(self, name: str) -> Callable[[F], F]:
        def deco(func: F) -> F:
            if name in self and self[name] is not func:
                raise ValueError(f"{self.kind} {name!r} registered twice")
            self[name] = func
            return func

        return deco
