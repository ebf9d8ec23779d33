"""The evaluator registry: name → function(state, **args) -> Verdict."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.naming import Registry


@dataclass(frozen=True)
class Verdict:
    """The outcome of one evaluator: passed, and a reason naming what was expected and what was found."""

    passed: bool
    reason: str

    @classmethod
    def check(cls, ok: bool, expected: str, found: str) -> "Verdict":
        return cls(bool(ok), f"expected {expected}, found {found}")


EvaluatorFunc = Callable[..., Verdict]
EVALUATORS: Registry = Registry("evaluator")
evaluator = EVALUATORS.register  # @evaluator("name") registers a check under a unique name


def get_evaluator(name: str) -> EvaluatorFunc:
    try:
        return EVALUATORS[name]
    except KeyError:
        raise ConfigError(f"unknown evaluator {name!r}", field="evaluate.func",
                          fix=f"use one of {sorted(EVALUATORS)}") from None
