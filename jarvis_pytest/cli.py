"""The `jarvis` command line. Each area registers its own subcommands in its own module."""

from __future__ import annotations

import argparse
import importlib
import sys

from jarvis_pytest.errors import JarvisError

# Modules that define `register(subparsers)`; each adds its subcommands.
COMMAND_MODULES = [
    "jarvis_pytest.tasks.commands",
    "jarvis_pytest.tasks.qc",
    "jarvis_pytest.infra.commands",
    "jarvis_pytest.dashboard.commands",
    "jarvis_pytest.agents.commands",
    "jarvis_pytest.player.commands",
    "jarvis_pytest.report.reproduce",
    "jarvis_pytest.cluster.commands",
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="jarvis", description="jarvis-pytest: cross-device GUI agent benchmark")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except JarvisError as exc:
        print(f"jarvis {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"jarvis {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
