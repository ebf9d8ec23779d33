"""The quality gate's near-miss states (`jarvis qc`): each negative of a task's subtasks runs on fresh devices —
set up as for the agent, the negative's steps applied, then every evaluator — and the task must fail there."""

from __future__ import annotations

from typing import Any, Sequence

from jarvis_pytest.devices.actions import parse_action
from jarvis_pytest.devices.base import Device
from jarvis_pytest.errors import DeviceFault, retry_device_faults
from jarvis_pytest.harness.evaluation import capture_baselines, evaluate_subtasks
from jarvis_pytest.harness.setup_steps import run_setup
from jarvis_pytest.results.model import NegativeVerdict
from jarvis_pytest.tasks.model import SolutionStep, Subtask


def apply_steps(steps: Sequence[SolutionStep], devices: dict[str, Device], platform: str) -> str | None:
    """Carry out solution-format steps (commands or actions) in order; the first failure's message, or None."""
    for step in steps:
        device = devices[step.platform or platform]
        if step.command is not None:
            res = device.run(step.command, user=step.user, timeout=float(step.timeout or 120))
            if res.fault:
                raise DeviceFault(f"a negative's command hit a device fault: {res.fault}: {step.command[:300]}")
            if res.returncode != 0:
                return (f"command failed ({res.returncode}): {step.command[:200]}\n"
                        f"{res.stdout[-500:]}{res.stderr[-500:]}")
        else:
            outcome = device.act(parse_action(step.action))
            if not outcome.ok:
                return f"action {step.action} failed: {outcome.error}"
    return None


def _negative_on_fresh_devices(subtasks: Sequence[Subtask], sub: Subtask, steps: Sequence[SolutionStep],
                               platforms: tuple[str, ...], environments: Any) -> tuple[str | None, list]:
    env = environments.acquire(platforms)
    try:
        run_setup(subtasks, env.devices)
        baselines = capture_baselines(subtasks, env.devices)
        error = apply_steps(steps, env.devices, sub.platform)
        return error, ([] if error else evaluate_subtasks(subtasks, env.devices, env.transfer, baselines))
    finally:
        env.close()


def run_negatives(subtasks: Sequence[Subtask], platforms: tuple[str, ...], environments: Any) -> list[NegativeVerdict]:
    """Every negative of every subtask, each on a freshly booted and set-up environment (closed after). A device
    fault (not the negative's own failure) is tried again on fresh devices; the last one is raised."""
    out: list[NegativeVerdict] = []
    for s_index, sub in enumerate(subtasks):
        for n_index, neg in enumerate(sub.negatives or []):
            (error, verdicts), faults = retry_device_faults(
                lambda _: _negative_on_fresh_devices(subtasks, sub, neg.steps, platforms, environments))
            passed = error is None and all(v.passed for v in verdicts)
            out.append(NegativeVerdict(subtask=s_index, index=n_index, kind=neg.kind, note=neg.note,
                                       passed=passed, error=error, verdicts=verdicts, device_faults=faults))
    return out
