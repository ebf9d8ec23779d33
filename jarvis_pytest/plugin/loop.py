"""The step loop (paper §3.1): observe the task's devices, ask the agent, execute on the chosen device.

Execution errors (an invalid action, a device the task does not use, an agent that produced nothing usable)
are fed back into the agent's history, never raised. The loop stops at DONE, FAIL, the step limit or the task's
time limit. Each step is appended to the trajectory as it happens.
"""

from __future__ import annotations

import concurrent.futures
import time
from dataclasses import dataclass

from jarvis_pytest.agents.protocol import Agent, AgentStep, HistoryEntry
from jarvis_pytest.devices.actions import TERMINAL_TYPES
from jarvis_pytest.devices.base import Device, Observation
from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.results.model import StepRecord
from jarvis_pytest.results.writer import TaskRecorder


@dataclass
class LoopLimits:
    max_steps: int = 50
    step_timeout: float = 300.0   # seconds for one agent decision
    task_timeout: float = 3600.0  # seconds for the whole loop


@dataclass
class LoopOutcome:
    steps: int
    end_reason: str  # done | fail | max_steps | timeout
    agent_seconds: float
    usage: dict[str, int]


def _unavailable_error(platform: str | None, devices: dict[str, Device]) -> str | None:
    if platform is None:
        return "action not found: the step names no platform"
    if platform not in devices:
        return f"device unavailable: {platform} is not used by this task (use one of {sorted(devices)})"
    return None


def run_loop(agent: Agent, devices: dict[str, Device], idle: dict[str, Observation], recorder: TaskRecorder,
             limits: LoopLimits) -> LoopOutcome:
    """Drive `agent` on `devices` until it ends; `idle` are the initial observations of unused platforms."""
    history: list[HistoryEntry] = []
    usage: dict[str, int] = {}
    agent_seconds = 0.0
    started = time.monotonic()
    pool = concurrent.futures.ThreadPoolExecutor(max_workers=1, thread_name_prefix="agent")
    try:
        for index in range(limits.max_steps):
            if time.monotonic() - started > limits.task_timeout:
                return LoopOutcome(index, "timeout", agent_seconds, usage)
            t0 = time.monotonic()
            observations = dict(idle)
            shots: dict[str, str] = {}
            for platform, device in sorted(devices.items()):
                obs = device.observe()
                observations[platform] = obs
                shots[platform] = recorder.screenshot(index, platform, obs.screenshot_png)
            t1 = time.monotonic()
            future = pool.submit(agent.act, observations, list(history))
            try:
                step: AgentStep = future.result(timeout=limits.step_timeout)
            except concurrent.futures.TimeoutError:
                recorder.step(StepRecord(index=index, platform=None, action=None, screenshots=shots,
                                         error=f"agent gave no answer within {limits.step_timeout:.0f} s"))
                return LoopOutcome(index + 1, "timeout", agent_seconds + limits.step_timeout, usage)
            t2 = time.monotonic()
            agent_seconds += t2 - t1
            for k, v in step.usage.items():
                usage[k] = usage.get(k, 0) + int(v)
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
            history.append(HistoryEntry(index=index, platform=step.platform,
                                        plan=step.reasoning.splitlines()[0][:300] if step.reasoning else "",
                                        action=record.action, error=error))
            if end_reason:
                return LoopOutcome(index + 1, end_reason, agent_seconds, usage)
        return LoopOutcome(limits.max_steps, "max_steps", agent_seconds, usage)
    except InfrastructureError:
        raise
    finally:
        pool.shutdown(wait=False, cancel_futures=True)
