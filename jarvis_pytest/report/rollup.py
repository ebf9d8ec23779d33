"""The paper's main table from per-task results: atomic TSR per platform; SW/MI/MD TSR and SSR; overall.

TSR = share of tasks whose every subtask passed. SSR (composed tasks only) = mean over tasks of
passed subtasks / subtasks (the paper's definition); the raw subtask counts are kept beside it. Tasks that ended
in an infrastructure error are excluded from every rate and counted apart; unfinished ("running") tasks are
ignored and counted apart. 95 % intervals are percentile bootstraps over tasks with a seeded RNG, so the same
results always give the same summary whatever order they arrive in.
"""

from __future__ import annotations

import random
from pathlib import Path
from typing import Any, Callable, Sequence

from pydantic import BaseModel, Field

from jarvis_pytest.results.model import TaskResult
from jarvis_pytest.results.writer import write_json_atomic

PLATFORMS = ("android", "windows", "ubuntu")
COMPOSED = ("sw", "mi", "md")


class Cell(BaseModel):
    """One table cell: the rate (None when n = 0), its raw counts and its 95 % bootstrap interval."""

    rate: float | None
    k: int | float  # a count; fractional only for SSR (sum of per-task ratios)
    n: int
    ci: tuple[float, float] | None = None

    def text(self) -> str:
        if self.rate is None:
            return "–"
        k = f"{self.k:g}"
        return f"{100 * self.rate:.1f} ({k}/{self.n})"

    def ci_text(self) -> str:
        return "–" if self.ci is None else f"[{100 * self.ci[0]:.1f}, {100 * self.ci[1]:.1f}]"


class ComposedCell(BaseModel):
    """TSR and SSR of a set of composed tasks; `subtasks` holds passed/total subtask counts."""

    tsr: Cell
    ssr: Cell
    subtasks: tuple[int, int] = (0, 0)


class BySubtasks(BaseModel):
    """Success against the number of subtasks (the paper's figure)."""

    subtasks: int
    n: int
    k: int
    tsr: float | None
    ssr: float | None


class Summary(BaseModel):
    agent: str | None = None
    atomic: dict[str, Cell]  # android, windows, ubuntu, overall
    composed: dict[str, ComposedCell]  # sw, mi, md, overall
    overall: dict[str, Cell]  # tsr over every task; ssr over composed tasks
    by_subtasks: list[BySubtasks] = Field(default_factory=list)
    errors: dict[str, int] = Field(default_factory=dict)  # per category; excluded from rates
    unfinished: int = 0
    tasks: int = 0  # tasks counted in the rates
    seed: int = 0


def _bootstrap(values: Sequence[float], rng: random.Random, n_boot: int) -> tuple[float, float] | None:
    n = len(values)
    if n == 0:
        return None
    means = sorted(sum(values[rng.randrange(n)] for _ in range(n)) / n for _ in range(n_boot))
    lo = means[int(0.025 * (n_boot - 1))]
    hi = means[int(round(0.975 * (n_boot - 1)))]
    return (lo, hi)


def _cell(values: list[float], rng: random.Random, n_boot: int) -> Cell:
    n = len(values)
    k = sum(values)
    rate = k / n if n else None
    ci = _bootstrap(values, rng, n_boot)
    if ci is not None and rate is not None:  # float rounding must not put the point outside its interval
        ci = (min(ci[0], rate), max(ci[1], rate))
    return Cell(rate=rate, k=int(k) if float(k).is_integer() else round(k, 4), n=n, ci=ci)


def _success(r: TaskResult) -> float:
    return 1.0 if r.status == "passed" else 0.0


def _ratio(r: TaskResult) -> float:
    return r.passed_subtasks / len(r.subtasks) if r.subtasks else 0.0


def rollup(results: Sequence[TaskResult], *, seed: int = 0, n_boot: int = 2000, agent: str | None = None) -> Summary:
    """The summary tables of `results` (any order; later duplicates of a task id replace earlier ones)."""
    by_id = {r.task_id: r for r in results}
    ordered = [by_id[k] for k in sorted(by_id)]
    done = [r for r in ordered if r.status in ("passed", "failed")]
    errors: dict[str, int] = {}
    for r in ordered:
        if r.status == "error":
            errors[r.category] = errors.get(r.category, 0) + 1
    rng = random.Random(seed)

    def cell(rs: list[TaskResult], f: Callable[[TaskResult], float]) -> Cell:
        return _cell([f(r) for r in rs], rng, n_boot)

    atomic = [r for r in done if r.category == "atomic"]
    atomic_table = {p: cell([r for r in atomic if r.platforms == [p]], _success) for p in PLATFORMS}
    atomic_table["overall"] = cell(atomic, _success)
    composed_table: dict[str, ComposedCell] = {}
    composed_all = [r for r in done if r.category in COMPOSED]
    for cat, rs in [(c, [r for r in done if r.category == c]) for c in COMPOSED] + [("overall", composed_all)]:
        composed_table[cat] = ComposedCell(
            tsr=cell(rs, _success), ssr=cell(rs, _ratio),
            subtasks=(sum(r.passed_subtasks for r in rs), sum(len(r.subtasks) for r in rs)))
    by_size: dict[int, list[TaskResult]] = {}
    for r in composed_all:
        by_size.setdefault(len(r.subtasks), []).append(r)
    curve = [BySubtasks(subtasks=size, n=len(rs), k=int(sum(map(_success, rs))),
                        tsr=sum(map(_success, rs)) / len(rs), ssr=sum(map(_ratio, rs)) / len(rs))
             for size, rs in sorted(by_size.items())]
    return Summary(
        agent=agent, atomic=atomic_table, composed=composed_table,
        overall={"tsr": cell(done, _success), "ssr": composed_table["overall"].ssr},
        by_subtasks=curve, errors=dict(sorted(errors.items())),
        unfinished=sum(1 for r in ordered if r.status == "running"), tasks=len(done), seed=seed)


