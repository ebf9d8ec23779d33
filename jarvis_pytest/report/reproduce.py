"""`jarvis reproduce RUN_DIR` and `jarvis diff RUN_A RUN_B`: a finished run made again under the conditions of its
run card (`report/run_card.py`), and two runs compared condition by condition and verdict by verdict.

`reproduce` replays the run's command line (its card's `selection.argv`: the agent, its models and settings, the
step limit, trials, workers, backends), without -k/-m, adding `--reproduce RUN_DIR`: the new run then runs exactly
the task trials RUN_DIR planned, and refuses before any device boots, naming each condition this machine or
command does not meet (another image, backend, harness commit, agent setting), unless `--allow-differences`. The
only thing it asks for is an API key the run used (never recorded): from the environment variable the harness
reads, else typed at a prompt. At the end it prints the verdicts that differ (`jarvis diff`).
"""

from __future__ import annotations

import argparse
import getpass
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.report.run_card import REPO_ROOT, differences, informational, read_card

SELECTION_OPTIONS = ("-k", "-m")  # replaced by the plan of the run reproduced
# each model's key option → the variable the harness also reads it from (`plugin/options.py`)
KEY_OPTIONS = {f"--{role}-api-key": f"JARVIS_{role.upper()}_API_KEY" for role in ("planner", "grounder")}



def _without_selection(argv: list[str]) -> list[str]:
    out, skip = [], False
    for arg in argv:
        if skip:
            skip = False
            continue
        if arg in SELECTION_OPTIONS:
            skip = True
            continue
        if any(arg.startswith(o) and len(arg) > 2 for o in SELECTION_OPTIONS):  # -kEXPR, -mEXPR
            continue
        out.append(arg)
    return out


def _keys(argv: list[str], env: dict[str, str], ask: bool) -> list[str]:
    """`argv` with each hidden key (`--planner-api-key ***`) taken out: the key goes to the child through the
    environment variable the harness reads, from this environment or typed at a prompt."""
    out, i = [], 0
    while i < len(argv):
        arg = argv[i]
        name, eq, value = arg.partition("=")
        if name in KEY_OPTIONS:
            var = KEY_OPTIONS[name]
            i += 1 if eq else 2
            if env.get(var):
                continue
            if not ask:
                raise ConfigError(f"the run used {name} and {var} is not set", field=var,
                                  fix=f"export {var}=... (keys are never recorded) and run again")
            env[var] = getpass.getpass(f"{name} (the run used one; it is never recorded): ")
            continue
        out.append(arg)
        i += 1
    return out


def command(run_dir: Path, card: dict[str, Any], results_dir: Path, allow: bool, env: dict[str, str],
            ask: bool) -> tuple[list[str], Path]:
    """The pytest command line that reproduces `run_dir`, and the folder to run it in."""
    selection = card.get("selection") or {}
    argv = _keys(_without_selection(list(selection.get("argv") or [])), env, ask)
    argv += ["--reproduce", str(Path(run_dir).resolve()), "--results-dir", str(results_dir)]
    if allow:
        argv.append("--allow-differences")
    where = REPO_ROOT / (selection.get("invocation") or ".")
    return [sys.executable, "-m", "pytest", *argv], where if where.is_dir() else REPO_ROOT


# -- verdicts ------------------------------------------------------------------------------------------------------
def verdicts(run_dir: Path) -> dict[str, dict[str, Any]]:
    """Result key → {"status", "subtasks": [passed per subtask]} of every result of a run."""
    from jarvis_pytest.report.rollup import load_results

    return {r.key: {"status": r.status, "subtasks": [s.passed for s in r.subtasks]}
            for r in load_results(run_dir)[0]}


def _verdict_text(v: dict[str, Any] | None) -> str:
    if v is None:
        return "(no result)"
    subs = v["subtasks"]
    return v["status"] + (f" {sum(subs)}/{len(subs)}" if subs else "")


def verdict_differences(a: dict[str, dict[str, Any]], b: dict[str, dict[str, Any]]) -> list[tuple[str, str, str]]:
    """(key, verdict in a, verdict in b) of every task trial whose status or subtask verdicts differ."""
    return [(k, _verdict_text(a.get(k)), _verdict_text(b.get(k))) for k in sorted(set(a) | set(b))
            if a.get(k) != b.get(k)]


