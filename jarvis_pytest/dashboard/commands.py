"""`jarvis dashboard` (and `python start_dashboard.py`): serve the dashboard over a results directory."""

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
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="start_dashboard.py", description=__doc__)
    add_arguments(parser)
    return serve(parser.parse_args(argv))


def register(sub) -> None:
    p = sub.add_parser("dashboard", help="serve the evaluation dashboard (live runs, trajectories, tables)")
    add_arguments(p)
    p.set_defaults(func=serve)
