"""The step loop (paper §3.1): observe the task's devices, ask the agent, execute on the chosen device.

Execution errors (an invalid action, a device the task does not use, an agent that produced nothing usable)
are fed back into the agent's history, never raised. The loop stops at DONE, FAIL, the step limit or the task's
time limit. Each step is appended to the trajectory as it happens, and `progress` always holds the steps taken
and the tokens spent, whatever ends the loop.

Deadlines: each agent decision runs in a daemon thread with a deadline (`jarvis_pytest.llm.deadline`) that model
clients honour, at most `step_timeout` and never past the task's deadline. A decision that does not come by
the step deadline is an infrastructure error (the model endpoint hangs); one cut short by the task deadline
ends the task as a `timeout`. Neither is an agent failure, and the session never waits for an abandoned thread.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field

from jarvis_pytest.agents.protocol import Agent, AgentStep, HistoryEntry
from jarvis_pytest.devices.actions import TERMINAL_TYPES
from jarvis_pytest.devices.base import Device, Observation
from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.llm.deadline import deadline_at
from jarvis_pytest.results.model import StepRecord
from jarvis_pytest.results.writer import TaskRecorder

GRACE = 2.0  # seconds past a deadline we wait for the agent's thread to give up on its own
DEADLINE_SLACK = 0.5  # an endpoint error this close to the deadline is the deadline's doing


@dataclass
class LoopLimits:
    max_steps: int = 50
    step_timeout: float = 300.0   # seconds for one agent decision
    task_timeout: float = 3600.0  # seconds for the whole loop


@dataclass
class LoopOutcome:
    """How far the loop got; kept current while it runs, so an error mid-task loses nothing."""

    steps: int = 0
    end_reason: str = ""  # done | fail | max_steps | timeout
    agent_seconds: float = 0.0
    usage: dict[str, int] = field(default_factory=dict)


class StepDeadline(InfrastructureError):
    """The agent (its model endpoint) gave no decision within the step's deadline."""


def _unavailable_error(platform: str | None, devices: dict[str, Device]) -> str | None:
    if platform is None:
        return "action not found: the step names no platform"
    if platform not in devices:
        return f"device unavailable: {platform} is not used by this task (use one of {sorted(devices)})"
    return None


def decide(agent: Agent, observations: dict[str, Observation], history: list[HistoryEntry],
           deadline: float) -> AgentStep | None:
    """`agent.act` in a daemon thread bounded by `deadline` (monotonic); None when no answer came in time.
    An exception of the agent is raised here, in the caller's thread."""
    box: dict[str, object] = {}

    def work() -> None:
        try:
            with deadline_at(deadline):
                box["step"] = agent.act(observations, history)
        except BaseException as exc:  # handed to the loop's thread
            box["error"] = exc

    thread = threading.Thread(target=work, name="agent-step", daemon=True)
    thread.start()
    thread.join(max(0.0, deadline - time.monotonic()) + GRACE)
    if "error" in box:
        raise box["error"]  # type: ignore[misc]
    return box.get("step")  # type: ignore[return-value]


def run_loop(agent: Agent, devices: dict[str, Device], idle: dict[str, Observation], recorder: TaskRecorder,
             limits: LoopLimits, progress: LoopOutcome | None = None) -> LoopOutcome:
    """Drive `agent` on `devices` until it ends; `idle` are the initial observations of unused platforms."""
    out = progress if progress is not None else LoopOutcome()
    history: list[HistoryEntry] = []
    task_deadline = time.monotonic() + limits.task_timeout
    for index in range(limits.max_steps):
        if time.monotonic() >= task_deadline:
            out.end_reason = "timeout"
            return out
        t0 = time.monotonic()
        observations = dict(idle)
        shots: dict[str, str] = {}
        for platform, device in sorted(devices.items()):
            obs = device.observe()
            observations[platform] = obs
            shots[platform] = recorder.screenshot(index, platform, obs.screenshot_png)
        t1 = time.monotonic()
        step_deadline = t1 + limits.step_timeout
        deadline = min(step_deadline, task_deadline)
        try:
            step = decide(agent, observations, list(history), deadline)
        except InfrastructureError as exc:  # the model client gave up at the deadline: the deadline's verdict
            if time.monotonic() < deadline - DEADLINE_SLACK:
                raise
            step, cause = None, exc
        else:
            cause = None
        t2 = time.monotonic()
        out.agent_seconds += t2 - t1
        if step is None:
            cut_by_task = task_deadline <= step_deadline
            message = (f"the task's time limit ({limits.task_timeout:g} s) passed while the agent decided" if cut_by_task
                       else f"the agent gave no decision within the step time limit ({limits.step_timeout:g} s): "
                            "its model endpoint does not answer")
            if cause is not None:
                message += f" ({cause})"
            recorder.step(StepRecord(index=index, platform=None, action=None, screenshots=shots, error=message,
                                     observe_ms=(t1 - t0) * 1000, agent_ms=(t2 - t1) * 1000))
            out.steps = index + 1
            if cut_by_task:
                out.end_reason = "timeout"
                return out
            raise StepDeadline(message)
        for k, v in step.usage.items():
            out.usage[k] = out.usage.get(k, 0) + int(v)
        action = step.action
        error = step.error
        end_reason = None
        exec_ms = 0.0
        if action is None:
            error = error or "action not found: the agent returned no action"
        elif action.type in TERMINAL_TYPES:
            end_reason = "done" if action.type == "DONE" else "fail"
        else:
            error = _unavailable_error(step.platform, devices)
            if error is None:
                outcome = devices[step.platform].act(action)
                exec_ms = outcome.elapsed_ms or (time.monotonic() - t2) * 1000
                if not outcome.ok:
                    error = outcome.error or "action failed"
        record = StepRecord(
            index=index, platform=step.platform,
            action=None if action is None else action.model_dump(mode="json"),
            reasoning=step.reasoning, raw_output=step.raw_output, error=error, screenshots=shots,
            observe_ms=(t1 - t0) * 1000, agent_ms=(t2 - t1) * 1000, exec_ms=exec_ms, usage=step.usage,
            extra=step.extra,
        )
        recorder.step(record)
        out.steps = index + 1
        history.append(HistoryEntry(index=index, platform=step.platform,
                                    plan=step.reasoning.splitlines()[0][:300] if step.reasoning else "",
                                    action=record.action, error=error))
        if end_reason:
            out.end_reason = end_reason
            return out
    out.end_reason = "max_steps"
    return out
