"""Typed automatic task composition (paper, Algorithm 1), seeded and deterministic.

Dependent graphs (SW, MD) follow Algorithm 1: sample a first instance, then repeatedly sample a slot among the
graph's open input slots and not-yet-used output slots and a library template with a compatible counterpart
slot (its output t ⪯ the open input's type, or the available output's type ⪯ its input), add the new instance
and the edge, until the graph has its target size. Deviations, all deterministic: a slot without any valid
partner is skipped rather than ending the loop (the loop ends when no slot has one); a template is used at most
once per graph; an output feeds at most one input; only file slots may connect different platforms, and every
such edge gets a built-in transfer subtask (see ``transfer.py``), which counts towards the size limit K; a
candidate that would make the graph unevaluable (``graph.evaluability_problems``) is skipped. Values propagate
along edges when the graph is built; setup steps that provide a fed input are dropped.

SW graphs draw candidates from the first instance's platform only. MD graphs prefer cross-platform candidates
while the graph is still on one platform, and need K ≥ 3. MI graphs cannot come out of Algorithm 1 (it only
grows by connecting slots), so they have their own path: 2..K independent instances of distinct templates,
covering at least two platforms, without edges.

Seeds: task ``index`` of a dataset with ``seed`` tries ``Random("jarvis-compose:<seed>:<index>:<attempt>")`` for
attempt = 0, 1, ... until it gets a valid, new (not a duplicate) task, so equal seeds and inputs give equal
datasets. Balanced datasets hold SW, MI and MD in equal thirds (a remainder goes to SW, then MI); otherwise each
task is MI with probability 1/3 and else a dependent graph from the whole library, classified SW or MD by its
platforms.
"""

from __future__ import annotations

import heapq
import json
import random
from dataclasses import dataclass
from typing import Callable

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.tasks.graph import classify, edge_problems, evaluability_problems
from jarvis_pytest.tasks.instances import materialise, sample_inputs
from jarvis_pytest.tasks.instruction import merged_instruction
from jarvis_pytest.tasks.library import Library
from jarvis_pytest.tasks.model import BoundSlot, Edge, Scalar, Subtask, Task, TaskTemplate
from jarvis_pytest.tasks.transfer import TRANSFER_INPUT, TRANSFER_OUTPUT, transfer_template

CATEGORIES = ("sw", "mi", "md")
DEPENDENT = "dependent"  # unbalanced datasets: Algorithm 1 over the whole library, SW or MD by outcome
VALUE_SAMPLES = 3        # value draws per candidate before giving it up (path collisions)


@dataclass(frozen=True)
class Node:
    """A graph node before building: a template and its sampled input values."""

    template: TaskTemplate
    values: dict[str, Scalar]


@dataclass(frozen=True, order=True)
class Link:
    """Output `out` of node `src` feeds input `inp` of node `dst` (node indices, not subtask indices)."""

    src: int
    out: str
    dst: int
    inp: str


@dataclass(frozen=True)
class Draft:
    """A task graph under construction (no transfer subtasks yet)."""

    nodes: tuple[Node, ...]
    links: tuple[Link, ...] = ()

    def fed(self, n: int) -> set[str]:
        return {link.inp for link in self.links if link.dst == n}

    def used(self, n: int) -> set[str]:
        return {link.out for link in self.links if link.src == n}

    def with_node(self, node: Node, link_to: Callable[[int], Link]) -> "Draft":
        new = len(self.nodes)
        return Draft(self.nodes + (node,), self.links + (link_to(new),))


@dataclass(frozen=True)
class Built:
    """A built draft: subtasks in execution order (transfers inserted), edges, and node → subtask index."""

    subtasks: list[Subtask]
    edges: list[Edge]
    index: dict[int, int]


def _topological(draft: Draft) -> list[int]:
    indegree = [0] * len(draft.nodes)
    for link in draft.links:
        indegree[link.dst] += 1
    ready = [n for n, d in enumerate(indegree) if d == 0]
    heapq.heapify(ready)
    order = []
    while ready:
        n = heapq.heappop(ready)
        order.append(n)
        for link in sorted(draft.links):
            if link.src == n:
                indegree[link.dst] -= 1
                if indegree[link.dst] == 0:
                    heapq.heappush(ready, link.dst)
    if len(order) != len(draft.nodes):
        raise ValueError("the draft graph has a cycle")
    return order


