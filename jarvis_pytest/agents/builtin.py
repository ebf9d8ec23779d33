"""The built-in agents: `oracle` (the tasks' reference solutions), `gui-oracle` (their GUI solutions, actions
only), `noop` (DONE at once), `replay` (a trajectory)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from jarvis_pytest.agents.gui_oracle import GuiOracleAgent
from jarvis_pytest.agents.oracle import OracleAgent
from jarvis_pytest.agents.protocol import AgentStep, HistoryEntry, TaskContext
from jarvis_pytest.devices.actions import Done, parse_action
from jarvis_pytest.devices.base import Observation
from jarvis_pytest.errors import ConfigError


class NoopAgent:
    """Declares success immediately: the floor every evaluator must fail (QC's "not already solved")."""

    name = "noop"

    def __init__(self, options: dict[str, Any] | None = None):
        self.options = dict(options or {})

    def reset(self, task: TaskContext) -> None:
        pass

    def act(self, observations: dict[str, Observation], history: list[HistoryEntry]) -> AgentStep:
        return AgentStep(platform=None, action=Done(), reasoning="noop agent: done without acting")

    def config(self) -> dict[str, Any]:
        return {"name": self.name}


class ReplayAgent:
    """Replays the actions of a recorded `traj.jsonl` (option `file`), then DONE."""

    name = "replay"

    def __init__(self, options: dict[str, Any] | None = None):
        self.options = dict(options or {})
        path = self.options.get("file")
        if not path:
            raise ConfigError("the replay agent needs a trajectory file", field="--agent-option file",
                              fix="pass --agent-option file=reports/<run>/tasks/<task>/traj.jsonl")
        self.path = Path(path)
        if not self.path.is_file():
            raise ConfigError("no such trajectory file", path=self.path, field="--agent-option file",
                              fix="point it at an existing traj.jsonl")
        self.steps: list[dict[str, Any]] = []

    def reset(self, task: TaskContext) -> None:
        self.steps = []
        for n, line in enumerate(self.path.read_text().splitlines(), 1):
            if not line.strip():
                continue
            try:
                rec = json.loads(line)
            except json.JSONDecodeError as exc:
                raise ConfigError(f"line {n} is not JSON ({exc})", path=self.path,
                                  fix="use a traj.jsonl written by jarvis-pytest") from exc
            if rec.get("action") and rec["action"].get("type") not in ("DONE", "FAIL") \
                    and not (rec.get("extra") or {}).get("commands"):  # the oracle's commands are not actions
                self.steps.append(rec)

    def act(self, observations: dict[str, Observation], history: list[HistoryEntry]) -> AgentStep:
        if not self.steps:
            return AgentStep(platform=None, action=Done(), reasoning="replay finished")
        rec = self.steps.pop(0)
        return AgentStep(platform=rec.get("platform"), action=parse_action(rec["action"]),
                         reasoning=rec.get("reasoning", ""), raw_output=rec.get("raw_output", ""))

    def config(self) -> dict[str, Any]:
        return {"name": self.name, "file": str(self.path)}


#: `oracle` and `gui-oracle` are told their solutions by `oracle.brief`, which recognises their class objects, not
#: these names.
BUILTIN_AGENTS = {"oracle": OracleAgent, "gui-oracle": GuiOracleAgent, "noop": NoopAgent, "replay": ReplayAgent}
