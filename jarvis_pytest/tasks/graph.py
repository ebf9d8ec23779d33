"""Checks and classification of task graphs (a :class:`Task`'s subtasks and edges).

Structure: every edge goes from an output slot of an earlier subtask to an input slot of a later one (so the
graph is acyclic and the subtask order is an execution order), carries the value along (value propagation) and
is type-compatible (t ⪯ u); an input is fed at most once. Platforms: an edge crosses platforms iff it enters a
built-in transfer subtask from the transfer's source platform; a transfer has exactly that one input edge and
feeds only ordinary subtasks on its own platform.

Evaluability (paper, appendix "Data Filtering"): a later subtask must not destroy an earlier subtask's observable
output: it may not move or delete a file an earlier subtask produced, nor edit one in place whose content the
earlier subtask's evaluators read; two subtasks on one platform may not change the same setting; and two
subtasks on one platform may not claim the same file path unless an edge hands the file from one to the other.

Categories: SW = one platform with dependencies, MI = several platforms without, MD = several platforms with.
"""

from __future__ import annotations

from typing import Sequence

from jarvis_pytest.devices.platforms import spec
from jarvis_pytest.tasks.model import Edge, Subtask, Task
from jarvis_pytest.tasks.templating import has_placeholder
from jarvis_pytest.tasks.types import TypeSystem


def classify(subtasks: Sequence[Subtask], edges: Sequence[Edge]) -> str | None:
    """atomic, sw, mi or md; None for several subtasks on one platform without dependencies (no category)."""
    if len(subtasks) == 1:
        return "atomic"
    several = len({s.platform for s in subtasks}) > 1
    if several:
        return "md" if edges else "mi"
    return "sw" if edges else None


def _key(platform: str, value: object) -> tuple[str, str]:
    text = str(value)
    return platform, text.lower() if spec(platform).case_insensitive_paths else text


def _name(subtasks: Sequence[Subtask], i: int) -> str:
    return f"subtask {i} ({subtasks[i].template})"


def edge_problems(subtasks: Sequence[Subtask], edges: Sequence[Edge], types: TypeSystem | None = None) -> list[str]:
    """Problems of the edges: ordering, slots, propagation, types and the transfer rule."""
    problems: list[str] = []
    n = len(subtasks)
    fed: set[tuple[int, str]] = set()
    into: dict[int, list[int]] = {}
    out_of: dict[int, list[int]] = {}
    for k, edge in enumerate(edges):
        (i, out), (j, inp) = edge.from_, edge.to
        label = f"edge {k} ({i}.{out} → {j}.{inp})"
        if not (0 <= i < n and 0 <= j < n):
            problems.append(f"{label}: subtask index out of range 0..{n - 1}")
            continue
        if i >= j:
            problems.append(f"{label}: points backwards; edges go from an earlier subtask to a later one (acyclic)")
        if out not in subtasks[i].output or inp not in subtasks[j].input:
            problems.append(f"{label}: {_name(subtasks, i)} has no output {out!r} or {_name(subtasks, j)} "
                            f"has no input {inp!r}")
            continue
        if (j, inp) in fed:
            problems.append(f"{label}: input {inp!r} of subtask {j} is fed twice")
        fed.add((j, inp))
        into.setdefault(j, []).append(i)
        out_of.setdefault(i, []).append(j)
        src, dst = subtasks[i].output[out], subtasks[j].input[inp]
        if src.value != dst.value:
            problems.append(f"{label}: value {src.value!r} was not propagated (input holds {dst.value!r})")
        if types is not None and (src.type not in types or dst.type not in types):
            problems.append(f"{label}: undeclared slot type {src.type!r} or {dst.type!r}")
        elif types is not None and not types.is_subtype(src.type, dst.type):
            problems.append(f"{label}: output type {src.type!r} does not fit input type {dst.type!r}")
        cross = subtasks[i].platform != subtasks[j].platform
        if cross and subtasks[j].source_platform != subtasks[i].platform:
            problems.append(f"{label}: crosses from {subtasks[i].platform} to {subtasks[j].platform} without a "
                            "transfer subtask")
        if not cross and subtasks[j].source_platform is not None:
            problems.append(f"{label}: a transfer subtask is fed from its own platform")
    for t, sub in enumerate(subtasks):
        if sub.source_platform is None:
            continue
        if len(into.get(t, [])) != 1:
            problems.append(f"{_name(subtasks, t)}: a transfer needs exactly one input edge, has {len(into.get(t, []))}")
        targets = out_of.get(t, [])
        if not targets:
            problems.append(f"{_name(subtasks, t)}: a transfer must feed a subtask on its platform")
        if any(subtasks[x].source_platform is not None for x in targets):
            problems.append(f"{_name(subtasks, t)}: a transfer feeds another transfer")
    return problems