def build(draft: Draft) -> Built:
    """Materialise the draft in topological order: propagate values, insert transfers on cross-platform edges."""
    subs: list[Subtask] = []
    edges: list[Edge] = []
    index: dict[int, int] = {}
    for n in _topological(draft):
        node = draft.nodes[n]
        fed: dict[str, BoundSlot] = {}
        pending: list[tuple[tuple[int, str], str]] = []
        for link in sorted(l for l in draft.links if l.dst == n):
            up_index = index[link.src]
            up = subs[up_index]
            slot = up.output[link.out]
            if up.platform != node.template.platform:
                transfer = materialise(transfer_template(up.platform, node.template.platform), {},
                                       fed={TRANSFER_INPUT: slot})
                subs.append(transfer)
                edges.append(Edge(from_=(up_index, link.out), to=(len(subs) - 1, TRANSFER_INPUT)))
                pending.append(((len(subs) - 1, TRANSFER_OUTPUT), link.inp))
                fed[link.inp] = transfer.output[TRANSFER_OUTPUT]
            else:
                pending.append(((up_index, link.out), link.inp))
                fed[link.inp] = slot
        subs.append(materialise(node.template, node.values, fed=fed))
        index[n] = len(subs) - 1
        edges += [Edge(from_=src, to=(index[n], inp)) for src, inp in pending]
    edges.sort(key=lambda e: (e.from_, e.to))
    return Built(subs, edges, index)


def _valid(built: Built, library: Library) -> bool:
    return not edge_problems(built.subtasks, built.edges, library.types) and \
        not evaluability_problems(built.subtasks, built.edges, library.types)


# -- Algorithm 1 ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Candidate:
    template: TaskTemplate
    slot: str        # the new node's slot
    direction: str   # "down": the new node consumes slot s; "up": the new node feeds slot s
    cross: bool      # the new node is on another platform


def _output_type(template: TaskTemplate, name: str) -> str:
    spec = template.outputs[name]
    return template.inputs[spec.same_type_as].type if spec.same_type_as else spec.type


def _candidates(library: Library, draft: Draft, built: Built, kind: str, n: int, slot: str,
                platforms: set[str] | None) -> list[_Candidate]:
    types = library.types
    used = {node.template.id for node in draft.nodes}
    here = draft.nodes[n].template.platform
    out = []
    for tpl in library.templates:
        if tpl.id in used or (platforms is not None and tpl.platform not in platforms):
            continue
        cross = tpl.platform != here
        if kind == "out":  # s is an available output: the new node takes it as an input
            t = built.subtasks[built.index[n]].output[slot].type
            for name in sorted(tpl.inputs):
                if tpl.inputs[name].feedable and types.is_subtype(t, tpl.inputs[name].type) and (not cross or types.is_file(t)):
                    out.append(_Candidate(tpl, name, "down", cross))
        else:  # s is an open input: the new node provides it from an output
            u = draft.nodes[n].template.inputs[slot].type
            for name in sorted(tpl.outputs):
                t = _output_type(tpl, name)
                if types.is_subtype(t, u) and (not cross or types.is_file(t)):
                    out.append(_Candidate(tpl, name, "up", cross))
    return out


def _try_add(library: Library, draft: Draft, n: int, slot: str, cand: _Candidate, rng: random.Random,
             size_limit: int) -> tuple[Draft, Built] | None:
    """Add an instance of the candidate linked to slot `slot` of node `n`, if the result is valid and fits."""
    for _ in range(VALUE_SAMPLES):
        node = Node(cand.template, sample_inputs(cand.template, rng))
        if cand.direction == "down":
            new = draft.with_node(node, lambda m: Link(n, slot, m, cand.slot))
        else:
            new = draft.with_node(node, lambda m: Link(m, cand.slot, n, slot))
        built = build(new)
        if len(built.subtasks) > size_limit:
            return None
        if _valid(built, library):
            return new, built
    return None


