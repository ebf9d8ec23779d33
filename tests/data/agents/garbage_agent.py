"""A user agent loaded as `garbage_agent:GarbageAgent` (module:Class): on each step it emits another kind of
garbage (a NaN scroll, a SCROLL of 1e9, a lone surrogate to type, a script that exits the interpreter, an
exception of its own code) and at last calls `sys.exit()` itself (issue 37: all of it is the agent's failure)."""

import sys

from jarvis_pytest.agents.protocol import AgentStep
from jarvis_pytest.devices import actions as A


def _raise():
    raise ValueError("the adapter could not read its model's answer")


class GarbageAgent:
    name = "garbage"

    def __init__(self, options=None):
        self.moves = []

    def reset(self, task):
        self.moves = [
            AgentStep("ubuntu", A.Scroll.model_construct(dx=0, dy=float("nan"))),
            AgentStep("ubuntu", {"type": "SCROLL", "dy": 1e9}, reasoning="scroll \ud800 a lot"),
            AgentStep("ubuntu", A.Typing.model_construct(text="x\udfff" * 500_000)),
            AgentStep("ubuntu", A.Pyautogui(script="import os\nos._exit(1)")),
            _raise,
            lambda: sys.exit("stuck"),
        ]

    def act(self, observations, history):
        move = self.moves.pop(0)
        return move() if callable(move) else move

    def config(self):
        return {"name": self.name}


class ResetRaises(GarbageAgent):
    """Its `reset` raises (an adapter bug before its first step): the agent's failure, not an `error`."""

    def reset(self, task):
        raise KeyError("the adapter's reset found no prompt template")
