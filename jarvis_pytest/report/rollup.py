"""The paper's result tables from per-task results (`results/model.py`).

What is computed (paper, Experiments, "Metrics"; tables `main_results` and `confidence_intervals`):

- TSR = share of tasks that passed (status "passed": every subtask passed), for atomic tasks per platform
  (android, windows, ubuntu) and overall, and for composed tasks per category (sw, mi, md) and overall.
- SSR (composed tasks only) = mean over tasks of passed/total subtasks (the paper's eq. 2). Beside it we keep the
  raw subtask counts k/n summed over the tasks and their ratio, the *pooled* SSR. The two differ when tasks have
  different numbers of subtasks. Note: the numbers printed in the paper's tables match the pooled ratio.
- 95 % percentile-bootstrap intervals over tasks. Every group of tasks has its own `random.Random` seeded from
  (seed, group name), and TSR and SSR of a group share the same resamples.
- Success against the number of subtasks (the paper's figure), over all composed tasks and per category.
- Tasks with status "error" (infrastructure failures) or "timeout" (the task's time limit passed) are left out of
  every rate and counted per category. Tasks still "running" (their session was stopped) are left out too and
  counted as unfinished, and tasks planned but never started as not run.

Results are sorted by task id before anything is computed. The same set of results therefore gives the same
summary.json byte for byte, whatever order they arrive in (one process, or xdist workers).
"""

from __future__ import annotations

import json
import math
import os
import random
import threading
from collections import Counter
from pathlib import Path
from typing import Any, Callable, Sequence

from pydantic import BaseModel, Field

from jarvis_pytest.devices.platforms import PLATFORM_NAMES, spec
from jarvis_pytest.results.model import TaskResult

PLATFORMS = PLATFORM_NAMES
COMPOSED = ("sw", "mi", "md")
CATEGORIES = ("atomic", *COMPOSED)
LEVEL = 0.95
DASH = "–"
_LABEL = {**{p: spec(p).label for p in PLATFORM_NAMES}, "overall": "Overall",
          "atomic": "Atomic", "sw": "SW", "mi": "MI", "md": "MD"}
_STATUS_RANK = {"passed": 3, "failed": 3, "timeout": 2, "error": 2, "running": 1}
HUMAN = "human"  # the agent of runs a person made in the browser player (`jarvis play`)


# ----------------------------------------------------------------------------------------------------- models


class Rate(BaseModel):
    """A task success rate: `k` of `n` tasks passed; `rate` and `ci` are None when n = 0."""

    rate: float | None
    k: int
    n: int
    ci: tuple[float, float] | None = None

    def text(self) -> str:
        return _pct_counts(self.rate, self.k, self.n)


class SubtaskRate(BaseModel):
    """SSR of `tasks` composed tasks. `rate` is the mean of per-task passed/total ratios (paper eq. 2).
    `k`/`n` count passed/total subtasks summed over the tasks, and `pooled_rate` = k/n."""

    rate: float | None
    k: int
    n: int
    tasks: int
    ci: tuple[float, float] | None = None
    pooled_rate: float | None = None
    pooled_ci: tuple[float, float] | None = None

    def text(self) -> str:
        return _pct_counts(self.rate, self.k, self.n)


class Composed(BaseModel):
    """One multi-task column pair of the main table."""

    tsr: Rate
    ssr: SubtaskRate


class BySubtasks(BaseModel):
    """Composed tasks with `subtasks` subtasks: `k` of `n` passed (with `--trials`, k and n count trials and `tsr`
    is the mean over tasks of their share of trials passed); `ssr` is the mean of per-task ratios."""

    subtasks: int
    n: int
    k: int
    tsr: float
    ssr: float


class ByDevices(BaseModel):
    """Composed tasks on `devices` devices: `k` of `n` passed (trials, as in `BySubtasks`); `ssr` is the mean of
    per-task ratios."""

    devices: int
    n: int
    k: int
    tsr: float
    ssr: float


class Timing(BaseModel):
    """How long the agent took on the counted tasks whose loop ran (`durations` has `loop`), in seconds. A task's
    time is its loop's wall time (`loop`: from the first screen to the last action); its decision time is what the
    agent took to decide (`agent`: model calls; for the agent `human`, a person in the player, how long each step
    waited for their input). Per step: the decision time of all tasks over all their steps."""

    tasks: int
    steps: int
    task_median: float | None = None
    task_mean: float | None = None
    decision_per_task: float | None = None  # mean
    decision_per_step: float | None = None  # Σ decision time / Σ steps


class TrialCell(BaseModel):
    """One cell over K trials per task: `mean` is the mean over its tasks of the share of their counted trials that
    passed; `pass_at_k` the share of tasks solved in at least one of K trials, `pass_all_k` (pass^K) in all K
    (unbiased estimators where a task has more than K counted trials). `tasks` with K counted trials enter pass@K
    and pass^K; `incomplete` tasks (fewer: some trials errored or never ran) enter only the mean."""

    tasks: int
    incomplete: int = 0
    mean: float | None = None
    mean_ci: tuple[float, float] | None = None
    pass_at_k: float | None = None
    pass_at_k_ci: tuple[float, float] | None = None
    pass_all_k: float | None = None
    pass_all_k_ci: tuple[float, float] | None = None


