"""The built-in agents: `oracle` (the tasks' reference solutions), `gui-oracle` (their GUI solutions, actions
only), `noop` (DONE at once), `replay` (a trajectory), `human` (a person in the browser player, `jarvis play`)."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

from jarvis_pytest.agents.gui_oracle import GuiOracleAgent
from jarvis_pytest.agents.oracle import OracleAgent
from jarvis_pytest.agents.protocol import AgentStep, HistoryEntry, TaskContext
from jarvis_pytest.devices.actions import Done, parse_action
from jarvis_pytest.devices.base import Observation
from jarvis_pytest.errors import ConfigError
from jarvis_pytest.player.agent import HumanAgent


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


PACES = ("auto", "recorded", "none")
MAX_WAIT = 5.0  # seconds the replay waits before one action at most, where it keeps the recorded pace


class ReplayAgent:
    """Replays the actions of a recorded `traj.jsonl` (option `file`), then DONE.

    Option `pace`: `recorded` waits before each action as long as the recording's agent took to decide it (its
    step's `agent_ms`, at most `max_wait` seconds, default 5): the time the device had to settle before it; `none`
    acts at once; `auto` (the default) is `recorded` for a run a person made in the player (its steps carry
    `extra.player`: a person acts on the live screen once the device has settled, so the pace is part of what they
    did) and `none` for any other."""

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
        self.pace = str(self.options.get("pace", "auto"))
        if self.pace not in PACES:
            raise ConfigError(f"pace {self.pace!r} is not one of {', '.join(PACES)}", field="--agent-option pace",
                              fix="give auto, recorded or none")
        try:
            self.max_wait = float(self.options.get("max_wait", MAX_WAIT))
        except ValueError:
            self.max_wait = -1.0
        if not 0 <= self.max_wait <= 60:
            raise ConfigError(f"max_wait {self.options.get('max_wait')!r} is not 0 to 60 seconds",
                              field="--agent-option max_wait", fix="give seconds, e.g. 5")
        self.steps: list[dict[str, Any]] = []
        self.paced = False

    def reset(self, task: TaskContext) -> None:
        self.steps = []
        by_person = False
        for n, line in enumerate(self.path.read_text().splitlines(), 1):
            if not line.strip():
                continue
            try:
                rec = json.loads(line)
            except json.JSONDecodeError as exc:
                raise ConfigError(f"line {n} is not JSON ({exc})", path=self.path,
                                  fix="use a traj.jsonl written by jarvis-pytest") from exc
            by_person = by_person or "player" in (rec.get("extra") or {})
            if rec.get("action") and rec["action"].get("type") not in ("DONE", "FAIL") \
                    and not (rec.get("extra") or {}).get("commands"):  # the oracle's commands are not actions
                self.steps.append(rec)
        self.paced = self.pace == "recorded" or (self.pace == "auto" and by_person)

    def act(self, observations: dict[str, Observation], history: list[HistoryEntry]) -> AgentStep:
        if not self.steps:
            return AgentStep(platform=None, action=Done(), reasoning="replay finished")
        rec = self.steps.pop(0)
        waited = 0.0
        if self.paced:
            recorded = rec.get("agent_ms")
            if isinstance(recorded, (int, float)) and not isinstance(recorded, bool) and recorded > 0:
                waited = min(recorded / 1000, self.max_wait)
                time.sleep(waited)
        return AgentStep(platform=rec.get("platform"), action=parse_action(rec["action"]),
                         reasoning=rec.get("reasoning", ""), raw_output=rec.get("raw_output", ""),
                         extra={"replayed": rec.get("index"), "waited_s": round(waited, 3)} if self.paced else {})

    def config(self) -> dict[str, Any]:
        config = {"name": self.name, "file": str(self.path)}
        config.update({k: self.options[k] for k in ("pace", "max_wait") if k in self.options})
        return config


#: `oracle` and `gui-oracle` are told their solutions by `oracle.brief`, which recognises their class objects, not
#: these names; `human` is handed a view of the devices' screens there, for the player's page.
BUILTIN_AGENTS = {"oracle": OracleAgent, "gui-oracle": GuiOracleAgent, "noop": NoopAgent, "replay": ReplayAgent,
                  "human": HumanAgent}
