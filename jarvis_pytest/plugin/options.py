"""Command-line options of the benchmark (`pytest --agent ...`) and their validation at start-up."""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from jarvis_pytest.devices.backend import ALIASES, BUILTIN, backend_option_pairs, check_backend_options
from jarvis_pytest.cluster.connect import configured as cluster_address
from jarvis_pytest.errors import ConfigError
from jarvis_pytest.infra import engines
from jarvis_pytest.infra.containers import PIDS_LIMIT, pids_limit
from jarvis_pytest.environments.pool import PREWARM_RESERVE_MB
from jarvis_pytest.harness.loop import LoopLimits
from jarvis_pytest.paths import REPO_ROOT

BACKEND_OPTION = "--backend-option"
BACKEND_OPTION_ALIASES = {"--android-serial": "android.serial", "--android-image": "android.image"}  # older flags


def addoption(parser: pytest.Parser) -> None:
    g = parser.getgroup("jarvis", "jarvis-pytest benchmark")
    g.addoption("--agent", default=None, help="agent to evaluate: a built-in (oracle, gui-oracle: the GUI "
                "solutions; human: a person in the browser player, see `jarvis play`; noop; replay), a name from "
                "agents/, or module:Class")
    g.addoption("--agent-option", action="append", default=[], metavar="KEY=VALUE",
                help="an option passed to the agent (repeatable)")
    for role in ("planner", "grounder"):
        g.addoption(f"--{role}-base-url", default=None, help=f"OpenAI-compatible base URL of the {role} "
                    f"(env JARVIS_{role.upper()}_BASE_URL)")
        g.addoption(f"--{role}-model", default=None, help=f"model name of the {role} (env JARVIS_{role.upper()}_MODEL)")
        g.addoption(f"--{role}-api-key", default=None, help=f"API key of the {role} (env "
                    f"JARVIS_{role.upper()}_API_KEY); never written to results")
    g.addoption("--max-steps", default="50", help="step limit per task (default 50)")
    g.addoption("--step-timeout", default="300", help="seconds for one agent decision, model calls included; "
                "past it the task ends as an infrastructure error (default 300)")
    g.addoption("--task-timeout", default="3600", help="seconds for one task's agent loop; past it the task ends "
                "with status `timeout`, counted apart from the rates (default 3600)")
    g.addoption("--trials", default="1", help="run every selected task K times, each on fresh devices (ids gain "
                "-trial<i>); the summary gives the mean rate over trials, pass@K, pass^K and the tasks whose trials "
                "disagree (default 1)")
    g.addoption("--reproduce", default=None, metavar="RUN_DIR", help="run again the tasks and trials an earlier "
                "run planned (its plan.json), under the conditions of its run card: refused, naming each difference, "
                "where this machine or command differs (another image, backend, harness, agent setting) unless "
                "--allow-differences; what `jarvis reproduce RUN_DIR` runs")
    g.addoption("--allow-differences", action="store_true", help="with --reproduce: run even where the conditions "
                "differ from the run's card (the differences are recorded in the new run's card)")
    g.addoption("--results-dir", default=None, help="where to write results (default reports/<run id>/)")
    g.addoption("--resume", default=None, metavar="RUN_DIR", help="continue a run: tasks with a result from the "
                "same agent configuration are not run again; errors and unfinished tasks are")
    g.addoption("--device-memory", default=None, help="memory limit per device container, e.g. 4g or 1536m "
                "(default: the platform's own, 4g for Ubuntu)")
    g.addoption("--device-cpus", default=None, help="CPU limit per device container, e.g. 1.5 (default: the "
                "backend's own, else all cores but one on machines with more than two); the process limit is "
                f"$JARVIS_DEVICE_PIDS (default {PIDS_LIMIT}, `none`: no limit)")
    for platform, names in BUILTIN.items():  # one --PLATFORM-backend per platform, from the registry
        aliases = "".join(f" (alias {a}: {n})" for (p, a), n in ALIASES.items() if p == platform)
        g.addoption(f"--{platform}-backend", default="auto", help=f"the {platform} device: auto (the first of "
                    f"{', '.join(names)} that can run here) or one of them{aliases}; results record which ran")
    g.addoption(BACKEND_OPTION, action="append", default=[], metavar="PLATFORM.KEY=VALUE",
                help="a setting of a device backend, e.g. windows.version=10 or android.serial=emulator-5554 "
                "(repeatable; a wrong key lists the valid ones)")
    for flag, key in BACKEND_OPTION_ALIASES.items():
        g.addoption(flag, default=None, help=f"the same as {BACKEND_OPTION} {key}=VALUE")
    g.addoption("--allow-egress", action="store_true", help="let devices reach beyond their task network (the "
                "host, the local network, the internet); off by default, and recorded in every result")
    g.addoption("--keep-devices", action="store_true", help="keep each task's devices after it ends, for debugging")
    g.addoption("--no-prewarm", action="store_true", help="do not boot the next task's devices in advance")
    g.addoption("--prewarm-reserve-mb", default=str(PREWARM_RESERVE_MB), help="memory (MB) a pre-warm leaves "
                "free for running tasks: the next task's devices start booting only while this much stays available "
                f"beside them (default {PREWARM_RESERVE_MB})")
    g.addoption("--library", default=str(REPO_ROOT / "tasks"), help="folder of atomic task templates")
    g.addoption("--dataset", action="append", default=None, metavar="FILE",
                help="composed-task dataset file(s) (default: tasks/composed/*.json)")
    g.addoption("--instances", default="2", help="seeded instances per atomic template (default 2)")
    g.addoption("--transfer", default=None, choices=("copyparty", "alist"),
                help="the network drive's server: copyparty (offline default, built here) or alist (an AList/"
                "OpenList image pulled from a registry, $JARVIS_ALIST_IMAGE); default $JARVIS_TRANSFER or copyparty")
    g.addoption("--docker-host", action="append", default=None, metavar="URL",
                help="a Docker engine to run devices on (repeatable: xdist workers are spread over the engines, each "
                "task's devices on one); unix://, tcp://127.0.0.1:PORT or ssh:// URLs of engines on this machine; "
                "default: [tool.jarvis] docker_hosts in pyproject.toml, else the local engine")
    g.addoption("--ray", default=None, metavar="ADDRESS", help="run each task's devices on a node of the Ray "
                "cluster at ADDRESS (HOST:PORT of its head; nodes declare jarvis_device_slots, see the README); the "
                "agent loop stays here; default: [tool.jarvis] ray in pyproject.toml, else no Ray")
    g.addoption("--qc", action="store_true", help="quality gate of the tasks: evaluate right after set-up (every "
                "evaluator must fail), run the oracle, evaluate again (every subtask must pass); implies --agent oracle")