def evaluability_problems(subtasks: Sequence[Subtask], edges: Sequence[Edge],
                          types: TypeSystem | None = None) -> list[str]:
    """Problems that would make an earlier subtask's result unobservable in the final state."""
    problems: list[str] = []
    producers: dict[tuple[str, str], list[tuple[int, str, bool]]] = {}
    for i, sub in enumerate(subtasks):
        for slot, bound in sub.output.items():
            producers.setdefault(_key(sub.platform, bound.value), []).append((i, slot, bound.content_checked is not False))
    for j, sub in enumerate(subtasks):
        for slot, how in sorted(sub.consumes.items()):
            value = sub.input[slot].value
            for i, out, checked in producers.get(_key(sub.platform, value), []):
                if i >= j:
                    continue
                if how in ("move", "delete"):
                    problems.append(f"{_name(subtasks, j)} {how}s {value}, the output {out!r} of "
                                    f"{_name(subtasks, i)}, whose result can then no longer be evaluated")
                elif checked:
                    problems.append(f"{_name(subtasks, j)} edits {value} in place, the output {out!r} of "
                                    f"{_name(subtasks, i)}, whose evaluators read its content")
    owner: dict[tuple[str, str], int] = {}
    for j, sub in enumerate(subtasks):
        for setting in sub.settings:
            key = (sub.platform, setting)
            if key in owner:
                problems.append(f"{_name(subtasks, owner[key])} and {_name(subtasks, j)} both change the "
                                f"{setting!r} setting of the {sub.platform} device; the later one overwrites the first")
            owner.setdefault(key, j)
    if types is not None:
        problems += _claim_problems(subtasks, edges, types)
    return problems


def _claim_problems(subtasks: Sequence[Subtask], edges: Sequence[Edge], types: TypeSystem) -> list[str]:
    """Two subtasks on one platform using one file path without an edge handing it over."""
    fed = {(e.to[0], e.to[1]) for e in edges}
    claimed: dict[tuple[str, str], int] = {}
    problems = []
    for j, sub in enumerate(subtasks):
        own_inputs = {_key(sub.platform, b.value) for b in sub.input.values()}
        keys = {_key(sub.platform, b.value) for name, b in sub.input.items()
                if (j, name) not in fed and b.type in types and types.is_file(b.type)}
        keys |= {k for b in sub.output.values() if b.type in types and types.is_file(b.type)
                 for k in [_key(sub.platform, b.value)] if k not in own_inputs}
        for key in sorted(keys):
            if key in claimed and claimed[key] != j:
                problems.append(f"{_name(subtasks, claimed[key])} and {_name(subtasks, j)} both use {key[1]} on the "
                                f"{key[0]} device without an edge between them")
            claimed.setdefault(key, j)
    return problems


def task_problems(task: Task, types: TypeSystem | None = None) -> list[str]:
    """Every problem of a task: devices and category consistent, edges, evaluability, no unrendered placeholder."""
    subs, edges = task.formatted_subtasks, task.edges
    problems = []
    platforms = sorted({s.platform for s in subs})
    if sorted(task.devices) != platforms:
        problems.append(f"devices {task.devices} do not match the subtasks' platforms {platforms}")
    category = classify(subs, edges)
    if category != task.category:
        actual = category or "no category: several independent subtasks on one platform"
        problems.append(f"category {task.category!r} does not match its graph ({actual})")
    problems += edge_problems(subs, edges, types)
    problems += evaluability_problems(subs, edges, types)
    if has_placeholder(task.instruction) or any(has_placeholder(s.model_dump(mode="json")) for s in subs):
        problems.append("an unrendered {{placeholder}} is left in the task")
    return problems