def _open_slots(draft: Draft) -> list[tuple[str, int, str]]:
    """I_open ∪ O_avail: unfed input slots and unused output slots, as (kind, node, slot), sorted."""
    slots = [("in", n, s) for n, node in enumerate(draft.nodes) for s in sorted(node.template.inputs)
             if s not in draft.fed(n) and node.template.inputs[s].feedable]
    return slots + [("out", n, s) for n, node in enumerate(draft.nodes) for s in sorted(node.template.outputs)
                    if s not in draft.used(n)]


def _extend(library: Library, draft: Draft, built: Built, slots: list[tuple[str, int, str]], rng: random.Random,
            size: int, platforms: set[str] | None, cross_only: bool) -> tuple[Draft, Built] | None:
    """The first slot (in the given order) with a valid random partner, and the graph grown by it."""
    for kind, n, slot in slots:
        cands = _candidates(library, draft, built, kind, n, slot, platforms)
        if cross_only:
            cands = [c for c in cands if c.cross]
        rng.shuffle(cands)
        for cand in cands:
            added = _try_add(library, draft, n, slot, cand, rng, size)
            if added:
                return added
    return None


def grow(library: Library, rng: random.Random, size: int, *, platforms: set[str] | None = None,
         want_cross: bool = False, start: TaskTemplate | None = None) -> Built:
    """Algorithm 1: grow a graph from a sampled first instance up to `size` subtasks (transfers included)."""
    pool = [t for t in library.templates if platforms is None or t.platform in platforms]
    first = start or rng.choice(pool)
    draft = Draft((Node(first, sample_inputs(first, rng)),))
    built = build(draft)
    while len(built.subtasks) < size:
        slots = _open_slots(draft)
        rng.shuffle(slots)
        single = len({node.template.platform for node in draft.nodes}) == 1
        added = None
        for cross_only in ((True, False) if want_cross and single else (False,)):
            added = added or _extend(library, draft, built, slots, rng, size, platforms, cross_only)
        if added is None:
            break
        draft, built = added
    return built


def independent(library: Library, rng: random.Random, size: int, platforms: set[str] | None = None) -> Built | None:
    """The MI path: `size` instances of distinct templates on at least two platforms, no edges."""
    pool = [t for t in library.templates if platforms is None or t.platform in platforms]
    rng.shuffle(pool)
    if len({t.platform for t in pool}) < 2:
        return None
    chosen: list[Node] = []
    built = None
    for tpl in pool:
        if len(chosen) == size:
            break
        if len(chosen) == 1 and tpl.platform == chosen[0].template.platform:
            continue
        for _ in range(VALUE_SAMPLES):
            trial = Draft(tuple(chosen) + (Node(tpl, sample_inputs(tpl, rng)),))
            candidate = build(trial)
            if _valid(candidate, library):
                chosen, built = list(trial.nodes), candidate
                break
    if built is None or len(chosen) < 2 or len({n.template.platform for n in chosen}) < 2:
        return None
    return built


def compose_task(library: Library, category: str, rng: random.Random, max_subtasks: int,
                 platforms: tuple[str, ...] | None = None) -> Task | None:
    """One composed task of `category` (sw, mi, md, or `dependent` = sw or md) or None if this draw failed;
    `platforms` restricts it to those platforms (one for SW, a pair for MI and MD)."""
    allowed = set(platforms) if platforms else None
    if category == "mi":
        built = independent(library, rng, rng.randint(2, max_subtasks), allowed)
    elif category == "sw":
        first = rng.choice([t for t in library.templates if allowed is None or t.platform in allowed])
        built = grow(library, rng, rng.randint(2, max_subtasks), platforms={first.platform}, start=first)
    elif category == "md":
        if max_subtasks < 3:
            return None
        built = grow(library, rng, rng.randint(3, max_subtasks), platforms=allowed, want_cross=True)
    else:
        built = grow(library, rng, rng.randint(2, max_subtasks))
    if built is None:
        return None
    got = classify(built.subtasks, built.edges)
    if got not in CATEGORIES or (category in CATEGORIES and got != category):
        return None
    return Task(id=f"{got}-draft", category=got, devices=sorted({s.platform for s in built.subtasks}),
                instruction=merged_instruction(built.subtasks, dependent=bool(built.edges)),
                edges=built.edges, formatted_subtasks=built.subtasks)


