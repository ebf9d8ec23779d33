"""`jarvis qc`: the paper's quality gate over the atomic task library, made adversarial.

For every task instance every evaluator must fail on the freshly set-up device, the task must fail on each of its
near-miss wrong states (`negatives`: at least an `artefact` and one wrong, partial or damaging operation), it
must pass after the oracle, and it must pass after its GUI solution (`gui_solution`: the agent's actions only, run
by the `gui-oracle` on fresh devices; `harness/gui_check.py`). A template that says the GUI cannot solve it on the
run's backend (`gui_infeasible`) shows the reason instead; one with neither ("no GUI solution yet") violates the
gate on the platforms whose every template has one (`GUI_REQUIRED`: Ubuntu and Windows), and is counted elsewhere. A composed task (`--composed`) must
fail on the fresh devices and pass after the oracle too, and each of its broken chains (`harness/chain_negatives.py`)
must fail it at the subtask meant to catch it. The gate runs as a benchmark run (`pytest tasks/test_atomic.py --qc`, so it has the harness's parallelism, pre-warming,
results and --resume), then prints one row per instance and exits non-zero on any violation or error.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from jarvis_pytest.paths import REPO_ROOT
from jarvis_pytest.report.rollup import load_results
from jarvis_pytest.results.model import SubtaskVerdict, TaskResult


def _state(verdicts: list[SubtaskVerdict] | None, want: bool) -> str:
    """"pass"/"fail" when every subtask (want=True) passed or every evaluator (want=False) failed, else the
    violation in capitals."""
    if not verdicts:
        return "-"
    good = all(v.passed for v in verdicts) if want else not any(e.passed for v in verdicts for e in v.evaluators)
    return ("pass" if want else "fail") if good else ("FAIL" if want else "PASS")


def _negatives(result: TaskResult) -> tuple[str, str]:
    """The negatives column ("2/2 fail", or how many PASS; for a composed task's broken chains "5/5 caught", or
    how many NOT CAUGHT) and the first violation's reason ("" when none)."""
    negs = result.qc_negatives
    if negs is None:
        return "-", ""
    chains = any(n.expect is not None for n in negs)
    rejected = sum(n.violation() is None for n in negs)
    good, bad = ("caught", "NOT CAUGHT") if chains else ("fail", "PASS")
    cell = f"{rejected}/{len(negs)} {good}" if rejected == len(negs) else f"{len(negs) - rejected}/{len(negs)} {bad}"
    reason = next((why for n in negs if (why := n.violation())), "")
    kinds = {n.kind for n in negs}
    if not reason and not chains and ("artefact" not in kinds or not kinds - {"artefact"}):
        return cell + " (too few)", ("needs negatives of kind `artefact` and of `wrong`/`partial`/`damage` "
                                      f"(has {sorted(kinds) or 'none'})")
    return cell, reason


GUI_CELLS = {"passed": "pass", "failed": "FAIL", "infeasible": "infeasible", "none": "none yet"}
# platforms whose templates must each have a GUI solution or say why the GUI cannot solve them: every Ubuntu and
# Windows template has one; Android's are not written (no Android device runs here to prove them)
GUI_REQUIRED = frozenset({"ubuntu", "windows"})


def _gui(result: TaskResult) -> tuple[str, str]:
    """The GUI column (`pass`, `FAIL`, `infeasible`, `none yet`; `-` without the check) and, when a GUI solution
    fails or a template of a `GUI_REQUIRED` platform has none, why ("" otherwise)."""
    checks = result.qc_gui or []
    failed = next((g for g in checks if g.state == "failed"), None)
    if failed is not None:
        return "FAIL", f"GUI solution fails: {failed.reason}"
    missing = next((g for g in checks if g.state == "none"), None)
    if missing is not None and result.platforms and result.platforms[0] in GUI_REQUIRED:
        return GUI_CELLS["none"], (f"no GUI solution: {missing.template} needs a `gui_solution`, or `gui_infeasible` "
                                   f"for {missing.backend or 'its backend'} with the reason")
    for state in ("infeasible", "none", "passed"):
        if any(g.state == state for g in checks):
            return GUI_CELLS[state], ""
    return "-", ""


