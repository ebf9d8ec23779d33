"""The run card: every condition a run's results depend on, in one block of run.json (`"card"`), written when the
run starts and completed as its results come in. `jarvis reproduce` starts a run under the same conditions and
`jarvis diff` compares two cards (`report/reproduce.py`).

The card (format 1)::

    harness     version, commit, dirty (uncommitted changes or untracked files in the checkout; `dirty_digest`
                hashes them), python, packages (pytest, pytest-xdist, docker, pydantic, httpx, pillow)
    agent       the agent's whole configuration as it records it: name, models and endpoints (never keys),
                sampling parameters, seed mode, prompt and parser versions (hashes), what a screenshot is when it
                reaches the model (`model_input`)
    limits      max_steps, step_timeout, task_timeout (seconds)
    trials      K of --trials; workers: xdist workers (0: none); instances: seeded instances per template
    tasks       library (path), templates_digest (`Library.digest`), datasets [{path, sha256, seed, command,
                library_digest}], planned (how many task trials) and plan_digest (a hash of every planned key and
                its task's definition)
    devices     per platform: backend (label), stand_in, image (reference), image_ids (seen), os (what the devices
                said they are: Debian and XFCE, Wine and the Windows it reports, Android's build fingerprint),
                provenance (a VM's golden and snapshot), hostname, timezone, locale; `transfer`: the drive's
                flavour and image
    environment egress, device_memory, device_cpus, backend options as given, docker_hosts
    selection   argv (the command line, secrets hidden, without --results-dir, --resume, --reproduce,
                --allow-differences), invocation (the folder it ran in, relative to the checkout), keyword (-k),
                markers (-m)
    reproduces  with --reproduce only: the run reproduced (`run`, `folder`) and the `differences` allowed
    machine     cpus, memory_gb, system, kernel: what the run ran on (shown by `jarvis diff`, never a reason for
                `jarvis reproduce` to refuse)

Conditions are every key but `machine.*`, `selection.*` and `reproduces.*` (what was selected is pinned by
`tasks.plan_digest`).
"""

from __future__ import annotations

import hashlib
import json
import os
import platform as _platform
import subprocess
import sys
from pathlib import Path
from typing import Any, Iterable, Mapping

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.paths import REPO_ROOT
from jarvis_pytest.results.run_state import read_run_meta

CARD_FORMAT = 1
PACKAGES = ("pytest", "pytest-xdist", "docker", "pydantic", "httpx", "pillow")
INFORMATIONAL = ("machine.", "selection.", "format", "reproduces")  # shown by `jarvis diff`, never a reason to refuse
PAPER_MAX_STEPS = 50
DEFAULT_TIMEOUTS = {"step_timeout": 300.0, "task_timeout": 3600.0}
DROPPED_OPTIONS = ("--results-dir", "--resume", "--reproduce")  # where results go and what is reproduced: a new
DROPPED_FLAGS = ("--allow-differences",)                          # run chooses these for itself


