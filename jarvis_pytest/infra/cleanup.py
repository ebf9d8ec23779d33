"""Remove what crashed or killed runs left behind: containers, networks and volumes with our labels.

Three selections: one run (`run_id`, whether its processes live or not), every run (`everything`), or — the
default of `jarvis cleanup` — orphans only: resources whose owning process (labels `org.jarvis.host` and
`org.jarvis.pid`) is gone from this host. Resources without an owner label, or owned by another host, are never
orphans (they may belong to a live run); remove them with `--run` or `--all`.
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
from jarvis_pytest.infra.containers import LABEL_HOST, LABEL_PID, LABEL_RUN
from jarvis_pytest.infra.egress import close_within
from jarvis_pytest.results.run_state import process_alive


def is_orphan(labels: dict[str, str]) -> bool:
    """Whether the process that created a resource with these labels is provably gone."""
    pid = labels.get(LABEL_PID, "")
    if labels.get(LABEL_HOST) != socket.gethostname() or not pid.isdigit():
        return False
    return not process_alive(int(pid))


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
            host: str | None = None) -> dict[str, int]:
    """Remove the resources of run `run_id`, of every run (`everything`), or (neither) the orphans of every run,
    on the engine at `host` (default: the local one; every engine of a run: `engines.cleanup_everywhere`).

    `orphans_only=True` narrows a selection to orphans. Returns counts per kind; raises InfrastructureError
    naming what could not be removed.
    """
    from jarvis_pytest.infra.engine import client

    if orphans_only is None:
        orphans_only = not run_id and not everything
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
                if _remove(resource, kind, problems):
                    counts[kind] += 1
    if problems:
        raise InfrastructureError("could not remove " + "; ".join(problems) + " (is another run still using them? "
                                  "`docker ps -a --filter label=org.jarvis.run` shows what is left)")
    return counts
