"""Command-line options of the benchmark (`pytest --agent ...`) and their validation at start-up."""

from __future__ import annotations

import os
import uuid
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import pytest

from jarvis_pytest.plugin.loop import LoopLimits

REPO_ROOT = Path(__file__).resolve().parents[2]


def addoption(parser: pytest.Parser) -> None:
    g = parser.getgroup("jarvis", "jarvis-pytest benchmark")
    g.addoption("--agent", default=None, help="agent to evaluate: a built-in (oracle, noop, replay), a name from "
                "agents/, or module:Class")
    g.addoption("--agent-option", action="append", default=[], metavar="KEY=VALUE",
                help="an option passed to the agent (repeatable)")
    for role in ("planner", "grounder"):
        g.addoption(f"--{role}-base-url", default=None, help=f"OpenAI-compatible base URL of the {role} "
                    f"(env JARVIS_{role.upper()}_BASE_URL)")
        g.addoption(f"--{role}-model", default=None, help=f"model name of the {role} (env JARVIS_{role.upper()}_MODEL)")
        g.addoption(f"--{role}-api-key", default=None, help=f"API key of the {role} (env "
                    f"JARVIS_{role.upper()}_API_KEY); never written to results")
    g.addoption("--max-steps", type=int, default=50, help="step limit per task (default 50)")
    g.addoption("--step-timeout", type=float, default=300.0, help="seconds for one agent decision (default 300)")
    g.addoption("--task-timeout", type=float, default=3600.0, help="seconds for one task's loop (default 3600)")
    g.addoption("--results-dir", default=None, help="where to write results (default reports/<run id>/)")
    g.addoption("--resume", default=None, metavar="RUN_DIR", help="continue a run: tasks with a result from the "
                "same agent configuration are not run again; errors and unfinished tasks are")
    g.addoption("--device-memory", default="4g", help="memory limit per device container (default 4g)")
    g.addoption("--device-cpus", type=float, default=None, help="CPU limit per device container (default none)")
    g.addoption("--keep-devices", action="store_true", help="keep each task's devices after it ends, for debugging")
    g.addoption("--no-prewarm", action="store_true", help="do not boot the next task's devices in advance")
    g.addoption("--library", default=str(REPO_ROOT / "tasks"), help="folder of atomic task templates")
    g.addoption("--dataset", action="append", default=None, metavar="FILE",
                help="composed-task dataset file(s) (default: tasks/composed/*.json)")
    g.addoption("--instances", type=int, default=2, help="seeded instances per atomic template (default 2)")
    g.addoption("--transfer", default=None, choices=("copyparty", "alist"),
                help="the network drive's server: copyparty (offline default, built here) or alist (an AList/"
                "OpenList image pulled from a registry, $JARVIS_ALIST_IMAGE); default $JARVIS_TRANSFER or copyparty")
    g.addoption("--qc", action="store_true", help="quality gate of the tasks: evaluate right after set-up (every "
                "evaluator must fail), run the oracle, evaluate again (every subtask must pass); implies --agent oracle")


@dataclass
class JarvisOptions:
    agent: str | None
    agent_options: dict[str, str]
    limits: LoopLimits
    results_dir: Path | None
    resume: Path | None
    device_memory: str
    device_cpus: float | None
    keep_devices: bool
    prewarm: bool
    library: Path
    datasets: list[Path]
    instances: int
    transfer: str | None = None
    qc: bool = False
    endpoints: dict[str, dict[str, str | None]] = field(default_factory=dict)


def _endpoint(config: pytest.Config, role: str) -> dict[str, str | None]:
    env = os.environ
    return {
        "base_url": config.getoption(f"--{role}-base-url") or env.get(f"JARVIS_{role.upper()}_BASE_URL"),
        "model": config.getoption(f"--{role}-model") or env.get(f"JARVIS_{role.upper()}_MODEL"),
        "api_key": config.getoption(f"--{role}-api-key") or env.get(f"JARVIS_{role.upper()}_API_KEY"),
    }


def read_options(config: pytest.Config) -> JarvisOptions:
    pairs: dict[str, str] = {}
    for item in config.getoption("--agent-option") or []:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise pytest.UsageError(f"--agent-option {item!r}: expected KEY=VALUE")
        pairs[key.strip()] = value
    datasets = config.getoption("--dataset")
    if datasets is None:
        datasets = sorted(str(p) for p in (REPO_ROOT / "tasks" / "composed").glob("*.json"))
    limits = LoopLimits(max_steps=config.getoption("--max-steps"), step_timeout=config.getoption("--step-timeout"),
                        task_timeout=config.getoption("--task-timeout"))
    if limits.max_steps < 1:
        raise pytest.UsageError("--max-steps must be at least 1")
    agent = config.getoption("--agent")
    if config.getoption("--qc"):
        if agent not in (None, "oracle"):
            raise pytest.UsageError(f"--qc runs the tasks' oracle solutions; drop --agent {agent}")
        agent = "oracle"
    results_dir = config.getoption("--results-dir")
    resume = config.getoption("--resume")
    if resume and not Path(resume).is_dir():
        raise pytest.UsageError(f"--resume {resume}: no such run directory")
    return JarvisOptions(
        agent=agent, agent_options=pairs, limits=limits,
        results_dir=Path(results_dir) if results_dir else None, resume=Path(resume) if resume else None,
        device_memory=config.getoption("--device-memory"), device_cpus=config.getoption("--device-cpus"),
        keep_devices=config.getoption("--keep-devices"), prewarm=not config.getoption("--no-prewarm"),
        library=Path(config.getoption("--library")), datasets=[Path(p) for p in datasets],
        instances=config.getoption("--instances"), transfer=config.getoption("--transfer"),
        qc=config.getoption("--qc"),
        endpoints={"planner": _endpoint(config, "planner"), "grounder": _endpoint(config, "grounder")},
    )


def new_run_id() -> str:
    return datetime.now(timezone.utc).strftime("%Y%m%d-%H%M%S-") + uuid.uuid4().hex[:6]
