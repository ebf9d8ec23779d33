"""Remove what crashed or killed runs left behind: containers, networks and volumes with our labels.

Four selections: one run (`run_id`, whether its processes live or not), every run (`everything`), the devices
runs kept with `--keep-devices` once those runs ended (`kept`), or — the default of `jarvis cleanup` and of every
run's start-up — orphans only: resources of a dead run. A resource is an orphan when it was made on this host
(label `org.jarvis.host`), the process that made it (`org.jarvis.pid`: the xdist worker, or the run's only
process) is gone, its run (`org.jarvis.run`) is not live (no process holds its lock: `results/run_lock.py`; an
xdist run is live while its controller is, whichever worker made the resource) and that run did not keep its
devices. Resources without an owner label, or owned by another host, are never orphans (they may belong to a
live run); remove them with `--run` or `--all`.
"""

from __future__ import annotations

import hashlib
import socket
import tempfile
import time
from contextlib import contextmanager, nullcontext
from pathlib import Path
from typing import Any, Iterator

from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.infra.containers import LABEL_HOST, LABEL_KEEP, LABEL_PID, LABEL_RUN
from jarvis_pytest.infra.egress import close_within
from jarvis_pytest.results import run_lock
from jarvis_pytest.results.run_state import process_alive


def is_orphan(labels: dict[str, str]) -> bool:
    """Whether a resource with these labels belongs to a dead run of this host that did not keep its devices:
    the process that created it is provably gone, and so is its run's controller."""
    pid = labels.get(LABEL_PID, "")
    if labels.get(LABEL_HOST) != socket.gethostname() or not pid.isdigit() or process_alive(int(pid)):
        return False
    if labels.get(LABEL_KEEP) == "1":  # kept with --keep-devices: only `jarvis cleanup --kept` (or --run) removes it
        return False
    run = labels.get(LABEL_RUN, "")
    return not run_lock.is_live(run) and not run_lock.is_kept(run)


def is_kept(labels: dict[str, str]) -> bool:
    """Whether a resource with these labels was kept by an ended run of this host started with --keep-devices
    (its label says so, or its run's lock record; the process that made it is gone and its run holds no lock)."""
    if labels.get(LABEL_HOST) != socket.gethostname():
        return False
    run, pid = labels.get(LABEL_RUN, ""), labels.get(LABEL_PID, "")
    if labels.get(LABEL_KEEP) == "1":
        return pid.isdigit() and not process_alive(int(pid)) and not run_lock.is_live(run)
    return run_lock.is_kept(run)


_SWEEP_LOCKS: dict[str, Any] = {}


@contextmanager
def orphan_sweep(host: str | None = None, timeout: float = 300) -> Iterator[None]:
    """Held by one orphan sweep of engine `host` on this machine at a time (reentrant in a thread): runs that
    start together count each leftover once, and a caller holding it keeps other sweeps off what it checks."""
    from filelock import FileLock, Timeout

    key = hashlib.sha256(str(host).encode()).hexdigest()[:12]
    lock = _SWEEP_LOCKS.setdefault(key, FileLock(str(Path(tempfile.gettempdir()) / f"jarvis-orphans-{key}.lock")))
    try:
        lock.acquire(timeout=timeout)
    except Timeout:
        raise InfrastructureError(f"another orphan sweep of this engine held its lock ({lock.lock_file}) for "
                                  f"{timeout:.0f} s; is a `jarvis cleanup` hanging?") from None
    try:
        yield
    finally:
        lock.release()


def _remove(resource: Any, kind: str, problems: list[str]) -> bool:
    import docker.errors

    if kind == "networks":
        close_within(resource.name)  # the rule before its bridge, as a run removes its own network
    for attempt in range(5):
        try:
            if kind == "containers":
                resource.remove(force=True, v=True)
            elif kind == "volumes":
                resource.remove(force=True)
            else:
                resource.remove()
            return True
        except docker.errors.NotFound:
            return False
        except docker.errors.APIError as exc:
            if attempt == 4:
                problems.append(f"{kind[:-1]} {resource.name}: {exc.explanation or exc}")
            time.sleep(0.3)  # a removal in progress elsewhere, or a network whose containers are still going
    return False


def cleanup(run_id: str | None = None, everything: bool = False, orphans_only: bool | None = None,
            host: str | None = None, kept: bool = False) -> dict[str, int]:
    """Remove the resources of run `run_id`, of every run (`everything`), those ended runs kept with
    --keep-devices (`kept`), or (none of these) the orphans of every run, on the engine at `host` (default: the
    local one; every engine of a run: `engines.cleanup_everywhere`).

    `orphans_only=True` narrows a selection to orphans. Returns counts per kind; raises InfrastructureError
    naming what could not be removed. The caller forgets the kept runs it removed everywhere
    (`run_lock.forget`).
    """
    from jarvis_pytest.infra.engine import client

    if orphans_only is None:
        orphans_only = not run_id and not everything and not kept
    docker = client(host=host)
    label = f"{LABEL_RUN}={run_id}" if run_id else LABEL_RUN
    counts = {"containers": 0, "networks": 0, "volumes": 0}
    problems: list[str] = []
    # listings through the low-level API: one request each, no per-item inspection that a removal racing ours
    # (another run ending) would turn into an error
    api = docker.api
    listings = {
        "containers": lambda: [(docker.containers.prepare_model(c), c.get("Labels")) for c in
                               api.containers(all=True, filters={"label": label})],
        "networks": lambda: [(docker.networks.prepare_model(n), n.get("Labels")) for n in
                             api.networks(filters={"label": label})],
        "volumes": lambda: [(docker.volumes.prepare_model(v), v.get("Labels")) for v in
                            (api.volumes(filters={"label": label}) or {}).get("Volumes") or []],
    }
    with orphan_sweep(host) if orphans_only else nullcontext():
        for kind, listing in listings.items():  # containers first: a network in use cannot go
            for resource, labels in listing():
                if orphans_only and not is_orphan(labels or {}):
                    continue
                if kept and not is_kept(labels or {}):
                    continue
                if _remove(resource, kind, problems):
                    counts[kind] += 1
    if problems:
        raise InfrastructureError("could not remove " + "; ".join(problems) + " (is another run still using them? "
                                  "`docker ps -a --filter label=org.jarvis.run` shows what is left)")
    return counts


def kept_devices(host: str | None = None) -> dict[str, dict[str, Any]]:
    """The ended runs of this host that kept their devices (--keep-devices) and what of them the engine at `host`
    still has: run id → {"run_dir", "ended", "containers": [names], "networks": [names]}. A run is found by its
    lock record or by the keep label of its resources (a run that used another run-lock folder)."""
    from jarvis_pytest.infra.engine import client

    runs = dict(run_lock.kept_runs())
    api = client(host=host).api
    here = f"{LABEL_HOST}={socket.gethostname()}"
    for c in api.containers(all=True, filters={"label": [f"{LABEL_KEEP}=1", here]}):
        if is_kept(c.get("Labels") or {}):
            runs.setdefault((c.get("Labels") or {}).get(LABEL_RUN, ""), {})
    found: dict[str, dict[str, Any]] = {}
    for run, record in runs.items():
        label = {"label": [f"{LABEL_RUN}={run}", here]}
        containers = sorted(n.lstrip("/") for c in api.containers(all=True, filters=label) for n in c["Names"][:1])
        networks = sorted(n["Name"] for n in api.networks(filters=label))
        found[run] = {"run_dir": record.get("run_dir", ""), "ended": record.get("ended", ""),
                      "containers": containers, "networks": networks}
    return found