def qc_row(result: TaskResult) -> dict[str, str]:
    """One line of the table: the task, its verdict on the fresh device (must be `fail`), on its negatives (each
    must fail), after the oracle (must be `pass`), after its GUI solution (must be `pass` where it has one), the
    gate's outcome and the first reason when it is violated."""
    if result.status == "skipped":  # no device for it here: counted apart, never a violation
        return {"task": result.task_id, "fresh": "-", "negatives": "-", "oracle": "-", "gui": "-", "gate": "skipped",
                "reason": (result.error or "")[:200]}
    before = _state(result.qc_initial, want=False)
    after = _state(result.subtasks, want=True)
    negatives, negative_reason = _negatives(result)
    gui, gui_reason = _gui(result)
    ok = result.status == "passed" and not negative_reason and not gui_reason
    reason = ""
    if result.status == "error":
        reason = (result.error or "error").splitlines()[0]
    elif not ok:
        bad = [e for v in (result.qc_initial or []) for e in v.evaluators if e.passed]
        bad_after = [e for v in result.subtasks if not v.passed for e in v.evaluators if not e.passed]
        if bad:
            reason = "passes untouched: " + bad[0].func + ": " + bad[0].reason
        elif bad_after:
            reason = "oracle fails: " + bad_after[0].func + ": " + bad_after[0].reason
        else:
            reason = negative_reason or gui_reason
    return {"task": result.task_id, "fresh": before, "negatives": negatives, "oracle": after, "gui": gui,
            "gate": "ok" if ok else ("ERROR" if result.status == "error" else "VIOLATED"), "reason": reason[:200]}


def render_table(rows: list[dict[str, str]]) -> str:
    """A Markdown table of the gate's rows, then a one-line total."""
    lines = ["| task | fresh device | negatives | after oracle | after GUI solution | gate | reason |",
             "|---|---|---|---|---|---|---|"]
    lines += [f"| {r['task']} | {r['fresh']} | {r.get('negatives', '-')} | {r['oracle']} | {r.get('gui', '-')} | "
              f"{r['gate']} | {r['reason']} |" for r in rows]
    ok = sum(r["gate"] == "ok" for r in rows)
    skipped = sum(r["gate"] == "skipped" for r in rows)
    lines.append(f"\n{ok}/{len(rows) - skipped} instances pass the quality gate"
                 + (f"; {skipped} skipped: no device for them on this machine" if skipped else ""))
    return "\n".join(lines)


def gui_table(results: list[TaskResult]) -> str:
    """Per application (and backend): how many of its templates the GUI solves (every instance passed after its
    GUI solution), fail it, are infeasible there, or have no GUI solution yet; then each infeasible template's
    reason ("" when no task had the check)."""
    per_template: dict[tuple[str, str, str], list[str]] = {}  # (backend label, app, template) → instance states
    reasons: dict[tuple[str, str], str] = {}
    for result in results:
        for g in result.qc_gui or []:
            label = f"{result.platforms[0] if result.platforms else '?'} ({g.backend})" if g.backend else "?"
            per_template.setdefault((label, g.app, g.template), []).append(g.state)
            if g.state == "infeasible":
                reasons[(g.template, label)] = g.reason
    if not per_template:
        return ""
    counts: dict[tuple[str, str], dict[str, int]] = {}
    for (label, app, _), states in sorted(per_template.items()):
        state = next(s for s in ("failed", "none", "infeasible", "passed") if s in states)
        row = counts.setdefault((label, app), {"passed": 0, "failed": 0, "infeasible": 0, "none": 0})
        row[state] += 1
    lines = ["| backend | application | solved through the GUI | GUI solution fails | infeasible there | "
             "no GUI solution yet |", "|---|---|--:|--:|--:|--:|"]
    lines += [f"| {label} | {app} | {c['passed']} | {c['failed']} | {c['infeasible']} | {c['none']} |"
              for (label, app), c in counts.items()]
    total = {k: sum(c[k] for c in counts.values()) for k in ("passed", "failed", "infeasible", "none")}
    lines.append(f"\n{total['passed']} templates solved through the GUI, {total['failed']} failing, "
                 f"{total['infeasible']} infeasible on their backend, {total['none']} without a GUI solution yet "
                 f"(a violation on {' and '.join(sorted(GUI_REQUIRED))})")
    lines += [f"- infeasible: {template} on {label}: {why}" for (template, label), why in sorted(reasons.items())]
    return "\n".join(lines)


