"""The task environments of one worker process: the infrastructure pool, configured from the options."""

from __future__ import annotations

from jarvis_pytest.plugin.options import JarvisOptions


def configure_backends(options: JarvisOptions) -> None:
    """Hand backend settings from the options to the backends of this process."""
    if options.android_serial or options.android_image:
        from jarvis_pytest.devices.android.backend import configure

        configure(serial=options.android_serial, image=options.android_image)


def make_environments(options: JarvisOptions, *, run_id: str, worker: str):
    """A pool that boots (and pre-warms) the devices of each task; `acquire(platforms)`, `prewarm`, `close`."""
    from jarvis_pytest.infra.engines import for_worker
    from jarvis_pytest.infra.lifecycle import Lifecycle, Limits
    from jarvis_pytest.infra.networks import KEEP_PER_WORKER
    from jarvis_pytest.infra.pool import Pool

    from jarvis_pytest.infra.containers import keep_devices

    configure_backends(options)
    keep_devices(options.keep_devices)
    lifecycle = Lifecycle(run_id, worker, Limits(memory=options.device_memory, cpus=options.device_cpus),
                          transfer=options.transfer, backends=options.backends, egress=options.allow_egress,
                          docker_host=for_worker(options.docker_hosts, worker), keep_networks=KEEP_PER_WORKER)
    return Pool(lifecycle, enabled=options.prewarm, reserve_mb=options.prewarm_reserve_mb)