class TrialTask(BaseModel):
    """One task's trials: `passed` of its `counted` trials (errors, timeouts and unfinished trials not counted)."""

    task_id: str
    category: str
    passed: int
    counted: int


class Trials(BaseModel):
    """`--trials K`: every cell over K trials per task, each task's count, and the tasks whose trials disagree."""

    k: int
    cells: dict[str, TrialCell]  # "atomic/<platform>", "atomic/overall", "composed/<category>", "composed/overall", "all"
    tasks: list[TrialTask] = Field(default_factory=list)
    unstable: list[str] = Field(default_factory=list)  # task ids with passed and failed trials


class Summary(BaseModel):
    """summary.json. Rates are fractions in [0, 1]; intervals are [lo, hi] or None when there is no task."""

    agent: str | None = None
    atomic: dict[str, Rate]  # android, windows, ubuntu, overall
    composed: dict[str, Composed]  # sw, mi, md, overall
    overall: dict[str, Rate | SubtaskRate]  # "tsr": every counted task; "ssr": composed tasks (= composed overall)
    by_subtasks: list[BySubtasks] = Field(default_factory=list)  # all composed tasks
    by_subtasks_category: dict[str, list[BySubtasks]] = Field(default_factory=dict)  # sw, mi, md
    errors: dict[str, int] = Field(default_factory=dict)  # per category; excluded from every rate
    unfinished: dict[str, int] = Field(default_factory=dict)  # status "running", per category; ignored
    timeouts: dict[str, int] = Field(default_factory=dict)  # status "timeout", per category; excluded
    not_run: dict[str, int] = Field(default_factory=dict)  # planned (plan.json) but no result, per category
    skipped: dict[str, int] = Field(default_factory=dict)  # no device for them on this machine, per category
    by_devices: list[ByDevices] = Field(default_factory=list)  # composed tasks by number of devices
    failure_modes: dict[str, dict[str, int]] = Field(default_factory=dict)  # category → mode → failed tasks
    stand_ins: dict[str, list[str]] = Field(default_factory=dict)  # platform → stand-in backends that ran it
    stand_in_categories: list[str] = Field(default_factory=list)  # atomic/sw/mi/md with a stand-in result counted
    devices: dict[str, list[str]] = Field(default_factory=dict)  # platform → what its devices really were
    tasks: int = 0  # tasks counted in the rates (each once, however many trials it had)
    rerun_after_device_fault: int = 0  # counted tasks whose devices faulted once and that ran again on fresh ones
    timing: Timing | None = None  # time per task and per step (None: no counted task ran its loop)
    trials: Trials | None = None  # the run had --trials K > 1: rates over trials, pass@K, pass^K, unstable tasks
    warnings: list[str] = Field(default_factory=list)  # inconsistent or unexpected results
    seed: int = 0
    n_boot: int = 2000
    level: float = LEVEL


# ---------------------------------------------------------------------------------------------------- compute


class _Task:
    """What the rollup needs of one task over its counted trials (one trial without `--trials`): `success` is the
    share of its trials that passed, `ratio` the mean over its trials of passed/total subtasks."""

    __slots__ = ("success", "wins", "trials", "passed", "total", "ratio")

    def __init__(self, trials: Sequence[TaskResult]):
        self.trials = len(trials)
        self.wins = sum(1 for r in trials if r.status == "passed")
        self.success = self.wins / self.trials
        self.passed = sum(r.passed_subtasks for r in trials)
        self.total = sum(len(r.subtasks) for r in trials)
        self.ratio = math.fsum(r.passed_subtasks / len(r.subtasks) if r.subtasks else 0.0 for r in trials) / self.trials


def _by_task(results: Sequence[TaskResult]) -> dict[str, list[TaskResult]]:
    """Each task id's results (one per trial), in id order."""
    by_id: dict[str, list[TaskResult]] = {}
    for r in results:
        by_id.setdefault(r.task_id, []).append(r)
    return dict(sorted(by_id.items()))


def _tasks(results: Sequence[TaskResult]) -> list[_Task]:
    """One `_Task` per task id, in id order, over its results (one per trial)."""
    return [_Task(trials) for trials in _by_task(results).values()]


