"""The task environments of one worker process: the infrastructure pool, configured from the options."""

from __future__ import annotations

from jarvis_pytest.plugin.options import JarvisOptions


def make_environments(options: JarvisOptions, *, run_id: str, worker: str):
    """A pool that boots (and pre-warms) the devices of each task; `acquire(platforms)`, `prewarm`, `close`."""
    from jarvis_pytest.infra.lifecycle import Lifecycle, Limits
    from jarvis_pytest.infra.pool import Pool

    lifecycle = Lifecycle(run_id, worker, Limits(memory=options.device_memory, cpus=options.device_cpus),
                          transfer=options.transfer, backends=options.backends, egress=options.allow_egress)
    return Pool(lifecycle, enabled=options.prewarm)
