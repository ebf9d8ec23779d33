"""The agent protocol every agent implements (built-in ones and the model adapters under `agents/`).

At each step the harness calls ``agent.act(observations, history)`` with the observations of every platform of
the benchmark (devices a task does not use carry only their initial screenshot, ``available=False``) and the
history of earlier steps, errors included. The agent answers one ``AgentStep``: the target platform, the action
in the unified action space, and its reasoning. An agent that cannot produce a valid action returns a step with
``error`` set and ``action=None``; the harness records it and feeds the error back in the history.

What an agent is given is all it is told: the task's instruction, its platforms and the transfer drive's address
and login (`TaskContext`), then each step's observations (screenshots, sizes, accessibility text) and the history
of its own earlier steps. Every one of them holds plain values (strings, numbers, bytes, tuples, dicts), never a
task, a subtask, an evaluator or a device. The solution, the near-miss states and the evaluators' arguments reach
only the built-in oracle, through `jarvis_pytest.agents.oracle.brief`, which nothing in this protocol carries.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

from jarvis_pytest.devices.actions import Action
from jarvis_pytest.devices.base import Observation


@dataclass(frozen=True)
class TaskContext:
    """What an agent is told about a task before it starts (and nothing more: no solution, no evaluator)."""

    task_id: str
    instruction: str
    platforms: tuple[str, ...]  # the platforms the task uses
    transfer: dict[str, str] = field(default_factory=dict)  # url, user, password, folder, flavour of the drive
    trial: int = 1  # which of the run's `--trials` this is; each trial starts on fresh devices
    seed: int | None = None  # for the agent's sampling: from the task id and the trial, the same on any machine


@dataclass
class AgentStep:
    """One decision of an agent."""

    platform: str | None
    action: Action | None
    reasoning: str = ""
    raw_output: str = ""  # the model's text(s), verbatim, for the trajectory
    error: str | None = None  # the agent's own error (unparseable output, ...)
    usage: dict[str, int] = field(default_factory=dict)  # prompt_tokens, completion_tokens
    extra: dict[str, Any] = field(default_factory=dict)  # e.g. the grounder's answer and the mapped point


@dataclass(frozen=True)
class HistoryEntry:
    """One earlier step as the agent sees it: its plan and what the framework said about it."""

    index: int
    platform: str | None
    plan: str
    action: dict[str, Any] | None
    error: str | None = None


@runtime_checkable
class Agent(Protocol):
    """The interface the harness drives."""

    name: str

    def reset(self, task: TaskContext) -> None: ...

    def act(self, observations: dict[str, Observation], history: list[HistoryEntry]) -> AgentStep: ...

    def config(self) -> dict[str, Any]:
        """The agent's configuration as recorded in results (never secrets such as API keys)."""
        ...