def chain_table(results: list[TaskResult]) -> str:
    """Per kind of broken chain: on how many tasks it was made, and how many of those it failed at the subtask
    meant to catch it ("" when no task had one)."""
    made: dict[str, list[bool]] = {}
    for result in results:
        for n in result.qc_negatives or []:
            if n.expect is not None:
                made.setdefault(n.kind.removeprefix("chain:"), []).append(not n.passed and not n.error)
    if not made:
        return ""
    lines = ["| broken chain | tasks | caught at the right subtask |", "|---|--:|--:|"]
    lines += [f"| {kind} | {len(got)} | {sum(got)} |" for kind, got in made.items()]
    return "\n".join(lines)


def pytest_argv(args: argparse.Namespace, run_dir: Path) -> list[str]:
    """The benchmark run that performs the gate."""
    module = "test_composed.py" if args.composed else "test_atomic.py"
    argv = [sys.executable, "-m", "pytest", str(REPO_ROOT / "tasks" / module), "--qc",
            "-p", "no:cacheprovider", "-q", "--instances", str(args.instances), "--library", str(args.library),
            "--results-dir" if not args.resume else "--resume", str(run_dir)]
    for dataset in args.dataset or []:
        argv += ["--dataset", str(dataset)]
    if args.platform:
        argv += ["-m", args.platform]
    if args.k:
        argv += ["-k", args.k]
    if args.n:
        argv += ["-n", str(args.n)]
    extra = list(args.pytest_args)
    return argv + (extra[1:] if extra[:1] == ["--"] else extra)


def run_qc(args: argparse.Namespace) -> int:
    run_dir = Path(args.resume or args.results_dir or
                   REPO_ROOT / "reports" / ("qc-" + datetime.now(timezone.utc).strftime("%Y%m%d-%H%M%S")))
    proc = subprocess.run(pytest_argv(args, run_dir), cwd=REPO_ROOT)
    results, problems = load_results(run_dir)
    if not results:
        print(f"jarvis qc: no task ran (pytest exit {proc.returncode}); see the output above", file=sys.stderr)
        return 2 if proc.returncode == 4 else (proc.returncode or 1)  # a usage error is the command's usage error
    rows = [qc_row(r) for r in results]
    table = render_table(rows)
    for extra in (gui_table(results), chain_table(results)):
        if extra:
            table += "\n\n" + extra
    (run_dir / "qc.md").write_text(table + "\n", encoding="utf-8")
    print(table)
    for p in problems:
        print(p, file=sys.stderr)
    print(f"results: {run_dir} (table in qc.md)")
    violated = any(r["gate"] not in ("ok", "skipped") for r in rows) or bool(problems)
    return 1 if violated or proc.returncode not in (0, 5) else 0


def register(sub: Any) -> None:
    p = sub.add_parser("qc", help="quality gate: every task instance fails on its fresh device and on its negatives, "
                       "and passes after the oracle and after its GUI solution (prints a table; exit 1 on any "
                       "violation)")
    p.add_argument("--platform", default=None, help="only this platform's tasks (e.g. ubuntu)")
    p.add_argument("-k", default=None, metavar="EXPR", help="only tasks matching this pytest -k expression")
    p.add_argument("-n", default=None, metavar="N", help="parallel workers (pytest-xdist), e.g. 2 or auto")
    p.add_argument("--instances", type=int, default=2, help="seeded instances per template (default 2)")
    p.add_argument("--composed", action="store_true", help="gate the composed tasks of the datasets instead: every "
                   "subtask evaluator fails on the fresh devices, the whole task passes after the oracle, and each "
                   "broken chain of its transfers fails at the transfer")
    p.add_argument("--dataset", action="append", type=Path, metavar="FILE",
                   help="with --composed: these dataset files (default tasks/composed/*.json)")
    p.add_argument("--library", type=Path, default=REPO_ROOT / "tasks", help="template folder (default tasks/)")
    p.add_argument("--results-dir", default=None, help="where to write the gate's results (default reports/qc-<time>)")
    p.add_argument("--resume", default=None, metavar="RUN_DIR", help="continue an interrupted gate run")
    p.add_argument("pytest_args", nargs=argparse.REMAINDER, help="further pytest arguments after --")
    p.set_defaults(func=run_qc)