NOTE = ("Rates in % with raw counts (k/n); errors (infrastructure failures) are excluded from the rates and "
        "counted apart; SSR is the mean over tasks of passed/total subtasks.")


def _table(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


def render_markdown(s: Summary) -> str:
    """summary.md: the paper's main table, intervals, success against subtasks, errors."""
    cols = ["Android", "Windows", "Ubuntu", "Overall"]
    keys = [*PLATFORMS, "overall"]
    ckeys = [*COMPOSED, "overall"]
    out = [f"# Results{f' — {s.agent}' if s.agent else ''}", "", "## Atomic tasks (TSR)", "",
           _table(cols, [[s.atomic[k].text() for k in keys]]), "",
           "## Composed tasks", "",
           _table(["", "SW", "MI", "MD", "Overall"],
                  [["TSR", *[s.composed[k].tsr.text() for k in ckeys]],
                   ["SSR", *[s.composed[k].ssr.text() for k in ckeys]],
                   ["subtasks passed", *[f"{s.composed[k].subtasks[0]}/{s.composed[k].subtasks[1]}" for k in ckeys]]]),
           "", f"Overall TSR (all tasks): {s.overall['tsr'].text()}", "",
           "## 95 % bootstrap confidence intervals", "",
           _table(["", *cols], [["atomic TSR", *[s.atomic[k].ci_text() for k in keys]]]), "",
           _table(["", "SW", "MI", "MD", "Overall"],
                  [["TSR", *[s.composed[k].tsr.ci_text() for k in ckeys]],
                   ["SSR", *[s.composed[k].ssr.ci_text() for k in ckeys]]]), ""]
    if s.by_subtasks:
        out += ["## Success against the number of subtasks", "",
                _table(["subtasks", "tasks", "TSR", "SSR"],
                       [[str(b.subtasks), str(b.n), f"{100 * b.tsr:.1f} ({b.k}/{b.n})", f"{100 * b.ssr:.1f}"]
                        for b in s.by_subtasks]), ""]
    errs = ", ".join(f"{k}: {v}" for k, v in s.errors.items()) or "none"
    out += [f"Errors (not in the rates): {errs}. Unfinished: {s.unfinished}. Tasks counted: {s.tasks}.", "",
            NOTE, ""]
    return "\n".join(out)


def render_terminal(s: Summary) -> str:
    """A compact fixed-width version for pytest's terminal summary."""
    w = 16
    row = lambda label, cells: f"{label:<10}" + "".join(f"{c:>{w}}" for c in cells)  # noqa: E731
    lines = [row("atomic", ["Android", "Windows", "Ubuntu", "Overall"]),
             row("TSR", [s.atomic[k].text() for k in (*PLATFORMS, "overall")]),
             row("composed", ["SW", "MI", "MD", "Overall"]),
             row("TSR", [s.composed[k].tsr.text() for k in (*COMPOSED, "overall")]),
             row("SSR", [s.composed[k].ssr.text() for k in (*COMPOSED, "overall")])]
    errs = sum(s.errors.values())
    lines.append(f"overall TSR {s.overall['tsr'].text()}; errors (not counted) {errs}; unfinished {s.unfinished}")
    return "\n".join(lines)


def load_results(run_dir: Path) -> tuple[list[TaskResult], list[str]]:
    """Every readable `tasks/*/result.json` of a run, and a problem line for each unreadable one."""
    results, problems = [], []
    for path in sorted((Path(run_dir) / "tasks").glob("*/result.json")):
        try:
            results.append(TaskResult.model_validate_json(path.read_text()))
        except (OSError, ValueError) as exc:
            problems.append(f"{path}: {str(exc).splitlines()[0]}")
    return results, problems


def write_summary(run_dir: Path, results: Sequence[TaskResult], agent: dict[str, Any] | None = None) -> Summary:
    """Write summary.json and summary.md of `results` into `run_dir` (atomically)."""
    summary = rollup(results, agent=(agent or {}).get("name"))
    run_dir.mkdir(parents=True, exist_ok=True)
    write_json_atomic(run_dir / "summary.json", summary.model_dump(mode="json"))
    tmp = run_dir / ".summary.md.tmp"
    tmp.write_text(render_markdown(summary))
    tmp.replace(run_dir / "summary.md")
    return summary
