"""The task environments of one worker process: the infrastructure pool, configured from the options and the
run's backends (resolved once, `devices.backend.resolve_backends`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from jarvis_pytest.plugin.options import JarvisOptions

if TYPE_CHECKING:
    from jarvis_pytest.devices.backend import Backends


def make_environments(options: JarvisOptions, backends: "Backends", *, run_id: str, worker: str):
    """A pool that boots (and pre-warms) the devices of each task; `acquire(platforms)`, `prewarm`, `close`."""
    from jarvis_pytest.infra.engines import for_worker
    from jarvis_pytest.infra.lifecycle import Lifecycle, Limits
    from jarvis_pytest.infra.networks import KEEP_PER_WORKER
    from jarvis_pytest.infra.pool import Pool

    from jarvis_pytest.infra.containers import keep_devices

    keep_devices(options.keep_devices)
    lifecycle = Lifecycle(run_id, worker, Limits(memory=options.device_memory, cpus=options.device_cpus),
                          transfer=options.transfer, backends=backends, egress=options.allow_egress,
                          docker_host=for_worker(options.docker_hosts, worker), keep_networks=KEEP_PER_WORKER)
    return Pool(lifecycle, enabled=options.prewarm, reserve_mb=options.prewarm_reserve_mb)
