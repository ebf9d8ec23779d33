"""`jarvis play <task>`: play a task yourself in the browser; `jarvis gui-solution <run>/tasks/<task>`: save a run
as its template's GUI solution."""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import webbrowser
from pathlib import Path

from jarvis_pytest.player.launch import REPO_ROOT, PlayError, start_play


def _new_results_dir() -> Path:
    from jarvis_pytest.results.run_state import new_run_id

    return REPO_ROOT / "reports" / f"{new_run_id()}-play"


def play(args: argparse.Namespace) -> int:
    results = (args.results_dir or _new_results_dir()).resolve()
    extra = args.pytest_args[1:] if args.pytest_args[:1] == ["--"] else args.pytest_args
    run = start_play(args.task, results, library=args.library, port=args.port, max_steps=args.max_steps,
                     task_timeout=args.task_timeout, pytest_args=extra)
    try:
        try:
            url = run.wait_url()
        except PlayError as exc:
            print(f"jarvis play: {exc}", file=sys.stderr)
            run.proc.wait()
            return run.proc.returncode or 1
        print(f"\njarvis play: {args.task} is ready in the player: {url}\n", flush=True)
        if not args.no_open:
            webbrowser.open(url)
        code = run.proc.wait()
    except KeyboardInterrupt:  # the run gets the same signal and stops its devices
        run.proc.wait()
        raise
    _report(results)
    return code


def _report(results: Path) -> None:
    """The played task's verdict and times, and how to replay it or save it as a GUI solution."""
    found = sorted((results / "tasks").glob("*/result.json"))
    if not found:
        return
    data = json.loads(found[0].read_text(encoding="utf-8"))
    d = data.get("durations") or {}
    steps = data.get("steps") or 0
    per_step = f", {d['agent'] / steps:.1f} s a step" if steps and "agent" in d else ""
    print(f"jarvis play: {data['task_id']}: {data['status']} ({data.get('end_reason') or '-'}) in {steps} steps; "
          f"your time {d.get('loop', 0):.1f} s{per_step}", flush=True)
    traj = found[0].parent / "traj.jsonl"
    print(f"  replay it:   pytest {shlex.quote(_node(data['task_id']))} --agent replay "
          f"--agent-option file={shlex.quote(str(traj))}")
    print(f"  save it as the template's GUI solution:   jarvis gui-solution {shlex.quote(str(found[0].parent))}")


def _node(task_id: str) -> str:
    from jarvis_pytest.player.launch import node_id

    return node_id(task_id)[0]


def gui_solution(args: argparse.Namespace) -> int:
    from jarvis_pytest.player.solution import save

    target, steps, notes = save(args.task_dir, args.library, out=args.out, write=args.write, force=args.force,
                                max_wait=args.max_wait)
    for note in notes:
        print(f"note: {note}", file=sys.stderr)
    if target is None:
        print(json.dumps({"gui_solution": steps}, indent=2, ensure_ascii=False))
    else:
        print(f"gui-solution: {len(steps)} steps written to {target}; check it with `jarvis qc -k <template id>`")
    return 0


def register(sub) -> None:
    p = sub.add_parser("play", help="play a task yourself in the browser (the agent `human`)",
                       description="Boot the task's devices and show their screens in the browser: click, type, "
                                   "scroll and press keys there, switch devices with the tabs, end with DONE or "
                                   "FAIL. The run is an ordinary benchmark run of the agent `human`.")
    p.add_argument("task", help="the task id, e.g. ubuntu-mousepad-replace_text[seed0] or sw-0013")
    p.add_argument("--results-dir", type=Path, default=None, help="where to write the run (default reports/<run id>-play)")
    p.add_argument("--library", type=Path, default=None, help="folder of atomic task templates (default tasks/)")
    p.add_argument("--port", type=int, default=0, help="the player's port on 127.0.0.1 (default 0: a free one)")
    p.add_argument("--max-steps", type=int, default=None, help="step limit (default the benchmark's, 50)")
    p.add_argument("--task-timeout", type=float, default=None,
                   help="seconds for the whole task (default the benchmark's, 3600); a step has no shorter limit")
    p.add_argument("--no-open", action="store_true", help="print the player's address, do not open a browser")
    p.add_argument("pytest_args", nargs="*", help="further pytest arguments, after --")
    p.set_defaults(func=play)
    g = sub.add_parser("gui-solution", help="save a run (e.g. one played with jarvis play) as its template's "
                       "gui_solution", description="Print the GUI solution a run's trajectory makes (plain actions, "
                       "the instance's values as placeholders, the recorded pace as WAITs), checked as templates are.")
    g.add_argument("task_dir", type=Path, help="the task's folder of the run: reports/<run>/tasks/<task>")
    g.add_argument("--library", type=Path, default=REPO_ROOT / "tasks", help="template folder (default tasks/)")
    where = g.add_mutually_exclusive_group()
    where.add_argument("--out", type=Path, default=None, help="write the template with the GUI solution to this file")
    where.add_argument("--write", action="store_true", help="put the GUI solution into the template's own file "
                       "(rewritten with 2-space indentation)")
    g.add_argument("--force", action="store_true", help="with --write: replace a GUI solution the template has")
    g.add_argument("--max-wait", type=float, default=5.0, help="seconds of one WAIT for the recorded pace, at most")
    g.set_defaults(func=gui_solution)
