"""Run one task end to end: boot its devices, set them up, drive the agent, evaluate, write the results."""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable

from jarvis_pytest.agents.gui_oracle import GuiOracleAgent
from jarvis_pytest.agents.oracle import brief as brief_oracle
from jarvis_pytest.agents.protocol import Agent, TaskContext
from jarvis_pytest.devices.actions import PLATFORMS
from jarvis_pytest.infra.transfer_server import (TRANSFER_ALIAS, TRANSFER_FOLDER, TRANSFER_PASSWORD, TRANSFER_PORT,
                                                 TRANSFER_USER)
from jarvis_pytest.errors import ConfigError, InfrastructureError, retry_device_faults
from jarvis_pytest.harness.evaluation import DriveWatch, capture_baselines, evaluate_subtasks
from jarvis_pytest.harness.inputs import input_hashes
from jarvis_pytest.harness import idle
from jarvis_pytest.harness.idle import idle_observation
from jarvis_pytest.harness.blame import AGENT_ERROR
from jarvis_pytest.harness.loop import LoopLimits, LoopOutcome, begin, run_loop
from jarvis_pytest.harness.setup_steps import run_setup, window_titles
from jarvis_pytest.results.failure_modes import classify
from jarvis_pytest.results.model import StepRecord, TaskResult, trial_seed
from jarvis_pytest.results.writer import TaskRecorder
from jarvis_pytest.tasks.model import Task
from jarvis_pytest.tasks.transfer import is_transfer


