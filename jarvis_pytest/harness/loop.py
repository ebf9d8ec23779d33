"""The step loop (paper §3.1): observe the task's devices, ask the agent, execute on the chosen device.

Execution errors (an invalid action, a device the task does not use, an agent that produced nothing usable, an
exception of the agent's own code) are fed back into the agent's history, never raised: whose fault a problem is
decides what it does (`harness/blame.py`). The loop stops at DONE, FAIL, the step limit, the task's time limit or
the agent's own failure (`agent_error`: its code exited, or crashed `AGENT_CRASH_LIMIT` steps in a row). Each step
is appended to the trajectory as it happens, and `progress` always holds the steps taken and the tokens spent,
whatever ends the loop.

Deadlines: each agent decision runs in a daemon thread with a deadline (`jarvis_pytest.llm.deadline`) that model
clients honour, at most `step_timeout` and never past the task's deadline. A decision that does not come by
the step deadline is an infrastructure error (the model endpoint hangs); one cut short by the task deadline
ends the task as a `timeout`. Neither is an agent failure, and the session never waits for an abandoned thread.
`--step-timeout` bounds model calls; an agent whose decisions wait for a person (`paced_by_person`: the browser
player's `human`) is not held to it, and each of its decisions may take until the task's deadline.
"""

from __future__ import annotations

import json
import math
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Callable

from pydantic import BaseModel

from jarvis_pytest.agents.protocol import Agent, AgentStep, HistoryEntry, TaskContext
from jarvis_pytest.devices.actions import TERMINAL_TYPES, Action, parse_action
from jarvis_pytest.devices.base import Device, Observation
from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.llm.deadline import deadline_at
from jarvis_pytest.harness.blame import AGENT_CRASH_LIMIT, AGENT_ERROR, blame, describe
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
    end_reason: str = ""  # done | fail | max_steps | timeout | agent_error
    agent_seconds: float = 0.0
    usage: dict[str, int] = field(default_factory=dict)


def decision_seconds(agent: Agent, limits: LoopLimits) -> float:
    """How long one decision of `agent` may take: the step time limit, which bounds model calls; for an agent that
    waits for a person (`paced_by_person`), the task's time limit (a person thinking is not an endpoint hanging)."""
    return limits.task_timeout if getattr(agent, "paced_by_person", False) is True else limits.step_timeout


class StepDeadline(InfrastructureError):
    """The agent (its model endpoint) gave no decision within the step's deadline."""


def _unavailable_error(platform: str | None, devices: dict[str, Device]) -> str | None:
    if platform is None:
        return "action not found: the step names no platform"
    if platform not in devices:
        return f"device unavailable: {platform} is not used by this task (use one of {sorted(devices)})"
    return None


class NotAStep(TypeError):
    """The agent's `act` returned something other than an `AgentStep`."""


_PENDING = object()


def _bounded(call: Callable[[], object], deadline: float, name: str) -> object:
    """`call()` in a daemon thread bounded by `deadline` (monotonic), under `deadline_at` so model clients honour
    it; `_PENDING` when no answer came in time (the thread is abandoned). Its exception is raised here."""
    box: dict[str, object] = {}

    def work() -> None:
        try:
            with deadline_at(deadline):
                box["value"] = call()
        except BaseException as exc:  # handed to the caller's thread
            box["error"] = exc

    thread = threading.Thread(target=work, name=name, daemon=True)
    try:
        thread.start()
    except RuntimeError as exc:  # no thread to be had: the harness's machine, not the agent
        raise InfrastructureError(f"cannot start the agent's thread: {exc}") from exc
    thread.join(max(0.0, deadline - time.monotonic()) + GRACE)
    if "error" in box:
        raise box["error"]  # type: ignore[misc]
    return box.get("value", _PENDING)


