"""The task environments of one worker process: the infrastructure pool, configured from the run's settings and
backends (resolved once, `devices.backend.resolve_backends`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from jarvis_pytest.devices.backend import Backends


def make_environments(backends: "Backends", *, run_id: str, worker: str, keep_devices: bool = False,
                      device_memory: str | None = None, device_cpus: float | None = None,
                      transfer: str | None = None, egress: bool = False, docker_hosts: tuple[str, ...] = (),
                      prewarm: bool = True, prewarm_reserve_mb: float | None = None):
    """A pool that boots (and pre-warms) the devices of each task; `acquire(platforms)`, `prewarm`, `close`."""
    from jarvis_pytest.infra.containers import keep_devices as keep
    from jarvis_pytest.infra.engines import for_worker
    from jarvis_pytest.environments.lifecycle import Lifecycle, Limits
    from jarvis_pytest.infra.networks import KEEP_PER_WORKER
    from jarvis_pytest.environments.pool import PREWARM_RESERVE_MB, Pool

    keep(keep_devices)
    lifecycle = Lifecycle(run_id, worker, Limits(memory=device_memory, cpus=device_cpus), transfer=transfer,
                          backends=backends, egress=egress, docker_host=for_worker(docker_hosts, worker),
                          keep_networks=KEEP_PER_WORKER)
    reserve = PREWARM_RESERVE_MB if prewarm_reserve_mb is None else prewarm_reserve_mb
    return Pool(lifecycle, enabled=prewarm, reserve_mb=reserve)