def agent_key(agent_config: dict[str, Any], limits: LoopLimits) -> str:
    """A stable hash of what decides an agent's behaviour; --resume reuses only results with the same key."""
    blob = json.dumps({"agent": agent_config, "max_steps": limits.max_steps}, sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


@dataclass
class RunContext:
    """What every task of a run (in one worker process) shares."""

    run_dir: Path
    agent: Agent
    environments: Any  # jarvis_pytest.infra pool: acquire(platforms) -> environment, prewarm(platforms), close()
    limits: LoopLimits = field(default_factory=LoopLimits)
    keep_devices: bool = False
    on_keep: Callable[[Any], None] | None = None
    qc: bool = False  # evaluate once right after set-up as well (the quality gate, `jarvis qc`)
    egress: bool = False  # the devices may reach beyond their task network (--allow-egress)
    prewarm_next: tuple[str, ...] | None = None  # the platforms of this worker's next task, booted ahead

    @property
    def agent_config(self) -> dict[str, Any]:
        return self.agent.config()


def task_platforms(task: Task) -> tuple[str, ...]:
    """The device platforms a task needs, sorted."""
    return tuple(sorted(set(task.devices or [s.platform for s in task.formatted_subtasks])))


def _passed(result: TaskResult) -> bool:
    """Every subtask passed; under the quality gate also every evaluator failed on the freshly set-up devices
    (a check that holds before the agent acts proves nothing about what it did) and every near-miss wrong state
    failed."""
    passed = bool(result.subtasks) and all(s.passed for s in result.subtasks)
    if result.qc_initial is not None:
        passed = passed and not any(e.passed for s in result.qc_initial for e in s.evaluators)
    if result.qc_negatives is not None:
        passed = passed and not any(n.passed or n.error for n in result.qc_negatives)
    if result.qc_gui is not None:
        passed = passed and not any(g.state == "failed" for g in result.qc_gui)
    return passed


def run_task(task: Task, ctx: RunContext, trial: int = 1) -> TaskResult:
    """Run trial `trial` of `task` and return its result; raises on infrastructure errors after recording them in
    result.json with status "error". A device fault (`DeviceFault`: in set-up, an oracle command or a near-miss
    state) runs the task again on fresh devices, up to DEVICE_FAULT_ATTEMPTS times in all; the result lists the
    faults."""
    return retry_device_faults(lambda faults: _run_once(task, ctx, faults, trial))[0]


def _run_once(task: Task, ctx: RunContext, faults: list[str], trial: int = 1) -> TaskResult:
    platforms = task_platforms(task)
    subtasks = task.formatted_subtasks
    config = ctx.agent_config
    result = TaskResult(task_id=task.id, category=task.category, platforms=list(platforms),
                        instruction=task.instruction, status="running", agent=config,
                        agent_key=agent_key(config, ctx.limits), egress=ctx.egress,
                        edges=[(e.from_[0], e.to[0]) for e in task.edges], device_faults=list(faults),
                        trial=trial, seed=trial_seed(task.id, trial))
    recorder = TaskRecorder(ctx.run_dir, result)
    t_start, wall_start = time.monotonic(), time.time()
    env = None
    progress = LoopOutcome()
    try:
        env = ctx.environments.acquire(platforms)
        if ctx.prewarm_next and not faults:  # only now: the devices booting ahead are the next task's, never this one's
            ctx.environments.prewarm(ctx.prewarm_next)
        result.image_ids = dict(env.image_ids)
        for platform, device in env.devices.items():  # the initial screen, for tasks that do not use the platform
            if platform in env.image_ids and not idle.known(platform, env.image_ids[platform]):
                idle.remember(platform, env.image_ids[platform], device.observe().screenshot_png)
        result.backends = dict(getattr(env, "backends", {}))
        result.device_os = dict(getattr(env, "device_os", {}))
        result.device_provenance = dict(getattr(env, "provenance", {}))
        result.stand_ins = sorted(getattr(env, "stand_ins", ()))
        result.engine = getattr(env, "engine", "")
        result.node = getattr(env, "node_label", "")
        result.worker = getattr(env, "worker", "")
        booted_ahead = wall_start - getattr(env, "boot_started", wall_start)  # > 0: pre-warmed
        t_boot = time.monotonic()
        opened = run_setup(subtasks, env.devices)
        baselines = capture_baselines(subtasks, env.devices)
        result.inputs = input_hashes(subtasks, env.devices, baselines)
        drive = DriveWatch(env, task)
        if ctx.qc:
            result.qc_initial = evaluate_subtasks(subtasks, env.devices, env.transfer, baselines, task.edges,
                                                  drive.turn())
        drive.start()
        t_setup = time.monotonic()
        transfer = {"url": f"http://{TRANSFER_ALIAS}:{TRANSFER_PORT}", "user": TRANSFER_USER,
                    "password": TRANSFER_PASSWORD, "folder": TRANSFER_FOLDER,
                    "flavour": getattr(env.transfer, "flavour", "copyparty")}
        failed_reset = begin(ctx.agent, TaskContext(task_id=task.id, instruction=task.instruction,
                                                    platforms=platforms, transfer=transfer, trial=trial,
                                                    seed=result.seed), ctx.limits)
        brief_oracle(ctx.agent, subtasks, env.devices, result.backends,  # to the built-in oracles only
                     window_titles(opened, env.devices) if type(ctx.agent) is GuiOracleAgent else None)
        limits = ctx.limits
        if type(ctx.agent) is GuiOracleAgent:  # a proof: its whole plan gets steps, as in `jarvis qc`'s GUI check
            limits = replace(limits, max_steps=max(limits.max_steps, len(ctx.agent.queue) + 5))
        if failed_reset is None:
            unused = {p: idle_observation(p) for p in PLATFORMS if p not in env.devices}
            outcome = run_loop(ctx.agent, env.devices, unused, recorder, limits, progress)
        else:  # the agent's own code failed before its first step: its failure, judged on the untouched devices
            recorder.step(StepRecord(index=0, platform=None, action=None, error=failed_reset))
            outcome = progress
            outcome.steps, outcome.end_reason = 1, AGENT_ERROR
        for platform, device in sorted(env.devices.items()):
            recorder.screenshot(outcome.steps, platform, device.observe().screenshot_png)
        t_loop = time.monotonic()
        result.steps, result.end_reason, result.usage = outcome.steps, outcome.end_reason, outcome.usage
        turn = drive.turn()
        result.subtasks = evaluate_subtasks(subtasks, env.devices, env.transfer, baselines, task.edges, turn)
        if turn is not None:
            recorder.drive_ledger(turn.window())
        t_eval = time.monotonic()
        if ctx.qc and task.category == "atomic":  # negatives belong to templates
            from jarvis_pytest.harness.negatives import run_negatives

            env.close()
            result.qc_negatives = run_negatives(subtasks, platforms, ctx.environments)
            from jarvis_pytest.harness.gui_check import GUI_FOLDER, run_gui_check

            result.qc_gui = run_gui_check(task, platforms, ctx.environments, result.backends, ctx.limits,
                                          recorder.dir / GUI_FOLDER)
        elif ctx.qc and any(is_transfer(s.template) for s in subtasks):  # a composed task's broken chains
            from jarvis_pytest.harness.chain_negatives import run_chain_negatives

            env.close()
            result.qc_negatives = run_chain_negatives(task, platforms, ctx.environments)
        result.status = "passed" if _passed(result) else "failed"
        if result.status == "failed" and result.qc_initial is None:
            result.failure_mode = classify(result.subtasks, result.edges, outcome.end_reason, recorder.acted_on)
        if outcome.end_reason == "timeout":  # the task's time limit, not the agent's verdict: counted apart
            result.status = "timeout"
        result.durations = {"boot": t_boot - t_start, "setup": t_setup - t_boot, "agent": outcome.agent_seconds,
                            "loop": t_loop - t_setup, "evaluate": t_eval - t_loop,
                            "total": time.monotonic() - t_start}
        if booted_ahead > 0:  # pre-warmed: its devices began to boot this long before the task started
            result.durations["booted_ahead"] = round(booted_ahead, 3)
        if ctx.qc:
            result.durations["negatives"] = time.monotonic() - t_eval
        return result
    except (InfrastructureError, ConfigError) as exc:
        result.status, result.end_reason, result.error = "error", "error", str(exc)
        result.durations["total"] = time.monotonic() - t_start
        raise
    except BaseException as exc:  # interrupted or a harness bug: keep what we have, marked as an error
        result.status, result.end_reason = "error", "error"
        result.error = ("interrupted (the run was stopped)" if isinstance(exc, KeyboardInterrupt)
                        else f"{exc.__class__.__name__}: {exc}")
        raise
    finally:
        if result.status in ("error", "running"):  # whatever ended the task, the steps taken and tokens spent stay
            result.steps, result.usage = progress.steps, dict(progress.usage)
            result.durations.setdefault("agent", progress.agent_seconds)
        try:
            recorder.finish()
        finally:  # a result that cannot be written (a full disk) still gives the devices back
            if env is not None:
                if ctx.keep_devices and ctx.on_keep:
                    ctx.on_keep(env)
                else:
                    env.close()
