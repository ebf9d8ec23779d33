"""The quality gate's near-miss states (`jarvis qc`): each negative of a task's subtasks runs on fresh devices —
set up as for the agent, the negative's steps applied, then every evaluator — and the task must fail there."""

from __future__ import annotations

from typing import Any, Sequence

from jarvis_pytest.devices.actions import parse_action
from jarvis_pytest.devices.base import Device
from jarvis_pytest.plugin.evaluation import capture_baselines, evaluate_subtasks
from jarvis_pytest.plugin.setup_steps import run_setup
from jarvis_pytest.results.model import NegativeVerdict
from jarvis_pytest.tasks.model import SolutionStep, Subtask


def apply_steps(steps: Sequence[SolutionStep], devices: dict[str, Device], platform: str) -> str | None:
    """Carry out solution-format steps (commands or actions) in order; the first failure's message, or None."""
    for step in steps:
        device = devices[step.platform or platform]
        if step.command is not None:
            res = device.run(step.command, user=step.user, timeout=float(step.timeout or 120))
            if res.returncode != 0:
                return (f"command failed ({res.returncode}): {step.command[:200]}\n"
                        f"{res.stdout[-500:]}{res.stderr[-500:]}")
        else:
            outcome = device.act(parse_action(step.action))
            if not outcome.ok:
                return f"action {step.action} failed: {outcome.error}"
    return None


def run_negatives(subtasks: Sequence[Subtask], platforms: tuple[str, ...], environments: Any) -> list[NegativeVerdict]:
    """Every negative of every subtask, each on a freshly booted and set-up environment (closed after)."""
    out: list[NegativeVerdict] = []
    for s_index, sub in enumerate(subtasks):
        for n_index, neg in enumerate(sub.negatives or []):
            env = environments.acquire(platforms)
            try:
                run_setup(subtasks, env.devices)
                baselines = capture_baselines(subtasks, env.devices)
                error = apply_steps(neg.steps, env.devices, sub.platform)
                verdicts = [] if error else evaluate_subtasks(subtasks, env.devices, env.transfer, baselines)
            finally:
                env.close()
            passed = error is None and all(v.passed for v in verdicts)
            out.append(NegativeVerdict(subtask=s_index, index=n_index, kind=neg.kind, note=neg.note,
                                       passed=passed, error=error, verdicts=verdicts))
    return out
