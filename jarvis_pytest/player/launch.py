"""Start a task in the player: one pytest run of that task with `--agent human`, and the player's address once it
listens (for `jarvis play` and the dashboard's Play button)."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.paths import REPO_ROOT

URL_WAIT = 300.0  # seconds the player gets to listen: the task's devices boot and are set up first
ATOMIC_ID = re.compile(r"(.+)\[seed(\d+)\]")
TASK_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.\-\[\]]*")


class PlayError(RuntimeError):
    """The run stopped before the player listened; `output` is the end of what it printed."""

    def __init__(self, message: str, output: str = ""):
        super().__init__(message)
        self.output = output


def node_id(task_id: str, library: Path | None = None) -> tuple[str, int]:
    """The pytest case of a task id and the instances it needs: `<template>[seedN]` (or a template id alone:
    seed 0) is an atomic case, anything else a composed task's."""
    if not TASK_ID.fullmatch(task_id):
        raise ConfigError(f"{task_id!r} is not a task id", field="TASK",
                          fix="give an id as the dashboard and `pytest --collect-only` show it, e.g. "
                              "ubuntu-mousepad-replace_text[seed0] or sw-0013")
    m = ATOMIC_ID.fullmatch(task_id)
    if m is None:
        from jarvis_pytest.tasks.library import load_library

        if any(t.id == task_id for t in load_library(library or REPO_ROOT / "tasks").templates):
            task_id, m = f"{task_id}[seed0]", ATOMIC_ID.fullmatch(f"{task_id}[seed0]")
    if m is not None:
        return f"tasks/test_atomic.py::test_atomic[{task_id}]", max(2, int(m.group(2)) + 1)
    return f"tasks/test_composed.py::test_composed[{task_id}]", 2


@dataclass
class Play:
    """A play run in progress."""

    task_id: str
    proc: subprocess.Popen
    results_dir: Path
    url_file: Path
    log: Path | None = None
    command: list[str] = field(default_factory=list)

    def output(self) -> str:
        try:
            return self.log.read_text(encoding="utf-8", errors="replace")[-4000:] if self.log else ""
        except OSError:
            return ""

    def _why(self) -> str:
        """Why the run ended without a player, where its result says (a task skipped for want of a device)."""
        for path in sorted((self.results_dir / "tasks").glob("*/result.json")):
            try:
                data = json.loads(path.read_text(encoding="utf-8"))
            except (OSError, ValueError):
                continue
            if data.get("status") in ("skipped", "error"):
                return f": the task was {data['status']} ({data.get('error') or 'no reason given'})"
        return ""

    def wait_url(self, timeout: float = URL_WAIT) -> str:
        """The player's address once it listens; PlayError when the run ends first or `timeout` passes."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.url_file.is_file():
                url = self.url_file.read_text(encoding="utf-8").strip()
                if url:
                    return url
            if self.proc.poll() is not None:
                raise PlayError(f"the run of {self.task_id} ended (exit {self.proc.returncode}) before the player "
                                f"started{self._why()}", self.output())
            time.sleep(0.2)
        raise PlayError(f"the player of {self.task_id} did not start within {timeout:g} s", self.output())


def start_play(task_id: str, results_dir: Path, *, library: Path | None = None, port: int = 0,
               max_steps: int | None = None, task_timeout: float | None = None, pytest_args: list[str] | None = None,
               log: Path | None = None, stdout: IO | None = None) -> Play:
    """Start one pytest run of `task_id` with the agent `human`, writing into `results_dir`. Its output goes to
    `log` (a file) or `stdout` (default: this process's)."""
    node, instances = node_id(task_id, library)
    url_dir = Path(tempfile.mkdtemp(prefix="jarvis-play-"))
    url_file = url_dir / "player.url"
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-q", node, "--agent", "human",
           "--agent-option", f"url_file={url_file}", "--agent-option", f"port={port}",
           "--results-dir", str(results_dir), "--instances", str(instances)]
    if library is not None:
        cmd += ["--library", str(library)]
    if max_steps is not None:
        cmd += ["--max-steps", str(max_steps)]
    if task_timeout is not None:
        cmd += ["--task-timeout", f"{task_timeout:g}"]
    cmd += list(pytest_args or [])
    out: IO | int | None = stdout
    handle = None
    if log is not None:
        log.parent.mkdir(parents=True, exist_ok=True)
        handle = open(log, "w", encoding="utf-8")
        out = handle
    try:
        # a run of its own, one task, no xdist: nothing of an xdist worker that starts it (a test under `-n`) is
        # passed on, else its player would take itself for that worker's and announce under the worker's name
        env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST_XDIST_")}
        proc = subprocess.Popen(cmd, cwd=REPO_ROOT, stdout=out, stderr=subprocess.STDOUT if out is not None else None,
                                stdin=subprocess.DEVNULL, env=env)
    finally:
        if handle is not None:
            handle.close()
    return Play(task_id=task_id, proc=proc, results_dir=Path(results_dir), url_file=url_file, log=log, command=cmd)
