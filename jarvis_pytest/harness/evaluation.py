"""Evaluate every evaluator of every subtask on the final state — all of them, even after one fails (SSR)."""

from __future__ import annotations

from typing import Any, Sequence

from jarvis_pytest.devices.base import Device
from jarvis_pytest.errors import ConfigError, InfrastructureError
from jarvis_pytest.evaluators import get_evaluator
from jarvis_pytest.evaluators.ledger import DriveLedger
from jarvis_pytest.evaluators.snapshots import capture_setup_snapshots, is_snapshot_key
from jarvis_pytest.evaluators.state import FinalState
from jarvis_pytest.evaluators.transfer import decide
from jarvis_pytest.results.model import EvaluatorVerdict, SubtaskVerdict, TaskResult
from jarvis_pytest.tasks.model import Edge, Subtask, Task
from jarvis_pytest.tasks.transfer import TRANSFER_INPUT, TRANSFER_OUTPUT, TransferLinks, is_transfer, transfer_links


def capture_baselines(subtasks: Sequence[Subtask], devices: dict[str, Device]) -> dict[tuple[str, str], bytes]:
    """The content of every subtask's `baseline` paths right after set-up (paths that do not exist are left out),
    and the set-up snapshots its evaluators ask for (`evaluators.snapshots`: processes, whole folders)."""
    out: dict[tuple[str, str], bytes] = {}
    for sub in subtasks:
        state = FinalState(platform=sub.platform, devices=devices)
        for path in sub.baseline:
            data = state.pull(path)
            if data is not None:
                out[(sub.platform, path)] = data
        out.update({(sub.platform, key): data for key, data in capture_setup_snapshots(state, sub.evaluate).items()})
    return out


class DriveWatch:
    """The drive's ledger around an agent's turn: `start()` marks its beginning, `turn()` marks its end (for now)
    and returns what the drive received and served in between (from the drive's start before `start`: what set-up
    did, for the quality gate's look at the untouched devices). Inert (None) for a task without a transfer subtask
    or a drive that keeps no ledger."""

    def __init__(self, env: Any, task: Task):
        wanted = any(is_transfer(s.template) for s in task.formatted_subtasks)
        self.env = env if wanted and getattr(env, "ledger_signal", None) else None
        self.begin: int | None = None

    def start(self) -> None:
        if self.env is not None:
            self.begin = self.env.mark_drive()

    def turn(self) -> DriveLedger | None:
        if self.env is None:
            return None
        end = self.env.mark_drive()
        text, read_object = self.env.drive_ledger()
        return DriveLedger.parse(text, read_object).between(self.begin, end)


def _received_baselines(subtasks: Sequence[Subtask], t: int, links: TransferLinks,
                        state: FinalState) -> dict[tuple[str, str], bytes]:
    """What the subtasks fed by transfer `t` take as the received file's baseline: the bytes that arrived through
    the drive (the ledger's kept copy), else, when the source is compared, the source's bytes (what should have
    arrived). Empty when neither is known."""
    spec = next((e for e in subtasks[t].evaluate if e.func == "transfer_arrived_unchanged"), None)
    if spec is None:
        return {}
    arrived = decide(state, **spec.args).arrived
    data = state.ledger.content(arrived.sha256) if arrived is not None and state.ledger is not None else None
    if data is None and not links.source_changed_later:
        data = state.pull(str(spec.args["source"]), str(spec.args["source_platform"]))
    if data is None:
        return {}
    return {(subtasks[t].platform, str(subtasks[t].output[TRANSFER_OUTPUT].value)): data}


def evaluate_subtasks(subtasks: Sequence[Subtask], devices: dict[str, Device], transfer: Any,
                      baselines: dict[tuple[str, str], bytes] | None = None, edges: Sequence[Edge] = (),
                      ledger: DriveLedger | None = None) -> list[SubtaskVerdict]:
    """Verdicts per subtask. An evaluator that raises (other than an infrastructure error) fails with its error.

    `ledger`: what the drive received and served in the agent's turn (None: the drive keeps no ledger). A transfer
    subtask learns its place in the graph from `edges` (which sides a later subtask changes) and gets the set-up
    content of the file it carries; a subtask fed by a transfer takes the arrived bytes as the received file's
    baseline."""
    verdicts: list[SubtaskVerdict] = []
    baselines = dict(baselines or {})
    received: dict[tuple[str, str], bytes] = {}  # (platform, path) → the bytes that arrived there by the drive
    for index, sub in enumerate(subtasks):
        # only the baselines this subtask declared: a path an upstream subtask feeds is not in its list, even
        # when another subtask captured that path at set-up (the upstream subtask changes it on purpose)
        own = {key: data for key, data in baselines.items()
               if key[0] == sub.platform and (key[1] in sub.baseline or is_snapshot_key(key[1]))}
        fed = {(sub.platform, str(sub.input[e.to[1]].value)) for e in edges if e.to[0] == index}
        own.update({key: data for key, data in received.items() if key in fed})
        links = None
        if is_transfer(sub.template):
            links = transfer_links(subtasks, edges, index)
            source = (sub.source_platform or "", str(sub.input[TRANSFER_INPUT].value))
            if source in baselines:
                own[source] = baselines[source]
        state = FinalState(platform=sub.platform, devices=devices, transfer=transfer, baselines=own, ledger=ledger,
                           chain=links)
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
        if links is not None:
            received.update(_received_baselines(subtasks, index, links, state))
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
    """The quality-gate message: evaluators that already pass before the oracle ran, negatives the evaluators
    accept, GUI solutions that do not solve their subtask, and subtasks the oracle failed."""
    lines = []
    for v in result.qc_initial or []:
        held = [e for e in v.evaluators if e.passed]
        if held:
            lines.append(f"subtask {v.index} {v.template}: evaluators pass on the untouched device "
                         f"({'; '.join(f'{e.func}: {e.reason}' for e in held)})")
    lines += [why for n in result.qc_negatives or [] if (why := n.violation())]
    lines += [f"subtask {g.subtask} {g.template}: the GUI solution does not solve it: {g.reason}"
              for g in result.qc_gui or [] if g.state == "failed"]
    if not all(s.passed for s in result.subtasks) or not result.subtasks:
        lines.append("the oracle did not solve the task: "
                     + failure_message(result.subtasks, result.end_reason, result.steps))
    return "\n".join(lines) or "quality gate failed"