def _short(text: str | None, width: int = 60) -> str:
    text = "(none)" if text is None else text
    return text if len(text) <= width else text[: width - 1] + "…"


def print_diff(run_a: Path, run_b: Path, out=sys.stdout) -> tuple[int, int]:
    """Print the conditions and verdicts that differ between two runs; (conditions, verdicts) that differ."""
    _, card_a = read_card(run_a)
    _, card_b = read_card(run_b)
    found = differences(card_a, card_b)
    conditions = [d for d in found if not informational(d[0])]
    info = [d for d in found if informational(d[0])]
    print(f"A: {run_a}\nB: {run_b}", file=out)
    print(f"\nconditions that differ: {len(conditions)}", file=out)
    for key, a, b in conditions:
        print(f"  {key}\n    A: {_short(a)}\n    B: {_short(b)}", file=out)
    if info:
        print(f"informational (where and how it ran): {', '.join(k for k, _, _ in info)}", file=out)
    va, vb = verdicts(run_a), verdicts(run_b)
    changed = verdict_differences(va, vb)
    same = len(set(va) & set(vb)) - sum(1 for k, _, _ in changed if k in va and k in vb)
    print(f"\nverdicts: {same} of {len(set(va) | set(vb))} task trials the same; {len(changed)} differ", file=out)
    width = max([len(k) for k, _, _ in changed] + [4])
    for key, a, b in changed:
        print(f"  {key:<{width}}  A: {a:<14} B: {b}", file=out)
    return len(conditions), len(changed)


# -- commands ------------------------------------------------------------------------------------------------------
def run_diff(args: argparse.Namespace) -> int:
    for d in (args.run_a, args.run_b):
        if not Path(d).is_dir():
            raise ConfigError("no such run folder", path=d, fix="give two folders under reports/")
    conditions, changed = print_diff(Path(args.run_a), Path(args.run_b))
    return 1 if conditions or changed else 0


def run_reproduce(args: argparse.Namespace) -> int:
    run_dir = Path(args.run_dir)
    if not run_dir.is_dir():
        raise ConfigError("no such run folder", path=run_dir, fix="give a folder under reports/")
    meta, card = read_card(run_dir)
    if meta.get("state") == "running":
        from jarvis_pytest.results.run_state import liveness

        if liveness(meta) == "running":
            raise ConfigError("the run is still going", path=run_dir, fix="wait for it to end")
    from jarvis_pytest.results.run_state import new_run_id

    results_dir = Path(args.results_dir or REPO_ROOT / "reports" / new_run_id()).resolve()
    env = dict(os.environ)
    cmd, cwd = command(run_dir, card, results_dir, args.allow_differences, env, ask=sys.stdin.isatty())
    print(f"jarvis reproduce: {' '.join(cmd[2:])}  (in {cwd})", flush=True)
    if args.dry_run:
        return 0
    rc = subprocess.run(cmd, cwd=cwd, env=env).returncode
    if rc not in (0, 1) or not (results_dir / "run.json").is_file():
        print(f"jarvis reproduce: the run did not finish (pytest exit {rc})", file=sys.stderr)
        return rc or 2
    print("", flush=True)
    _, changed = print_diff(run_dir, results_dir)
    return 1 if changed else 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("reproduce", help="run a finished run again under the conditions of its run card (refused, "
                       "naming each difference, where they cannot be met), then compare the verdicts",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("run_dir", metavar="RUN_DIR", help="the run to reproduce (reports/<run id>)")
    p.add_argument("--allow-differences", action="store_true", help="run even where conditions differ (they are "
                   "recorded in the new run's card)")
    p.add_argument("--results-dir", default=None, help="where the new run writes (default reports/<new run id>)")
    p.add_argument("--dry-run", action="store_true", help="print the command and stop")
    p.set_defaults(func=run_reproduce)
    d = sub.add_parser("diff", help="the conditions (run cards) and verdicts that differ between two runs; exit 1 "
                       "when any does")
    d.add_argument("run_a", metavar="RUN_A")
    d.add_argument("run_b", metavar="RUN_B")
    d.set_defaults(func=run_diff)