def _interval(stats: list[float], level: float) -> tuple[float, float]:
    """Percentile interval: cut the same number of resamples off each end."""
    stats.sort()
    cut = min(int(round((1 - level) / 2 * len(stats))), (len(stats) - 1) // 2)
    return stats[cut], stats[len(stats) - 1 - cut]


def _group(name: str, results: list[TaskResult], seed: int, n_boot: int) -> Composed:
    """TSR and SSR of one group of tasks, with intervals from the same (paired) bootstrap resamples of tasks (a
    task's trials stay together). With one trial per task TSR is the share of tasks that passed; with more, the
    mean over tasks of the share of their trials that passed, and k/n count trials."""
    tasks = _tasks(results)
    n = len(tasks)
    if n == 0:
        return Composed(tsr=Rate(rate=None, k=0, n=0), ssr=SubtaskRate(rate=None, k=0, n=0, tasks=0))
    k, runs = sum(t.wins for t in tasks), sum(t.trials for t in tasks)
    passed, total = sum(t.passed for t in tasks), sum(t.total for t in tasks)
    rng = random.Random(f"jarvis-rollup/{seed}/{name}")  # str seeds are hashed with SHA-512: stable everywhere
    tsr_b, ssr_b, pooled_b = [], [], []
    for _ in range(n_boot):
        sample = rng.choices(tasks, k=n)
        tsr_b.append(math.fsum(t.success for t in sample) / n)
        ssr_b.append(math.fsum(t.ratio for t in sample) / n)  # fsum is exact: the order of a sample cannot matter
        sample_total = sum(t.total for t in sample)
        pooled_b.append(sum(t.passed for t in sample) / sample_total if sample_total else 0.0)
    return Composed(
        tsr=Rate(rate=math.fsum(t.success for t in tasks) / n, k=k, n=runs, ci=_interval(tsr_b, LEVEL)),
        ssr=SubtaskRate(rate=math.fsum(t.ratio for t in tasks) / n, k=passed, n=total, tasks=n,
                        ci=_interval(ssr_b, LEVEL), pooled_rate=passed / total if total else None,
                        pooled_ci=_interval(pooled_b, LEVEL) if total else None))


def _by_size(results: list[TaskResult], size: Callable[[TaskResult], int]) -> list[dict[str, Any]]:
    """Per value of `size` (a task's subtasks, its devices), in order: the size, k/n (trials), TSR and SSR."""
    groups: dict[int, list[TaskResult]] = {}
    for r in results:
        groups.setdefault(size(r), []).append(r)
    out = []
    for value, rs in sorted(groups.items()):
        ts = _tasks(rs)
        out.append({"size": value, "n": sum(t.trials for t in ts), "k": sum(t.wins for t in ts),
                    "tsr": math.fsum(t.success for t in ts) / len(ts), "ssr": math.fsum(t.ratio for t in ts) / len(ts)})
    return out


def _curve(results: list[TaskResult]) -> list[BySubtasks]:
    return [BySubtasks(subtasks=g.pop("size"), **g) for g in _by_size(results, lambda r: len(r.subtasks))]


def _by_devices(results: list[TaskResult]) -> list[ByDevices]:
    return [ByDevices(devices=g.pop("size"), **g) for g in _by_size(results, lambda r: len(set(r.platforms)))]


def _failure_modes(done: dict[str, list[TaskResult]]) -> dict[str, dict[str, int]]:
    out: dict[str, dict[str, int]] = {}
    for cat, rs in done.items():
        counts = Counter(r.failure_mode for r in rs if r.status == "failed" and r.failure_mode)
        if counts:
            out[cat] = dict(sorted(counts.items()))
    return out


def _stand_ins(results: list[TaskResult]) -> dict[str, list[str]]:
    found: dict[str, set[str]] = {}
    for r in results:
        for p in r.stand_ins:
            found.setdefault(p, set()).add(r.backends.get(p, p))
    return {p: sorted(v) for p, v in sorted(found.items())}


def _devices(results: list[TaskResult]) -> dict[str, list[str]]:
    """Platform → what its devices really were (`TaskResult.device_os`, read inside them), over every result."""
    found: dict[str, set[str]] = {}
    for r in results:
        for p, system in r.device_os.items():
            found.setdefault(p, set()).add(system)
    return {p: sorted(v) for p, v in sorted(found.items())}


def _devices_line(s: Summary) -> str:
    """E.g. `ubuntu platform: Debian GNU/Linux 12 (bookworm), XFCE 4.18; windows platform: ...` (the platforms
    keep the paper's names; this says what ran under each)."""
    return "; ".join(f"{p} platform: {' / '.join(v)}" for p, v in s.devices.items())


def _timing(results: list[TaskResult]) -> Timing | None:
    timed = [r for r in results if "loop" in r.durations]
    if not timed:
        return None
    loops = sorted(r.durations["loop"] for r in timed)
    decided = [r.durations.get("agent", 0.0) for r in timed]
    steps = sum(r.steps for r in timed)
    mid = len(loops) // 2
    median = loops[mid] if len(loops) % 2 else (loops[mid - 1] + loops[mid]) / 2
    return Timing(tasks=len(timed), steps=steps, task_median=round(median, 3),
                  task_mean=round(math.fsum(loops) / len(loops), 3),
                  decision_per_task=round(math.fsum(decided) / len(timed), 3),
                  decision_per_step=round(math.fsum(decided) / steps, 3) if steps else None)


def _dedupe(results: Sequence[TaskResult], warnings: list[str]) -> list[TaskResult]:
    """One result per task and trial (`TaskResult.key`), sorted by task id and trial. A duplicated key keeps the
    most finished result, whatever the order: status rank, then latest `finished`, then the larger JSON text."""
    by_key: dict[str, TaskResult] = {}
    rank = lambda r: (_STATUS_RANK.get(r.status, 0), r.finished, r.model_dump_json())  # noqa: E731
    for r in results:
        other = by_key.get(r.key)
        if other is None or rank(r) > rank(other):
            by_key[r.key] = r
    counts = Counter(r.key for r in results)
    warnings += [f"task {key!r} appears {c} times; kept its {by_key[key].status} result"
                 for key, c in sorted(counts.items()) if c > 1]
    return sorted(by_key.values(), key=lambda r: (r.task_id, r.trial))


def _atomic_platform(r: TaskResult) -> str | None:
    platforms = [p.lower() for p in r.platforms]
    return platforms[0] if len(platforms) == 1 and platforms[0] in PLATFORMS else None


def _check(r: TaskResult, warnings: list[str]) -> None:
    """Note results whose status disagrees with their subtask verdicts (the rates trust the status)."""
    if r.status not in ("passed", "failed"):
        return
    all_passed = bool(r.subtasks) and all(s.passed for s in r.subtasks)
    if not r.subtasks:
        warnings.append(f"task {r.task_id!r} is {r.status} but has no subtask verdicts")
    elif (r.status == "passed") != all_passed and not (r.status == "failed" and (r.qc_initial or r.qc_negatives)):
        warnings.append(f"task {r.task_id!r} is {r.status} but {r.passed_subtasks}/{len(r.subtasks)} subtasks passed")
    if r.category.lower() == "atomic" and _atomic_platform(r) is None:
        warnings.append(f"atomic task {r.task_id!r} has platforms {r.platforms}: counted in Overall only")


def _trial_count(results: Sequence[TaskResult], planned: dict[str, str] | None) -> int:
    """K of `--trials K`: the highest trial among the results and the planned keys (`task#trial<n>`)."""
    from jarvis_pytest.results.model import TRIAL_MARK

    found = [r.trial for r in results]
    for key in planned or {}:
        number = key.rpartition(TRIAL_MARK)[2] if TRIAL_MARK in key else "1"
        found.append(int(number) if number.isdigit() else 1)
    return max(found, default=1)


def _pass_k(n: int, c: int, k: int) -> tuple[float, float]:
    """(pass@k, pass^k) of a task with `c` of `n` ≥ k trials passed: the chance that k trials drawn from its n
    hold at least one pass, and only passes (with n = k: solved in any, in all)."""
    total = math.comb(n, k)
    return 1 - math.comb(n - c, k) / total, math.comb(c, k) / total


def _trial_cell(name: str, results: list[TaskResult], k: int, seed: int, n_boot: int) -> TrialCell:
    tasks = list(_by_task(results).values())
    if not tasks:
        return TrialCell(tasks=0)
    share = [sum(r.status == "passed" for r in rs) / len(rs) for rs in tasks]
    full = [_pass_k(len(rs), sum(r.status == "passed" for r in rs), k) for rs in tasks if len(rs) >= k]
    rng = random.Random(f"jarvis-rollup/{seed}/trials/{name}")
    mean_b = [math.fsum(rng.choices(share, k=len(share))) / len(share) for _ in range(n_boot)]
    cell = TrialCell(tasks=len(full), incomplete=len(tasks) - len(full), mean=math.fsum(share) / len(share),
                     mean_ci=_interval(mean_b, LEVEL))
    if full:
        at_b, all_b = [], []
        for _ in range(n_boot):
            sample = rng.choices(full, k=len(full))
            at_b.append(math.fsum(a for a, _ in sample) / len(sample))
            all_b.append(math.fsum(b for _, b in sample) / len(sample))
        cell.pass_at_k, cell.pass_at_k_ci = math.fsum(a for a, _ in full) / len(full), _interval(at_b, LEVEL)
        cell.pass_all_k, cell.pass_all_k_ci = math.fsum(b for _, b in full) / len(full), _interval(all_b, LEVEL)
    return cell


def _trials(done: dict[str, list[TaskResult]], k: int, seed: int, n_boot: int) -> Trials:
    groups = {f"atomic/{p}": [r for r in done["atomic"] if _atomic_platform(r) == p] for p in PLATFORMS}
    groups["atomic/overall"] = done["atomic"]
    groups.update({f"composed/{c}": done[c] for c in COMPOSED})
    groups["composed/overall"] = [r for c in COMPOSED for r in done[c]]
    groups["all"] = [r for c in CATEGORIES for r in done[c]]
    tasks = [TrialTask(task_id=t, category=rs[0].category.lower(), passed=sum(r.status == "passed" for r in rs),
                       counted=len(rs)) for t, rs in _by_task(groups["all"]).items()]
    return Trials(k=k, cells={name: _trial_cell(name, rs, k, seed, n_boot) for name, rs in groups.items()},
                  tasks=tasks, unstable=[t.task_id for t in tasks if 0 < t.passed < t.counted])


def rollup(results: Sequence[TaskResult], *, seed: int = 0, n_boot: int = 2000,
           agent: str | None = None, planned: dict[str, str] | None = None) -> Summary:
    """The summary tables of `results`, in any order (see the module docstring for the definitions); `planned`
    (task id → category) are the tasks the run meant to run: those without a result are counted as not run."""
    if n_boot < 1:
        raise ValueError(f"n_boot must be at least 1, not {n_boot}")
    warnings: list[str] = []
    ordered = _dedupe(results, warnings)
    trials = _trial_count(ordered, planned)
    errors = dict.fromkeys(CATEGORIES, 0)
    unfinished = dict.fromkeys(CATEGORIES, 0)
    timeouts = dict.fromkeys(CATEGORIES, 0)
    not_run = dict.fromkeys(CATEGORIES, 0)
    skipped = dict.fromkeys(CATEGORIES, 0)
    have = {r.key for r in ordered}
    for tid, cat in sorted((planned or {}).items()):
        if tid not in have and cat.lower() in not_run:
            not_run[cat.lower()] += 1
    done: dict[str, list[TaskResult]] = {c: [] for c in CATEGORIES}
    unknown: dict[str, int] = {}
    for r in ordered:
        cat = r.category.lower()
        if cat not in done:
            unknown[r.category] = unknown.get(r.category, 0) + 1
        elif r.status == "error":
            errors[cat] += 1
        elif r.status == "timeout":
            timeouts[cat] += 1
        elif r.status == "skipped":
            skipped[cat] += 1
        elif r.status == "running":
            unfinished[cat] += 1
        else:
            _check(r, warnings)
            done[cat].append(r)
    warnings += [f"{n} task(s) of unknown category {c!r} ignored" for c, n in sorted(unknown.items())]

    def tsr(name: str, rs: list[TaskResult]) -> Rate:  # atomic tasks: TSR only (SSR is for composed tasks)
        return _group(name, rs, seed, n_boot).tsr

    atomic = {p: tsr(f"atomic/{p}", [r for r in done["atomic"] if _atomic_platform(r) == p]) for p in PLATFORMS}
    atomic["overall"] = tsr("atomic/overall", done["atomic"])
    composed_all = sorted((r for c in COMPOSED for r in done[c]), key=lambda r: r.task_id)
    composed = {c: _group(f"composed/{c}", done[c], seed, n_boot) for c in COMPOSED}
    composed["overall"] = _group("composed/overall", composed_all, seed, n_boot)
    everything = sorted(done["atomic"] + composed_all, key=lambda r: r.task_id)
    return Summary(
        agent=agent, atomic=atomic, composed=composed,
        overall={"tsr": tsr("all", everything), "ssr": composed["overall"].ssr},
        by_subtasks=_curve(composed_all), by_subtasks_category={c: _curve(done[c]) for c in COMPOSED},
        errors=errors, unfinished=unfinished, timeouts=timeouts, not_run=not_run, skipped=skipped,
        by_devices=_by_devices(composed_all), failure_modes=_failure_modes(done),
        stand_ins=_stand_ins(everything),
        stand_in_categories=sorted({r.category.lower() for r in everything if r.stand_ins}),
        devices=_devices(ordered),
        tasks=len({r.task_id for r in everything}), warnings=sorted(warnings),
        rerun_after_device_fault=sum(1 for r in everything if r.device_faults),
        timing=_timing(everything), seed=seed, n_boot=n_boot, level=LEVEL,
        trials=_trials(done, trials, seed, n_boot) if trials > 1 else None)


# ----------------------------------------------------------------------------------------------------- render


def _secs(value: float | None) -> str:
    return DASH if value is None else f"{value:.1f}"


def _pct(rate: float | None) -> str:
    return DASH if rate is None else f"{100 * rate:.1f}"


def _pct_counts(rate: float | None, k: int, n: int) -> str:
    return DASH if rate is None else f"{100 * rate:.1f} ({k}/{n})"


def _ci(ci: tuple[float, float] | None) -> str:
    return DASH if ci is None else f"[{100 * ci[0]:.1f}, {100 * ci[1]:.1f}]"


def _md_table(header: list[str], rows: list[list[str]]) -> list[str]:
    esc = lambda s: s.replace("|", "\\|")  # noqa: E731
    return ["| " + " | ".join(map(esc, header)) + " |", "|---" + "|--:" * (len(header) - 1) + "|",
            *("| " + " | ".join(map(esc, row)) + " |" for row in rows), ""]


def _main_cells(s: Summary) -> tuple[list[Rate], list[Rate | SubtaskRate]]:
    atomic = [s.atomic[k] for k in (*PLATFORMS, "overall")]
    multi = [cell for c in (*COMPOSED, "overall") for cell in (s.composed[c].tsr, s.composed[c].ssr)]
    return atomic, multi


def _notes(s: Summary) -> list[str]:
    n_err, n_run = sum(s.errors.values()), sum(s.unfinished.values())
    n_out, n_not = sum(s.timeouts.values()), sum(s.not_run.values())
    return [
        "Notes:",
        "",
        "- Cells are `rate % (k/n)`. For TSR, k/n counts tasks. For SSR, k/n counts passed/total subtasks summed "
        "over the tasks, while the rate is the paper's SSR (eq. 2): the mean over composed tasks of each task's "
        "passed/total. The pooled ratio k/n is given in Table 2 and differs when tasks have different numbers of "
        "subtasks. `–`: no task in the cell.",
        f"- Tasks that ended in an infrastructure error (status `error`, {n_err} here) are excluded from every "
        f"rate and counted apart, per category; so are tasks that ran out of their time limit (status `timeout`, "
        f"{n_out} here). Unfinished tasks (status `running`: their session was stopped, {n_run} here) and tasks "
        f"planned but never started ({n_not} here) are not counted; `--resume` runs them.",
        f"- Intervals: {100 * s.level:g} % percentile bootstrap over tasks, {s.n_boot} resamples, seed {s.seed}.",
        *([f"- {s.trials.k} trials per task: each rate is the mean over tasks of the share of their trials that "
           f"passed, and (k/n) count trials; an interval resamples tasks with all their trials (Table 7)."]
          if s.trials is not None else []),
        f"- A device that fails to carry out a command that is fine (Wine now and then cannot start a program) is "
        f"not the task's failure: set-up (before the agent acts), an oracle command or a quality-gate near-miss "
        f"state is done again on fresh devices, and an evaluator's read-only command is run again. The verdict is "
        f"the last run's; `device_faults` in the result lists the faults ({s.rerun_after_device_fault} counted "
        f"tasks ran again here).",
        "",
    ]


def _star(s: Summary, platform: str) -> str:
    return "*" if platform in s.stand_ins else ""


def _cat_star(s: Summary, category: str) -> str:
    """* on a column of a category (sw, mi, md; "atomic" or "composed" for the overall columns) whose counted
    results include one from a stand-in device."""
    cats = s.stand_in_categories
    hit = any(c in cats for c in COMPOSED) if category == "composed" else category in cats
    return "*" if hit else ""


def _stand_in_note(s: Summary) -> str:
    return "; ".join(f"{_LABEL.get(p, p)} ran on {', '.join(labels)}" for p, labels in s.stand_ins.items()) + "."


def render_markdown(s: Summary) -> str:
    """summary.md: the paper's main table (atomic, multi), intervals, success against subtasks, errors."""
    name = s.agent or "agent"
    atomic, multi = _main_cells(s)
    out = [f"# JarvisGUI results{f' — {s.agent}' if s.agent else ''}", "",
           f"Tasks counted: {s.tasks}. Not counted: errors {sum(s.errors.values())}, timeouts "
           f"{sum(s.timeouts.values())}, skipped for want of a device {sum(s.skipped.values())}, unfinished "
           f"{sum(s.unfinished.values())}, never ran {sum(s.not_run.values())}.", ""]
    if s.devices:
        out += [f"**Devices:** {_devices_line(s)}.", ""]
    if s.stand_ins:
        out += [f"**Stand-in devices:** {_stand_in_note(s)} Cells marked * include results from a stand-in: "
                "they are not comparable with results from the real platform.", ""]
    out += ["## Table 1a. Atomic tasks: TSR (%)", ""]
    out += _md_table(["Model", *(_LABEL[p] + _star(s, p) for p in PLATFORMS), "Overall" + _cat_star(s, "atomic")],
                     [[name, *(c.text() for c in atomic)]])
    out += ["## Table 1b. Multi-tasks: TSR and SSR (%)", ""]
    out += _md_table(["Model", *(f"{_LABEL[c]} {m}{_cat_star(s, 'composed' if c == 'overall' else c)}"
                                 for c in (*COMPOSED, "overall") for m in ("TSR", "SSR"))],
                     [[name, *(c.text() for c in multi)]])
    out += ["Row of the paper's main table (after Model and Size):", "", "```latex",
            " & ".join(_pct(c.rate) for c in [*atomic, *multi]) + r" \\", "```", ""]
    rows = [[f"Atomic {_LABEL[p]} TSR", _pct(s.atomic[p].rate), _ci(s.atomic[p].ci), f"{s.atomic[p].k}/{s.atomic[p].n}"]
            for p in (*PLATFORMS, "overall")]
    for c in (*COMPOSED, "overall"):
        t, u = s.composed[c].tsr, s.composed[c].ssr
        rows += [[f"{_LABEL[c]} TSR", _pct(t.rate), _ci(t.ci), f"{t.k}/{t.n} tasks"],
                 [f"{_LABEL[c]} SSR", _pct(u.rate), _ci(u.ci), f"{u.k}/{u.n} subtasks, {u.tasks} tasks"],
                 [f"{_LABEL[c]} SSR (pooled)", _pct(u.pooled_rate), _ci(u.pooled_ci), f"{u.k}/{u.n} subtasks"]]
    t = s.overall["tsr"]
    rows.append(["All tasks TSR", _pct(t.rate), _ci(t.ci), f"{t.k}/{t.n} tasks"])
    out += [f"## Table 2. Rates with {100 * s.level:g} % bootstrap confidence intervals (%)", ""]
    out += _md_table(["Cell", "Rate", "95 % CI", "Counts"], rows)
    if s.by_subtasks:
        per_cat = {c: {b.subtasks: b for b in s.by_subtasks_category.get(c, [])} for c in COMPOSED}
        cat_cell = lambda b: DASH if b is None else _pct_counts(b.tsr, b.k, b.n)  # noqa: E731
        out += ["## Table 3. Success against the number of subtasks (composed tasks, %)", ""]
        out += _md_table(["Subtasks", "Tasks", "TSR", "SSR", *(f"{_LABEL[c]} TSR" for c in COMPOSED)],
                         [[str(b.subtasks), str(b.n), _pct_counts(b.tsr, b.k, b.n), _pct(b.ssr),
                           *(cat_cell(per_cat[c].get(b.subtasks)) for c in COMPOSED)] for b in s.by_subtasks])
    if s.by_devices:
        out += ["## Table 4. Success against the number of devices (composed tasks, %)", ""]
        out += _md_table(["Devices", "Tasks", "TSR", "SSR"],
                         [[str(b.devices), str(b.n), _pct_counts(b.tsr, b.k, b.n), _pct(b.ssr)] for b in s.by_devices])
    if s.failure_modes:
        from jarvis_pytest.results.failure_modes import MODES

        out += ["## Table 5. Failure modes of failed tasks (counts; results/failure_modes.py)", ""]
        cats = [c for c in CATEGORIES if c in s.failure_modes]
        out += _md_table(["Mode", *(_LABEL[c] for c in cats), "Total"],
                         [[m, *(str(s.failure_modes[c].get(m, 0)) for c in cats),
                           str(sum(s.failure_modes[c].get(m, 0) for c in cats))] for m in MODES
                          if any(s.failure_modes[c].get(m) for c in cats)])
    if s.timing is not None:
        t = s.timing
        whose = ("a person's, in the player: how long each step waited for their input (each step's think time, "
                 "from its screen shown to the input, is `extra.player.think_ms` in traj.jsonl)" if s.agent == HUMAN
                 else "the agent's: its model calls and its own code")
        out += ["## Table 6. Time per task and per step (s)", ""]
        out += _md_table(["Model", "Tasks", "Steps", "Task time, median", "Task time, mean", "Decision time per task",
                          "Decision time per step"],
                         [[name, str(t.tasks), str(t.steps), _secs(t.task_median), _secs(t.task_mean),
                           _secs(t.decision_per_task), _secs(t.decision_per_step)]])
        out += [f"A task's time is its agent loop's wall time, from the first screen to the last action; the "
                f"decision time is {whose} (per step: over all steps of the counted tasks).", ""]
    if s.trials is not None:
        out += _trials_markdown(s.trials, s.level)
    out += ["## Not counted", ""]
    out += _md_table(["", *(_LABEL[c] for c in CATEGORIES), "Total"],
                     [[label, *(str(d.get(c, 0)) for c in CATEGORIES), str(sum(d.values()))]
                      for label, d in (("Errors (excluded)", s.errors), ("Timeouts (excluded)", s.timeouts),
                                       ("Skipped: cannot run here", s.skipped), ("Unfinished", s.unfinished),
                                       ("Never ran", s.not_run))])
    out += _notes(s)
    if s.warnings:
        out += ["Warnings:", "", *(f"- {w}" for w in s.warnings), ""]
    return "\n".join(out)


_TRIAL_ROWS = [(f"atomic/{p}", f"Atomic {_LABEL[p]}") for p in PLATFORMS] + [("atomic/overall", "Atomic overall")] + \
    [(f"composed/{c}", f"{_LABEL[c]}") for c in COMPOSED] + [("composed/overall", "Multi overall"), ("all", "All tasks")]


def _trials_markdown(t: Trials, level: float) -> list[str]:
    """Table 7 (each cell over K trials) and each task's trials; the unstable tasks named."""
    out = [f"## Table 7. {t.k} trials per task: mean success over trials, pass@{t.k} and pass^{t.k} (%)", ""]
    out += _md_table(["Cell", "Tasks", "Mean over trials", f"{100 * level:g} % CI", f"pass@{t.k}", "CI",
                      f"pass^{t.k}", "CI"],
                     [[label, str(c.tasks + c.incomplete) + (f" ({c.incomplete} incomplete)" if c.incomplete else ""),
                       _pct(c.mean), _ci(c.mean_ci), _pct(c.pass_at_k), _ci(c.pass_at_k_ci), _pct(c.pass_all_k),
                       _ci(c.pass_all_k_ci)]
                      for key, label in _TRIAL_ROWS for c in [t.cells[key]] if c.tasks or c.incomplete])
    out += [f"pass@{t.k}: solved in at least one of {t.k} trials; pass^{t.k}: solved in all {t.k}. A task with fewer "
            f"counted trials (some errored, timed out or never ran) is incomplete: it counts in the mean only. "
            f"Intervals resample tasks, each with all its trials.", ""]
    out += [f"**Unstable tasks** (trials disagree): {len(t.unstable)}" + (": " + ", ".join(f"`{u}`" for u in t.unstable)
                                                                         if t.unstable else "."), ""]
    out += [f"### Trials passed per task", ""]
    out += _md_table(["Task", "Category", "Trials passed"],
                     [[x.task_id, x.category, f"{x.passed}/{x.counted}" + ("" if x.counted == t.k else
                                                                          f" (of {t.k} planned)")] for x in t.tasks])
    return out


def render_terminal(s: Summary) -> str:
    """Compact fixed-width tables for pytest's terminal summary."""
    atomic = [s.atomic[k].text() for k in (*PLATFORMS, "overall")]
    tsr = [s.composed[c].tsr.text() for c in (*COMPOSED, "overall")]
    ssr = [s.composed[c].ssr.text() for c in (*COMPOSED, "overall")]
    w = max(12, *(len(x) for x in atomic + tsr + ssr)) + 2
    row = lambda label, cells: (f"{label:<8}" + "".join(f"{c:>{w}}" for c in cells)).rstrip()  # noqa: E731
    lines = [row("atomic", [*(_LABEL[p] + _star(s, p) for p in PLATFORMS), "Overall" + _cat_star(s, "atomic")]),
             row("  TSR", atomic),
             row("multi", [*(_LABEL[c] + _cat_star(s, c) for c in COMPOSED), "Overall" + _cat_star(s, "composed")]),
             row("  TSR", tsr), row("  SSR", ssr)]
    if s.devices:
        lines.append(f"devices: {_devices_line(s)}")
    if s.stand_ins:
        lines.append(f"* includes results from a stand-in device ({_stand_in_note(s)[:-1]}): not comparable with "
                     "the real platform")
    if s.by_subtasks:
        lines.append("by subtasks: " + "  ".join(f"{b.subtasks}: {_pct_counts(b.tsr, b.k, b.n)}"
                                                  for b in s.by_subtasks))
    errs = ", ".join(f"{c} {n}" for c, n in s.errors.items() if n) or "0"
    lines.append(f"{s.tasks} tasks counted; errors (not in rates): {errs}; timeouts: {sum(s.timeouts.values())}; "
                 f"skipped (cannot run here): {sum(s.skipped.values())}; "
                 f"unfinished: {sum(s.unfinished.values())}; never ran: {sum(s.not_run.values())}"
                 "; SSR = mean of per-task ratios, (k/n) = subtasks")
    if s.timing is not None:
        who = "a person's time" if s.agent == HUMAN else "decision"
        lines.append(f"time: a task {_secs(s.timing.task_median)} s (median of {s.timing.tasks}), {who} per step "
                     f"{_secs(s.timing.decision_per_step)} s")
    if s.trials is not None:
        t, k = s.trials, s.trials.k
        lines.append(f"trials: {k} per task; the rates above are means over trials, (k/n) = trials")
        lines.append(f"{'':<18}{'tasks':>6}  {'mean [95 % CI]':<22}{f'pass@{k}':>8}{f'pass^{k}':>8}")
        for key, label in _TRIAL_ROWS:
            c = t.cells[key]
            if c.tasks or c.incomplete:
                lines.append(f"{label:<18}{c.tasks + c.incomplete:>6}  {_pct(c.mean) + ' ' + _ci(c.mean_ci):<22}"
                             f"{_pct(c.pass_at_k):>8}{_pct(c.pass_all_k):>8}")
        shown = ", ".join(f"{u} ({x.passed}/{x.counted})" for u in t.unstable[:5]
                          for x in t.tasks if x.task_id == u)
        more = f" and {len(t.unstable) - 5} more" if len(t.unstable) > 5 else ""
        lines.append(f"unstable tasks (trials disagree): {len(t.unstable)}" + (f": {shown}{more}" if shown else ""))
    lines += [f"warning: {w}" for w in s.warnings]
    return "\n".join(lines)


# ------------------------------------------------------------------------------------------------------- files


def load_results(run_dir: Path) -> tuple[list[TaskResult], list[str]]:
    """`(results, problems)`: every readable `tasks/*/result.json` of a run (sorted by path), and one line per
    file that could not be read or validated (corrupted, truncated, wrong schema); such files are skipped."""
    results, problems = [], []
    for path in sorted((Path(run_dir) / "tasks").glob("*/result.json")):
        try:
            results.append(TaskResult.model_validate_json(path.read_bytes()))
        except (OSError, ValueError) as exc:  # pydantic's ValidationError is a ValueError
            first = str(exc).strip().splitlines()
            problems.append(f"{path}: skipped ({exc.__class__.__name__}: {first[0] if first else ''})")
    return results, problems


def _write_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    try:
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def summary_json(summary: Summary) -> str:
    """The exact text of summary.json: sorted keys, indent 2, trailing newline."""
    return json.dumps(summary.model_dump(mode="json"), indent=2, sort_keys=True, ensure_ascii=False) + "\n"


def write_summary(run_dir: Path, results: Sequence[TaskResult], agent: dict[str, Any] | None = None, *,
                  seed: int = 0, n_boot: int = 2000, planned: dict[str, str] | None = None) -> Summary:
    """Write `summary.json` and `summary.md` of `results` into `run_dir`, each through a temporary file and a
    rename; returns the summary. `agent` is the agent configuration; its "name" is shown."""
    name = (agent or {}).get("name")
    summary = rollup(results, seed=seed, n_boot=n_boot, agent=str(name) if name is not None else None,
                     planned=planned)
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    _write_atomic(run_dir / "summary.json", summary_json(summary))
    _write_atomic(run_dir / "summary.md", render_markdown(summary))
    return summary
