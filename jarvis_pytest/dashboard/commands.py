"""`jarvis dashboard` (and `python start_dashboard.py`): serve the dashboard over a results directory; `jarvis
runs`: the runs of a results directory with their state (in progress, interrupted, finished) and progress."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from jarvis_pytest.dashboard.server import make_server


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--port", type=int, default=8000, help="port to listen on (default 8000; 0 picks a free one)")
    parser.add_argument("--results", type=Path, default=Path("reports"),
                        help="the results directory: one sub-directory per run (default reports/)")
    parser.add_argument("--host", default="127.0.0.1",
                        help="address to bind (default 127.0.0.1; anything else exposes your results to the network)")
    parser.add_argument("--verbose", action="store_true", help="log every request")


def serve(args: argparse.Namespace) -> int:
    results = args.results.resolve()
    if not results.is_dir():
        print(f"dashboard: {results} is not a directory (yet); it will be read when it appears", file=sys.stderr)
    try:
        server = make_server(results, args.host, args.port, verbose=args.verbose)
    except OSError as exc:
        print(f"dashboard: cannot listen on {args.host}:{args.port}: {exc.strerror}", file=sys.stderr)
        return 2
    print(f"dashboard: {server.url}  (results: {results}; Ctrl-C to stop)", flush=True)
    try:
        server.serve_forever(poll_interval=0.5)
    except KeyboardInterrupt:
        pass
    finally:
        server.server_close()
        server.stop_plays()  # the runs its Play button started: their devices go too
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="start_dashboard.py", description=__doc__)
    add_arguments(parser)
    return serve(parser.parse_args(argv))


def list_runs(args: argparse.Namespace) -> int:
    """One line per run, newest first: id, state, agent, tasks done of planned, passed, errors."""
    from jarvis_pytest.dashboard.store import ResultsStore

    runs = ResultsStore(args.results).runs()["runs"]
    if not runs:
        print(f"no runs under {args.results.resolve()}")
    for r in runs:
        c = r.get("counts") or {}
        print(f"{r['id']}\t{r.get('state', '?')}\t{r.get('agent_name') or '-'}\t"
              f"{c.get('done', 0)}/{c.get('total', 0)} done\t{c.get('passed', 0)} passed\t"
              f"{c.get('error', 0)} errors\t{c.get('pending', 0) + c.get('interrupted', 0) + c.get('running', 0)} not finished")
        for problem in r.get("problems") or []:  # each file that cannot be read, by name, under its run
            print(f"  unreadable: {problem['file']}: {problem['message']}")
    return 0


def register(sub) -> None:
    p = sub.add_parser("dashboard", help="serve the evaluation dashboard (live runs, trajectories, tables)")
    add_arguments(p)
    p.set_defaults(func=serve)
    r = sub.add_parser("runs", help="list the runs with their state (in progress, interrupted, finished)")
    r.add_argument("--results", type=Path, default=Path("reports"), help="the results directory (default reports/)")
    r.set_defaults(func=list_runs)
