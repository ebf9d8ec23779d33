"""The built-in agents: `oracle` (the tasks' reference solutions), `noop` (DONE at once), `replay` (a trajectory)."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

from jarvis_pytest.agents.protocol import AgentStep, HistoryEntry, TaskContext
from jarvis_pytest.devices.actions import Done, Fail, Wait, parse_action
from jarvis_pytest.devices.base import Device, Observation
from jarvis_pytest.errors import ConfigError, DeviceFault


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


class OracleAgent:
    """Executes each subtask's reference solution with its slot values bound.

    A solution step is either `{"action": {...}}` (an action of the unified action space, sent through the
    harness like any agent's action) or `{"command": "...", "user": ..., "platform": ...}` (run on the device
    directly; the oracle is the one agent the harness hands its devices, through `attach_devices`). A step's
    platform defaults to its subtask's platform. Each command is one step of the trajectory, on its device, with
    the command, its return code, its time and the end of its output (as a WAIT(0) action, so replays skip it).
    A failing command ends the task with FAIL and the command's output as reasoning.
    """

    name = "oracle"

    def __init__(self, options: dict[str, Any] | None = None):
        self.options = dict(options or {})
        self.devices: dict[str, Device] = {}
        self.queue: list[tuple[str, dict[str, Any]]] = []
        self.last_platform: str | None = None
        self.failed: AgentStep | None = None

    def reset(self, task: TaskContext) -> None:
        # in a composed task every subtask's application is open: before a subtask's first GUI step its window
        # (the template's `window`) is brought to the front; a file an upstream subtask made is opened first
        # (`opens`: set-up held those steps back, the instruction asks for them)
        composed = len(task.subtasks) > 1
        self.queue = []
        for sub in task.subtasks:
            for opener in sub.opens or []:
                self.queue.append((opener.platform or sub.platform, ("open", opener)))
            focus = composed and bool(sub.window)
            for step in sub.solution:
                if focus and step.action is not None:
                    self.queue.append((step.platform or sub.platform, ("focus", sub.window)))
                    focus = False
                self.queue.append((step.platform or sub.platform, step))
        self.last_platform = task.platforms[0] if task.platforms else None
        self.failed = None

    def attach_devices(self, devices: dict[str, Device]) -> None:
        self.devices = devices

    def act(self, observations: dict[str, Observation], history: list[HistoryEntry]) -> AgentStep:
        if self.failed is not None:
            return self.failed
        if not self.queue:
            return AgentStep(platform=self.last_platform, action=Done(), reasoning="oracle solution complete")
        platform, step = self.queue.pop(0)
        self.last_platform = platform
        if isinstance(step, tuple) and step[0] == "open":  # a held-back set-up step: open the upstream's file
            opener, device = step[1], self.devices[platform]
            shown = device.launch(opener.app, *opener.args) if opener.type == "launch" else device.open(opener.path)
            what = f"{opener.app} {' '.join(opener.args)}" if opener.type == "launch" else opener.path
            return AgentStep(platform=platform, action=Wait(seconds=0), reasoning=f"oracle: open {what} "
                             f"({'its window shows' if shown else 'no window yet'})",
                             extra={"opened": {"what": what, "window": shown}})
        if isinstance(step, tuple):  # ("focus", title): bring the subtask's window to the front
            shown = getattr(self.devices[platform], "focus", lambda title: False)(step[1])
            return AgentStep(platform=platform, action=Wait(seconds=0), reasoning=f"oracle: bring the window "
                             f"{step[1]!r} to the front ({'done' if shown else 'no such window'})",
                             extra={"focus": {"title": step[1], "shown": shown}})
        if step.action is not None:
            return AgentStep(platform=platform, action=parse_action(step.action),
                             reasoning=step.note or "oracle solution step")
        t0 = time.monotonic()
        result = self.devices[platform].run(step.command, user=step.user, timeout=float(step.timeout or 120))
        if result.fault:  # the device's fault, not the solution's: the task runs again on fresh devices
            raise DeviceFault(f"an oracle command hit a device fault: {result.fault}: {step.command[:300]}")
        record = {"platform": platform, "command": step.command, "user": step.user,
                  "returncode": result.returncode, "seconds": round(time.monotonic() - t0, 3),
                  "output": (result.stdout[-500:] + result.stderr[-500:]).strip()}
        reasoning = step.note or "oracle command"
        if result.returncode != 0:
            self.failed = AgentStep(platform=platform, action=Fail(), extra={"commands": [record]},
                                    reasoning=f"oracle command failed ({result.returncode}): {step.command}\n"
                                              f"{result.stdout[-1000:]}{result.stderr[-1000:]}")
            return self.failed
        return AgentStep(platform=platform, action=Wait(seconds=0), reasoning=f"{reasoning}: $ {step.command[:300]}",
                         extra={"commands": [record]})

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


BUILTIN_AGENTS = {"oracle": OracleAgent, "noop": NoopAgent, "replay": ReplayAgent}