SPREAD_TRIES = 25  # attempts on one platform (pair) before the next one


def platform_spread(library: Library) -> dict[str, list[tuple[str, ...]]]:
    """Where each category's tasks go, in turn (the paper's mix): SW over every platform with templates, MI and
    MD over every pair of them."""
    from itertools import combinations

    platforms = sorted({t.platform for t in library.templates})
    pairs = list(combinations(platforms, 2))
    return {"sw": [(p,) for p in platforms], "mi": pairs, "md": pairs}


def category_plan(seed: int, count: int, balanced: bool, category: str | None = None) -> list[str]:
    """The category of every task of a dataset: all `category` when given, equal thirds when balanced, else MI
    or dependent at random."""
    if category is not None:
        return [category] * count
    if balanced:
        base, extra = divmod(count, 3)
        return [c for i, c in enumerate(CATEGORIES) for _ in range(base + (1 if i < extra else 0))]
    rng = random.Random(f"jarvis-compose:{seed}:plan")
    return ["mi" if rng.random() < 1 / 3 else DEPENDENT for _ in range(count)]


def _signature(task: Task) -> str:
    return json.dumps([[s.template, {k: v.value for k, v in s.input.items()}] for s in task.formatted_subtasks]
                      + [e.model_dump(by_alias=True) for e in task.edges], sort_keys=True)


def compose(library: Library, *, seed: int, count: int, max_subtasks: int, balanced: bool = False,
            category: str | None = None, finalize: Callable[[Task], Task | None] | None = None, max_attempts: int = 200) -> list[Task]:
    """A dataset of `count` distinct composed tasks with ids `<category>-<index:04d>`.

    `finalize` (e.g. the LLM rewrite and judge) may change a task or reject it (None); a rejected draw counts as
    a failed attempt and the next attempt is tried.
    """
    if count < 0:
        raise ConfigError("the task count cannot be negative", field="--count", fix="pass --count 1 or more")
    if max_subtasks < 2:
        raise ConfigError("a composed task needs at least 2 subtasks", field="--max-subtasks", fix="pass 2 or more")
    plan = category_plan(seed, count, balanced, category)
    if "md" in plan and max_subtasks < 3:
        raise ConfigError("an MD task needs at least 3 subtasks (two tasks and a transfer)", field="--max-subtasks",
                          fix="pass --max-subtasks 3 or more")
    if not library.templates and plan:
        raise ConfigError("the library has no templates", path=library.root,
                          fix="add templates under <library>/<platform>/*.json or pass --library DIR")
    tasks: list[Task] = []
    seen: set[str] = set()
    spread = platform_spread(library)
    turns = {c: 0 for c in (*CATEGORIES, DEPENDENT)}
    for index, category in enumerate(plan):
        turn = turns[category]
        turns[category] += 1
        for attempt in range(max_attempts):
            rng = random.Random(f"jarvis-compose:{seed}:{index}:{attempt}")
            choices = spread.get(category)
            # SW round-robin over the platforms, MI and MD over the platform pairs; a choice that keeps failing
            # hands over to the next one (after SPREAD_TRIES attempts), so every task still gets made
            where = choices[(turn + attempt // SPREAD_TRIES) % len(choices)] if choices else None
            task = compose_task(library, category, rng, max_subtasks, where)
            if task is None or _signature(task) in seen:
                continue
            task = task.model_copy(update={"id": f"{task.category}-{index:04d}"})
            if finalize is not None:
                task = finalize(task)
                if task is None:
                    continue
            seen.add(_signature(task))
            tasks.append(task)
            break
        else:
            raise ConfigError(f"could not compose a new {category} task (number {index}) in {max_attempts} attempts",
                              path=library.root, field="--count",
                              fix="add templates with compatible slots on more platforms, raise --max-subtasks, "
                                  "or ask for fewer tasks")
    return tasks