def decide(agent: Agent, observations: dict[str, Observation], history: list[HistoryEntry],
           deadline: float) -> AgentStep | None:
    """`agent.act` in a daemon thread bounded by `deadline` (monotonic); None when no answer came in time.
    An exception of the agent is raised here, in the caller's thread; an answer that is not an `AgentStep` (None
    included) raises `NotAStep`."""
    step = _bounded(lambda: agent.act(observations, history), deadline, "agent-step")
    if step is _PENDING:
        return None
    if not isinstance(step, AgentStep):
        raise NotAStep(f"the agent's act() returned {type(step).__name__}, not an AgentStep")
    return step


def begin(agent: Agent, context: TaskContext, limits: LoopLimits) -> str | None:
    """`agent.reset(context)` bounded by the step time limit: None when it went through, else why the task ends as
    the agent's failure (its code raised). A reset that does not end in time, or a model endpoint that fails in
    it, raises as a decision would (`error`)."""
    deadline = time.monotonic() + limits.step_timeout
    try:
        done = _bounded(lambda: agent.reset(context), deadline, "agent-reset")
    except BaseException as exc:
        verdict = blame(exc, "agent")
        if verdict.effect == "error":
            raise
        return f"the agent's reset() failed: {verdict.message}"
    if done is _PENDING:
        raise StepDeadline(f"the agent's reset() did not end within the step time limit ({limits.step_timeout:g} s)")
    return None


def _text(value: object) -> str:
    """An agent's free text as a string ("" for None; another object's str, or its type's name when that fails)."""
    if value is None or isinstance(value, str):  # a str subclass, too: the step record keeps it as a plain str
        return value or ""
    try:
        return str(value)
    except Exception:
        return f"<{type(value).__name__}>"


def _usage(usage: object) -> dict[str, int]:
    """Token counts: the entries that are whole, finite, non-negative numbers (anything else is dropped)."""
    if not isinstance(usage, dict):
        return {}
    out = {}
    for key, value in usage.items():
        if isinstance(key, str) and not isinstance(value, bool) and isinstance(value, (int, float)) \
                and math.isfinite(value) and 0 <= value < 2 ** 63:
            out[key] = int(value)
    return out


def _extra(extra: object) -> dict[str, Any]:
    """The agent's extra facts as plain JSON (objects JSON cannot hold become their repr); a note when they are not
    a dict or cannot be written at all (a cycle, nesting too deep)."""
    if not extra:
        return {}
    if not isinstance(extra, dict):
        return {"unrecorded": f"the step's extra is a {type(extra).__name__}, not a dict"}
    try:
        return json.loads(json.dumps(extra, default=repr, allow_nan=True))
    except (ValueError, TypeError, RecursionError) as exc:
        return {"unrecorded": f"the step's extra is not JSON: {describe(exc)}"}


def _action(action: object) -> Action | None:
    """The step's action checked again against the action space (an adapter may build one without validation,
    e.g. with `model_construct`, or hand a dict); raises what the action space raises."""
    if action is None:
        return None
    if isinstance(action, BaseModel):
        action = action.model_dump(mode="python", warnings=False)
    if not isinstance(action, dict):
        raise TypeError(f"an action must be an action of the unified action space, not {type(action).__name__}")
    return parse_action(action)


@dataclass(frozen=True)
class _Said:
    """An agent's step as plain, checked values: its action checked again against the action space (a refusal is
    the step's error), its texts as strings, its token counts as integers, its extra facts as JSON."""

    platform: str | None
    action: Action | None
    error: str | None
    reasoning: str
    raw_output: str
    usage: dict[str, int]
    extra: dict[str, Any]

    @classmethod
    def of(cls, step: AgentStep) -> "_Said":
        error = None if step.error is None else _text(step.error)
        try:
            action = _action(step.action)
        except Exception as exc:
            action, error = None, blame(exc, "action").message
        platform = step.platform
        return cls(platform=platform if platform is None or isinstance(platform, str) else _text(platform),
                   action=action, error=error, reasoning=_text(step.reasoning), raw_output=_text(step.raw_output),
                   usage=_usage(step.usage), extra=_extra(step.extra))


