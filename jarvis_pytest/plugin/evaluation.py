"""Evaluate every evaluator of every subtask on the final state — all of them, even after one fails (SSR)."""

from __future__ import annotations

from typing import Any, Sequence

from jarvis_pytest.devices.base import Device
from jarvis_pytest.errors import ConfigError, InfrastructureError
from jarvis_pytest.evaluators import get_evaluator
from jarvis_pytest.evaluators.state import FinalState
from jarvis_pytest.results.model import EvaluatorVerdict, SubtaskVerdict, TaskResult
from jarvis_pytest.tasks.model import Subtask


def capture_baselines(subtasks: Sequence[Subtask], devices: dict[str, Device]) -> dict[tuple[str, str], bytes]:
    """The content of every subtask's `baseline` paths right after set-up (paths that do not exist are left out)."""
    out: dict[tuple[str, str], bytes] = {}
    for sub in subtasks:
        state = FinalState(platform=sub.platform, devices=devices)
        for path in sub.baseline:
            data = state.pull(path)
            if data is not None:
                out[(sub.platform, path)] = data
    return out


def evaluate_subtasks(subtasks: Sequence[Subtask], devices: dict[str, Device], transfer: Any,
                      baselines: dict[tuple[str, str], bytes] | None = None) -> list[SubtaskVerdict]:
    """Verdicts per subtask. An evaluator that raises (other than an infrastructure error) fails with its error."""
    verdicts: list[SubtaskVerdict] = []
    for index, sub in enumerate(subtasks):
        # only the baselines this subtask declared: a path an upstream subtask feeds is not in its list, even
        # when another subtask captured that path at set-up (the upstream subtask changes it on purpose)
        own = {key: data for key, data in (baselines or {}).items()
               if key[0] == sub.platform and key[1] in sub.baseline}
        state = FinalState(platform=sub.platform, devices=devices, transfer=transfer, baselines=own)
        results: list[EvaluatorVerdict] = []
        for spec in sub.evaluate:
            func_name = spec.func
            args = dict(spec.args)
            try:
                verdict = get_evaluator(func_name)(state, **args)
                passed, reason = verdict.passed, verdict.reason
            except (InfrastructureError, ConfigError):
                raise
            except Exception as exc:  # an evaluator bug or an unreadable file is a failed check, with its reason
                passed, reason = False, f"evaluator raised {exc.__class__.__name__}: {exc}"
            results.append(EvaluatorVerdict(func=func_name, args=args, passed=passed, reason=reason))
        verdicts.append(SubtaskVerdict(index=index, template=sub.template, platform=sub.platform,
                                       passed=bool(results) and all(r.passed for r in results), evaluators=results))
    return verdicts


def failure_message(verdicts: list[SubtaskVerdict], end_reason: str, steps: int) -> str:
    """The assertion message: each failed subtask with its evaluators' reasons."""
    failed = [v for v in verdicts if not v.passed]
    lines = [f"{len(failed)}/{len(verdicts)} subtasks failed (agent stopped: {end_reason} after {steps} steps)"]
    for v in failed:
        lines.append(f"  subtask {v.index} {v.template} on {v.platform}:")
        if not v.evaluators:
            lines.append("    no evaluator (a task without evaluators cannot pass)")
        for e in v.evaluators:
            if not e.passed:
                lines.append(f"    {e.func}: {e.reason}")
    return "\n".join(lines)


def qc_message(result: TaskResult) -> str:
    """The quality-gate message: evaluators that already pass before the oracle ran, and subtasks the oracle
    failed."""
    lines = []
    for v in result.qc_initial or []:
        held = [e for e in v.evaluators if e.passed]
        if held:
            lines.append(f"subtask {v.index} {v.template}: evaluators pass on the untouched device "
                         f"({'; '.join(f'{e.func}: {e.reason}' for e in held)})")
    for n in result.qc_negatives or []:
        if n.error:
            lines.append(f"negative {n.index} ({n.kind}: {n.note}) could not be applied: {n.error}")
        elif n.passed:
            lines.append(f"negative {n.index} ({n.kind}: {n.note}) passes: the evaluators accept this wrong state")
    if not all(s.passed for s in result.subtasks) or not result.subtasks:
        lines.append("the oracle did not solve the task: "
                     + failure_message(result.subtasks, result.end_reason, result.steps))
    return "\n".join(lines) or "quality gate failed"