@dataclass
class JarvisOptions:
    agent: str | None
    agent_options: dict[str, str]
    limits: LoopLimits
    results_dir: Path | None
    resume: Path | None
    device_memory: str | None
    device_cpus: float | None
    keep_devices: bool
    prewarm: bool
    library: Path
    datasets: list[Path]
    instances: int
    transfer: str | None = None
    prewarm_reserve_mb: float = PREWARM_RESERVE_MB
    qc: bool = False
    endpoints: dict[str, dict[str, str | None]] = field(default_factory=dict)
    allow_egress: bool = False
    backends: dict[str, str] = field(default_factory=dict)  # platform → backend name asked for (absent: auto)
    backend_options: dict[str, dict[str, str]] = field(default_factory=dict)  # platform → key → text (as given)
    docker_hosts: tuple[str, ...] = ()  # the run's Docker engines (`infra/engines.py`); empty: the local one
    ray: str | None = None  # the Ray cluster whose nodes run the devices (`cluster/`); None: this machine's engines
    trials: int = 1  # each selected task runs this many times, on fresh devices each time
    reproduce: Path | None = None  # an earlier run whose planned tasks (and trials) are run again, and only those,
    #                               under the conditions of its run card
    allow_differences: bool = False  # --reproduce although conditions differ


def _endpoint(config: pytest.Config, role: str) -> dict[str, str | None]:
    env = os.environ
    return {
        "base_url": config.getoption(f"--{role}-base-url") or env.get(f"JARVIS_{role.upper()}_BASE_URL"),
        "model": config.getoption(f"--{role}-model") or env.get(f"JARVIS_{role.upper()}_MODEL"),
        "api_key": config.getoption(f"--{role}-api-key") or env.get(f"JARVIS_{role.upper()}_API_KEY"),
    }