def _git(*args: str) -> subprocess.CompletedProcess | None:
    try:
        return subprocess.run(["git", "-C", str(REPO_ROOT), *args], capture_output=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        return None


def harness() -> dict[str, Any]:
    """The harness that runs: its version, its git commit and whether the checkout differs from it, Python and the
    packages a result depends on."""
    from importlib import metadata

    from jarvis_pytest import __version__

    packages = {}
    for name in PACKAGES:
        try:
            packages[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            packages[name] = None
    out: dict[str, Any] = {"version": __version__, "commit": None, "dirty": None, "dirty_digest": None,
                           "python": _platform.python_version(), "packages": packages}
    head = _git("rev-parse", "HEAD")
    if head is None or head.returncode != 0:
        return out  # not a git checkout (an installed package): the version is all there is
    out["commit"] = head.stdout.decode().strip()
    status = _git("status", "--porcelain", "--untracked-files=all")
    changes = status.stdout.decode() if status is not None and status.returncode == 0 else ""
    out["dirty"] = bool(changes.strip())
    if out["dirty"]:
        digest = hashlib.sha256()
        diff = _git("diff", "HEAD", "--binary")
        digest.update(diff.stdout if diff is not None else b"")
        for line in sorted(changes.splitlines()):
            if line.startswith("??"):
                path = REPO_ROOT / line[3:].strip().strip('"')
                digest.update(line.encode() + b"\0" + (path.read_bytes() if path.is_file() else b""))
        out["dirty_digest"] = digest.hexdigest()[:16]
    return out


def machine() -> dict[str, Any]:
    """What the run ran on (informational)."""
    memory = None
    try:
        memory = round(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30, 1)
    except (ValueError, OSError, AttributeError):
        pass
    return {"cpus": os.cpu_count(), "memory_gb": memory, "system": _platform.system(), "kernel": _platform.release()}


def file_sha256(path: Path) -> str | None:
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError:
        return None


def relative(path: Path | str) -> str:
    """`path` relative to the checkout where it is inside it (the same on any machine), else as given."""
    resolved = Path(path).resolve()
    try:
        return str(resolved.relative_to(REPO_ROOT))
    except ValueError:
        return str(path)


def dataset_record(path: Path) -> dict[str, Any]:
    """A dataset file's identity: its path, SHA-256 and how it was composed (seed, command, library digest)."""
    meta: dict[str, Any] = {}
    try:
        meta = json.loads(Path(path).read_text(encoding="utf-8")).get("meta") or {}
    except (OSError, ValueError, AttributeError):
        pass
    return {"path": relative(path), "sha256": file_sha256(path), "seed": meta.get("seed"),
            "command": meta.get("command"), "library_digest": meta.get("library_digest")}


def replay_argv(argv: list[str]) -> list[str]:
    """The command line without the options that say where results go (`DROPPED_OPTIONS`), which a new run
    chooses for itself."""
    out: list[str] = []
    skip = False
    for arg in argv:
        if skip:
            skip = False
            continue
        name = arg.partition("=")[0]
        if name in DROPPED_FLAGS:
            continue
        if name in DROPPED_OPTIONS:
            skip = "=" not in arg
            continue
        out.append(arg)
    return out


def plan_digest(keys: Iterable[str], digests: Mapping[str, str]) -> str:
    """A hash of the planned task trials (`plan.json` keys) and the definitions of their tasks."""
    from jarvis_pytest.results.model import TRIAL_MARK

    blob = json.dumps(sorted((k, digests.get(k.split(TRIAL_MARK)[0], "")) for k in keys))
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def build(*, agent: dict[str, Any], limits: Any, trials: int, workers: int, instances: int, library: Path,
          templates_digest: str, datasets: list[Path], devices: dict[str, dict[str, Any]],
          transfer: dict[str, Any], environment: dict[str, Any], argv: list[str], keyword: str,
          markers: str) -> dict[str, Any]:
    """The card of a run about to start (see the module docstring); the plan and what the devices are follow."""
    return {
        "format": CARD_FORMAT,
        "harness": harness(),
        "agent": agent,
        "limits": {"max_steps": limits.max_steps, "step_timeout": limits.step_timeout,
                   "task_timeout": limits.task_timeout},
        "trials": trials, "workers": workers, "instances": instances,
        "tasks": {"library": relative(library), "templates_digest": templates_digest,
                  "datasets": [dataset_record(d) for d in datasets], "planned": 0, "plan_digest": None},
        "devices": {**devices, "transfer": transfer},
        "environment": environment,
        "selection": {"argv": replay_argv(argv), "invocation": relative(Path.cwd()), "keyword": keyword,
                      "markers": markers},
        "machine": machine(),
    }


def with_results(card: dict[str, Any], results: Iterable[Any]) -> dict[str, Any]:
    """`card` with what its devices turned out to be, from the results (`TaskResult`): per platform the image ids,
    the systems the devices said they are and their provenance."""
    card = json.loads(json.dumps(card))
    devices = card.setdefault("devices", {})
    seen: dict[str, dict[str, set[str]]] = {}
    provenance: dict[str, list[Any]] = {}
    for r in results:
        for p, image in r.image_ids.items():
            seen.setdefault(p, {"image_ids": set(), "os": set()})["image_ids"].add(image)
        for p, system in r.device_os.items():
            seen.setdefault(p, {"image_ids": set(), "os": set()})["os"].add(system)
        for p, prov in r.device_provenance.items():
            if prov not in provenance.setdefault(p, []):
                provenance[p].append(prov)
    for p, found in seen.items():
        entry = devices.setdefault(p, {})
        entry["image_ids"] = sorted(set(entry.get("image_ids") or []) | found["image_ids"])
        entry["os"] = sorted(set(entry.get("os") or []) | found["os"])
        if provenance.get(p):
            entry["provenance"] = provenance[p]
    return card


# -- reading cards -------------------------------------------------------------------------------------------------
def read_card(run_dir: Path, field: str | None = None) -> tuple[dict[str, Any], dict[str, Any]]:
    """(run.json, its card) of `run_dir`; a ConfigError naming the file (and the option `field` that named the
    run) when there is none."""
    meta, bad = read_run_meta(run_dir)
    if bad or meta is None:
        raise ConfigError(f"run.json {bad or 'is missing'}", path=Path(run_dir) / "run.json", field=field,
                          fix="give the folder of a run (reports/<run id>)")
    card = meta.get("card")
    if not isinstance(card, dict):
        raise ConfigError("run.json has no run card: the run was made before run cards were written",
                          path=Path(run_dir) / "run.json", field=field,
                          fix="run its command (run.json's sessions[].argv) again")
    return meta, card


def flatten(data: Any, prefix: str = "") -> dict[str, str]:
    """Dotted key → the value's JSON text, for every leaf of `data` (a list is one leaf)."""
    if isinstance(data, dict) and data:
        out: dict[str, str] = {}
        for key in sorted(data):
            out.update(flatten(data[key], f"{prefix}{key}."))
        return out
    return {prefix.rstrip("."): json.dumps(data, sort_keys=True, ensure_ascii=False)}


def informational(key: str) -> bool:
    return key.startswith(INFORMATIONAL)


def differences(a: dict[str, Any], b: dict[str, Any]) -> list[tuple[str, str | None, str | None]]:
    """(key, value in a, value in b) of every leaf that differs; None where a card lacks the key."""
    fa, fb = flatten(a), flatten(b)
    return [(k, fa.get(k), fb.get(k)) for k in sorted(set(fa) | set(fb)) if fa.get(k) != fb.get(k)]


def _agent_params(agent: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in agent.items() if k.endswith("_params") and isinstance(v, dict)}


def _sizes(info: Any) -> list[tuple[str, list, list]]:
    """(platform, screen size, size sent) from an agent's `model_input` entry."""
    if not isinstance(info, dict) or not isinstance(info.get("sent"), dict):
        return []
    screen = info.get("screen") or {}
    return [(p, screen.get(p) or sent, sent) for p, sent in sorted(info["sent"].items())]


def _downscaled(info: Any) -> list[str]:
    return [f"{p} {s[0]}x{s[1]} sent as {t[0]}x{t[1]}" for p, s, t in _sizes(info) if t[0] * t[1] < s[0] * s[1]]


def _input_text(info: Any) -> str:
    sizes = _sizes(info)
    if not sizes:
        return str(info)
    same = all(s == t for _, s, t in sizes)
    return f"{info.get('encoding', '?')}, " + ("each device's full screen" if same else "; ".join(
        f"{p} {s[0]}x{s[1]} sent as {t[0]}x{t[1]}" for p, s, t in sizes))


def settings_lines(card: dict[str, Any]) -> list[str]:
    """The settings that change scores, one line each, for the start of a run."""
    agent = card.get("agent") or {}
    limits = card.get("limits") or {}
    lines = [f"agent {agent.get('name')}"
             + "".join(f"; {role} {cfg.get('model')} at {cfg.get('base_url')}" for role, cfg in agent.items()
                       if isinstance(cfg, dict) and cfg.get("model")),
             f"step limit {limits.get('max_steps')}, step timeout {limits.get('step_timeout'):g} s, task timeout "
             f"{limits.get('task_timeout'):g} s; trials {card.get('trials')}; instances {card.get('instances')}"]
    for name, params in _agent_params(agent).items():
        lines.append(f"{name.replace('_params', '')} sampling: "
                     + ", ".join(f"{k}={v}" for k, v in sorted(params.items()) if not isinstance(v, (dict, list)))
                     + f"; seed {agent.get('seed', 'none')}")
    for role, info in (agent.get("model_input") or {}).items():
        lines.append(f"{role} screenshots: {_input_text(info)}")
    devices = card.get("devices") or {}
    lines.append("devices: " + "; ".join(
        (f"{d['backend']}" + (" (a stand-in)" if d.get("stand_in") else "")) if d.get("backend")
        else f"{p}: none here" for p, d in sorted(devices.items()) if p != "transfer"))
    h = card.get("harness") or {}
    lines.append(f"harness {h.get('version')} at {str(h.get('commit'))[:12]}" + (" with uncommitted changes"
                                                                                 if h.get("dirty") else ""))
    return lines


def unusual(card: dict[str, Any]) -> list[str]:
    """Warnings about settings that make a score hard to compare with the paper's or with another run's."""
    out = []
    limits = card.get("limits") or {}
    agent = card.get("agent") or {}
    if (limits.get("max_steps") or PAPER_MAX_STEPS) < PAPER_MAX_STEPS:
        out.append(f"the step limit {limits['max_steps']} is under the paper's {PAPER_MAX_STEPS}: tasks that need "
                   "more steps fail")
    for key, default in DEFAULT_TIMEOUTS.items():
        if (limits.get(key) or default) < default:
            out.append(f"{key.replace('_', ' ')} {limits[key]:g} s is under the default {default:g} s")
    for role, info in (agent.get("model_input") or {}).items():
        smaller = _downscaled(info)
        if smaller:
            out.append(f"the {role}'s screenshots are downscaled before the model sees them ({', '.join(smaller)})")
    sampled = [n for n, p in _agent_params(agent).items() if (p.get("temperature") or 0) > 0]
    if sampled and (card.get("trials") or 1) == 1:
        out.append(f"{', '.join(s.replace('_params', '') for s in sampled)} samples at temperature > 0 with one "
                   "trial per task: the score varies from run to run; give --trials 3 or more")
    if agent.get("seed") == "none":
        out.append("no seed is sent to the models: sampling is not repeatable even where the server would be")
    if (card.get("environment") or {}).get("egress"):
        out.append("devices may reach the network (--allow-egress): tasks may depend on the outside world")
    stand_ins = [p for p, d in (card.get("devices") or {}).items() if isinstance(d, dict) and d.get("stand_in")]
    if stand_ins:
        out.append(f"stand-in devices for {', '.join(sorted(stand_ins))}: their results are not the real "
                   "platform's")
    if (card.get("harness") or {}).get("dirty"):
        out.append("the harness has uncommitted changes: its commit alone does not reproduce this run")
    return out


# Known only once devices ran (compared by `jarvis diff` afterwards), or pinned otherwise (the plan: by the tasks'
# definitions and the templates' and datasets' digests); images are compared by `_image_differences`.
AFTER_THE_RUN = ("os", "provenance", "image_ids", "image_id")


def _comparable(key: str) -> bool:
    parts = key.split(".")
    if informational(key) or key in ("tasks.planned", "tasks.plan_digest"):
        return False
    return not (parts[0] == "devices" and len(parts) >= 3 and parts[2] in AFTER_THE_RUN)


def _image_differences(expected: dict[str, Any], here: dict[str, Any]) -> list[str]:
    out = []
    for platform, want in sorted((expected.get("devices") or {}).items()):
        used = sorted(set(want.get("image_ids") or []) | ({want["image_id"]} if want.get("image_id") else set()))
        if not used:
            continue
        got = (here.get("devices") or {}).get(platform) or {}
        have = got.get("image_id") or next(iter(got.get("image_ids") or []), None)
        name = want.get("image") or platform
        if have is None:
            out.append(f"devices.{platform}: the image {name} is not on this machine (the run used "
                       f"{', '.join(i[:19] for i in used)}): load that image (docker save/load) or allow the difference")
        elif have not in used:
            out.append(f"devices.{platform}: the image {name} here is {have[:19]}, the run used "
                       f"{', '.join(i[:19] for i in used)}")
    return out


def reproduction_differences(expected: dict[str, Any], here: dict[str, Any]) -> list[str]:
    """Each condition of the card `expected` (a finished run's) that the card `here` (a run about to start) does
    not meet, in words: `key: the run had A, here B`."""
    out = [f"{key}: the run had {a if a is not None else '(nothing)'}, here {b if b is not None else '(nothing)'}"
           for key, a, b in differences(expected, here) if _comparable(key)]
    return out + _image_differences(expected, here)
