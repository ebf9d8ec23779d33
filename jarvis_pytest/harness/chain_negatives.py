"""The quality gate's broken chains for composed tasks (`jarvis qc --composed`).

For each transfer subtask of a task, the oracle's plan (`agents/oracle.py`) is changed into the near-miss wrong
chains a weak or lazy agent could leave, each carried out on fresh devices after set-up and then evaluated:

- `made_up`: the transfer skipped, the destination's file made up (the harness writes the source's very bytes
  there, past the drive);
- `substituted`: a different file (the source's bytes with one byte changed) put on the drive under the right name,
  and carried;
- `too_early`: the file carried before the upstream subtask changed it (only where the upstream edits the file in
  place, so that there is a file to carry before it);
- `unplaced`: the file uploaded to the drive and never taken off it;
- `upstream_skipped`: the upstream subtask left out; the transfer carries whatever is at the source.

Each must fail the task, and at the subtask that should catch it: the transfer (the upstream too, for
`upstream_skipped`). A later subtask may fail as well (it works on what the broken chain left). A step that fails
because the chain is broken (a download of a file never uploaded) is recorded, the rest of its subtask's steps are
skipped (each would wait out its timeout), and the rest of the plan goes on.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Sequence

from jarvis_pytest.agents.oracle import PlanItem, SubtaskWindows, carry_out, oracle_plan
from jarvis_pytest.errors import retry_device_faults
from jarvis_pytest.harness.evaluation import DriveWatch, capture_baselines, evaluate_subtasks
from jarvis_pytest.harness.setup_steps import run_setup
from jarvis_pytest.results.model import NegativeVerdict
from jarvis_pytest.tasks.model import Task
from jarvis_pytest.tasks.transfer import TRANSFER_INPUT, TRANSFER_OUTPUT, is_transfer, transfer_links

UPLOAD, DOWNLOAD = 0, 1  # the built-in transfer's solution: upload on the source, download on the destination


@dataclass(frozen=True)
class Carry:
    """The harness copies the source's bytes to the destination itself: nothing passes through the drive."""

    source_platform: str
    source: str
    platform: str
    path: str


@dataclass(frozen=True)
class Substitute:
    """The harness puts a near-miss of the source's bytes on the drive under the source's name, over HTTP as an
    agent's upload would."""

    source_platform: str
    source: str
    name: str


@dataclass(frozen=True)
class ChainNegative:
    """A broken chain: the changed plan, the transfer it breaks, and the subtasks that must fail on it."""

    kind: str
    note: str
    transfer: int
    expect: tuple[int, ...]
    plan: tuple[Any, ...] = field(repr=False)


def _near_miss(data: bytes) -> bytes:
    """The bytes with the last one changed (one bit), or one byte where there were none."""
    return data[:-1] + bytes([data[-1] ^ 1]) if data else b"\0"


def chain_negatives(task: Task) -> list[ChainNegative]:
    """The broken chains of every transfer subtask of `task`, in order."""
    subs = task.formatted_subtasks
    plan = oracle_plan(subs)
    out: list[ChainNegative] = []
    for t, sub in enumerate(subs):
        if not is_transfer(sub.template):
            continue
        links = transfer_links(subs, task.edges, t)
        source, dest = str(sub.input[TRANSFER_INPUT].value), str(sub.output[TRANSFER_OUTPUT].value)
        src_platform = sub.source_platform or ""
        name = source.replace("\\", "/").rsplit("/", 1)[-1]
        mine = [i for i, p in enumerate(plan) if p.subtask == t]
        first = mine[0]
        rest = [p for p in plan if p.subtask != t]
        at = sum(1 for p in plan[:first] if p.subtask != t)  # where the transfer's steps were, in `rest`

        def own(item: PlanItem, index: int) -> bool:
            return item.subtask == t and item.kind == "step" and item.index == index

        out.append(ChainNegative(
            "made_up", f"the transfer skipped: {dest} made up with the source's bytes, past the drive", t, (t,),
            tuple(rest[:at] + [Carry(src_platform, source, sub.platform, dest)] + rest[at:])))
        out.append(ChainNegative(
            "substituted", f"a different {name} (one byte changed) put on the drive and carried", t, (t,),
            tuple(Substitute(src_platform, source, name) if own(p, UPLOAD) else p for p in plan)))
        if links.upstream is not None and links.upstream_edits_in_place:
            up = links.upstream
            start = next(i for i, p in enumerate(rest) if p.subtask == up)
            moved = [plan[i] for i in mine]
            out.append(ChainNegative(
                "too_early", f"{name} carried before {subs[up].template} changed it", t, (t,),
                tuple(rest[:start] + moved + rest[start:])))
        out.append(ChainNegative(
            "unplaced", f"{name} uploaded to the drive and never taken off it", t, (t,),
            tuple(p for p in plan if not own(p, DOWNLOAD))))
        if links.upstream is not None:
            up = links.upstream
            out.append(ChainNegative(
                "upstream_skipped", f"{subs[up].template} left out; the transfer carries what is at {source}", t,
                (up, t), tuple(p for p in plan if p.subtask != up)))
    return out