MEMORY = re.compile(r"^\d+(\.\d+)?[bkmg]?$", re.IGNORECASE)


def _bad(option: str, value: object, fix: str) -> ConfigError:
    return ConfigError(f"{value!r} is not valid", field=option, fix=fix)


def _number(config: pytest.Config, option: str, kind: type, *, minimum: float, fix: str) -> float | int:
    """An option's value as `kind`, at least `minimum`; one clear error otherwise."""
    raw = config.getoption(option)
    try:
        value = kind(raw)
    except (TypeError, ValueError):
        raise _bad(option, raw, fix) from None
    if value != value or value < minimum or value in (float("inf"),):  # NaN, too small, infinite
        raise _bad(option, raw, fix)
    return value


def _directory_option(config: pytest.Config, option: str) -> Path | None:
    raw = config.getoption(option)
    if not raw:
        return None
    path = Path(raw)
    if path.exists() and not path.is_dir():
        raise ConfigError("names a file, not a folder", path=path, field=option,
                          fix="give a folder (it is created when missing)")
    return path


def read_options(config: pytest.Config) -> JarvisOptions:
    """Every option checked once, at start-up: a bad value is one ConfigError naming the option and the fix."""
    pairs: dict[str, str] = {}
    for item in config.getoption("--agent-option") or []:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise _bad("--agent-option", item, "write KEY=VALUE, e.g. --agent-option planner_model=qwen3-vl-plus")
        pairs[key.strip()] = value
    datasets = config.getoption("--dataset")
    if datasets is None:
        datasets = sorted(str(p) for p in (REPO_ROOT / "tasks" / "composed").glob("*.json"))
    else:
        for d in datasets:
            if not Path(d).is_file():
                raise ConfigError("no such dataset file", path=d, field="--dataset",
                                  fix="name a JSON file written by `jarvis compose` (e.g. tasks/composed/*.json)")
    limits = LoopLimits(
        max_steps=int(_number(config, "--max-steps", int, minimum=1, fix="give a whole number of steps, 1 or more")),
        step_timeout=float(_number(config, "--step-timeout", float, minimum=0.001,
                                   fix="give a positive number of seconds, e.g. 300")),
        task_timeout=float(_number(config, "--task-timeout", float, minimum=0.001,
                                   fix="give a positive number of seconds, e.g. 3600")))
    instances = int(_number(config, "--instances", int, minimum=1, fix="give 1 or more seeded instances per template"))
    trials = int(_number(config, "--trials", int, minimum=1, fix="give 1 or more trials per task, e.g. --trials 3"))
    reproduce = _directory_option(config, "--reproduce")
    if reproduce is not None and not (reproduce / "plan.json").is_file():
        raise ConfigError("no plan.json there", path=reproduce, field="--reproduce",
                          fix="give the folder of a run that started (reports/<run id>)")
    memory = config.getoption("--device-memory")
    if memory is not None and not MEMORY.match(str(memory).strip()):
        raise _bad("--device-memory", memory, "give a size such as 4g, 1536m or 2147483648")
    reserve = float(_number(config, "--prewarm-reserve-mb", float, minimum=0,
                            fix="give the MB to keep free for running tasks, e.g. 2048 (0: no reserve)"))
    pids_limit()  # $JARVIS_DEVICE_PIDS: a bad value is one error now, not one per task
    cpus = None
    if config.getoption("--device-cpus") is not None:
        cpus = float(_number(config, "--device-cpus", float, minimum=0.01,
                             fix=f"give a positive number of CPUs, e.g. 1.5 (this machine has {os.cpu_count()})"))
    agent = config.getoption("--agent")
    if config.getoption("--qc"):
        if agent not in (None, "oracle"):
            raise ConfigError(f"--qc runs the tasks' oracle solutions, not {agent!r}", field="--agent",
                              fix=f"drop --agent {agent}")
        agent = "oracle"
    library = Path(config.getoption("--library"))
    if not library.is_dir():
        raise ConfigError("no such library folder", path=library, field="--library",
                          fix="give a folder holding <platform>/*.json templates (default tasks/)")
    results_dir = _directory_option(config, "--results-dir")
    resume = _directory_option(config, "--resume")
    if config.getoption("--resume") and resume is None:
        raise ConfigError("empty run directory", field="--resume", fix="give reports/<run id>")
    if resume is not None and not resume.is_dir():
        raise ConfigError("no such run directory", path=resume, field="--resume",
                          fix="give a folder under reports/ written by an earlier run")
    if resume is not None and results_dir is not None and resume.resolve() != results_dir.resolve():
        raise ConfigError("--resume and --results-dir name different folders", field="--results-dir",
                          fix="drop --results-dir: a resumed run writes into the run it resumes")
    backends, backend_options = _backends(config), _backend_options(config)
    check_backend_options(backends, backend_options)  # names, keys and values; whether they run here: at start
    hosts = engines.configured(config.getoption("--docker-host"), config.rootpath)
    ray = cluster_address(config.getoption("--ray"), config.rootpath)
    if ray and hosts:
        raise ConfigError("--ray and --docker-host both say where devices run", field="--docker-host",
                          fix="drop --docker-host (and [tool.jarvis] docker_hosts): with --ray each Ray node runs "
                              "devices on its own engine")
    return JarvisOptions(
        agent=agent, agent_options=pairs, limits=limits, results_dir=results_dir, resume=resume,
        device_memory=str(memory).strip() if memory is not None else None, device_cpus=cpus,
        keep_devices=config.getoption("--keep-devices"), prewarm=not config.getoption("--no-prewarm"),
        prewarm_reserve_mb=reserve,
        library=library, datasets=[Path(p) for p in datasets], instances=instances,
        transfer=config.getoption("--transfer"), qc=config.getoption("--qc"),
        endpoints={"planner": _endpoint(config, "planner"), "grounder": _endpoint(config, "grounder")},
        allow_egress=config.getoption("--allow-egress"),
        backends=backends, backend_options=backend_options,
        docker_hosts=hosts, ray=ray, trials=trials, reproduce=reproduce, allow_differences=config.getoption("--allow-differences"),
    )


def _backends(config: pytest.Config) -> dict[str, str]:
    """The backend asked for per platform (`--PLATFORM-backend`; auto is left out), as given."""
    out = {}
    for platform in BUILTIN:
        try:
            name = config.getoption(f"--{platform}-backend")
        except ValueError:
            continue
        if name not in (None, "", "auto"):
            out[platform] = name
    return out


def _backend_options(config: pytest.Config) -> dict[str, dict[str, str]]:
    """`--backend-option PLATFORM.KEY=VALUE` (and the older flags that name one) as platform → key → text: a
    malformed one, or one key given two values, is one ConfigError."""
    pairs = [(BACKEND_OPTION, item) for item in config.getoption(BACKEND_OPTION) or []]
    pairs += [(flag, f"{key}={config.getoption(flag)}") for flag, key in BACKEND_OPTION_ALIASES.items()
              if config.getoption(flag) is not None]
    return backend_option_pairs(pairs)