def run_loop(agent: Agent, devices: dict[str, Device], idle: dict[str, Observation], recorder: TaskRecorder,
             limits: LoopLimits, progress: LoopOutcome | None = None) -> LoopOutcome:
    """Drive `agent` on `devices` until it ends; `idle` are the initial observations of unused platforms."""
    out = progress if progress is not None else LoopOutcome()
    history: list[HistoryEntry] = []
    task_deadline = time.monotonic() + limits.task_timeout
    crashes = 0  # steps in a row on which the agent's code raised
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
        step_deadline = t1 + decision_seconds(agent, limits)
        deadline = min(step_deadline, task_deadline)
        crash = None  # the verdict on an exception of the agent's code
        try:
            step = decide(agent, observations, list(history), deadline)
        except InfrastructureError as exc:  # the model client gave up at the deadline: the deadline's verdict
            if time.monotonic() < deadline - DEADLINE_SLACK:
                raise
            step, cause = None, exc
        except BaseException as exc:  # the agent's code, its parsing, or a model client other than ours
            crash = blame(exc, "agent")
            if crash.effect != "error":
                step, cause = AgentStep(platform=None, action=None, error=crash.message), None
            elif isinstance(exc, KeyboardInterrupt) or time.monotonic() < deadline - DEADLINE_SLACK:
                raise
            else:  # another client's endpoint error at the deadline: the deadline's verdict, as for ours
                step, cause, crash = None, exc, None
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
        try:
            said = _Said.of(step)
        except Exception as exc:  # a step whose fields raise when read (an adapter's own AgentStep subclass)
            crash = blame(exc, "agent")
            said = _Said.of(AgentStep(platform=None, action=None, error=crash.message))
        crashes = crashes + 1 if crash is not None else 0
        for k, v in said.usage.items():
            out.usage[k] = out.usage.get(k, 0) + v
        platform, action, error = said.platform, said.action, said.error
        end_reason = None
        exec_ms = 0.0
        if crash is not None and (crash.effect == "end" or crashes >= AGENT_CRASH_LIMIT):
            end_reason = AGENT_ERROR
            if crash.effect != "end":
                error += f" (the agent's code raised on {crashes} steps in a row: the task ends as its failure)"
        elif action is None:
            error = error or "action not found: the agent returned no action"
        elif action.type in TERMINAL_TYPES:
            end_reason = "done" if action.type == "DONE" else "fail"
        else:
            error = _unavailable_error(platform, devices)
            if error is None:
                error, exec_ms = _execute(devices[platform], action, t2)
        record = StepRecord(
            index=index, platform=platform,
            action=None if action is None else action.model_dump(mode="json"),
            reasoning=said.reasoning, raw_output=said.raw_output, error=error, screenshots=shots,
            observe_ms=(t1 - t0) * 1000, agent_ms=(t2 - t1) * 1000, exec_ms=exec_ms, usage=said.usage,
            extra=said.extra,
        )
        recorder.step(record)
        out.steps = index + 1
        history.append(HistoryEntry(index=index, platform=platform,
                                    plan=record.reasoning.splitlines()[0][:300] if record.reasoning else "",
                                    action=record.action, error=error))
        if end_reason:
            out.end_reason = end_reason
            return out
    out.end_reason = "max_steps"
    return out


def _execute(device: Device, action: Action, started: float) -> tuple[str | None, float]:
    """Carry out `action` on `device`: the step's error (None when it went through) and its milliseconds. A
    refusal, or an action the device cannot be sent, is the agent's error; a device that fails raises."""
    try:
        outcome = device.act(action)
    except BaseException as exc:
        verdict = blame(exc, "device")
        if verdict.effect == "error":
            raise
        return verdict.message, (time.monotonic() - started) * 1000
    exec_ms = outcome.elapsed_ms or (time.monotonic() - started) * 1000
    return (None if outcome.ok else blame(outcome, "device").message), exec_ms