def _label(item: Any) -> str:
    if isinstance(item, PlanItem):
        return f"subtask {item.subtask} {item.kind}" + (f" {item.index}" if item.kind == "step" else "")
    return type(item).__name__.lower()


def _carry_out(item: Any, env: Any, windows: SubtaskWindows) -> str | None:
    devices = env.devices
    if isinstance(item, Carry):
        data = devices[item.source_platform].download(item.source) \
            if devices[item.source_platform].exists(item.source) else None
        if data is None:
            return f"no {item.source} to copy"
        devices[item.platform].upload(item.path, data)
        return None
    if isinstance(item, Substitute):
        device = devices[item.source_platform]
        data = device.download(item.source) if device.exists(item.source) else b""
        env.transfer.upload(f"/data/{item.name}", _near_miss(data))
        return None
    return carry_out(item, devices, windows)


def _on_fresh_devices(task: Task, negative: ChainNegative, platforms: tuple[str, ...],
                      environments: Any) -> tuple[list[str], list]:
    env = environments.acquire(platforms)
    try:
        subs = task.formatted_subtasks
        run_setup(subs, env.devices)
        baselines = capture_baselines(subs, env.devices)
        drive = DriveWatch(env, task)
        drive.start()
        windows = SubtaskWindows()
        problems: list[str] = []
        broken: set[int] = set()  # subtasks one of whose steps failed: the rest of their steps is skipped (each
        for item in negative.plan:  # would wait out its own timeout on what the broken chain left)
            if isinstance(item, PlanItem) and item.subtask in broken:
                continue
            err = _carry_out(item, env, windows)
            if err is not None:
                problems.append(f"{_label(item)}: {err}")
                if isinstance(item, PlanItem):
                    broken.add(item.subtask)
        return problems, evaluate_subtasks(subs, env.devices, env.transfer, baselines, task.edges, drive.turn())
    finally:
        env.close()


def run_chain_negatives(task: Task, platforms: tuple[str, ...], environments: Any,
                        negatives: Sequence[ChainNegative] | None = None) -> list[NegativeVerdict]:
    """Every broken chain of `task` (default: `chain_negatives(task)`), each on freshly booted and set-up devices.
    A verdict's `passed` is the gate's violation: the task passed, or a subtask in `expect` did."""
    out: list[NegativeVerdict] = []
    for n, neg in enumerate(negatives if negatives is not None else chain_negatives(task)):
        (problems, verdicts), faults = retry_device_faults(
            lambda _: _on_fresh_devices(task, neg, platforms, environments))
        held = [i for i in neg.expect if verdicts[i].passed]
        violated = all(v.passed for v in verdicts) or bool(held)
        out.append(NegativeVerdict(subtask=neg.transfer, index=n, kind=f"chain:{neg.kind}", note=neg.note,
                                   passed=violated, verdicts=verdicts, expect=list(neg.expect),
                                   step_errors=problems, device_faults=faults))
    return out
