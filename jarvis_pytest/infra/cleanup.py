"""Remove what a crashed or killed run left behind: containers, networks and volumes with our labels."""

from __future__ import annotations

from jarvis_pytest.infra.lifecycle import LABEL_RUN


def cleanup(run_id: str | None = None, everything: bool = False) -> dict[str, int]:
    """Remove the resources of run `run_id`, or of every run when `everything`; returns counts."""
    from jarvis_pytest.infra.engine import client

    if not run_id and not everything:
        raise ValueError("give a run id or everything=True")
    docker = client()
    label = f"{LABEL_RUN}={run_id}" if run_id else LABEL_RUN
    counts = {"containers": 0, "networks": 0, "volumes": 0}
    for c in docker.containers.list(all=True, filters={"label": label}):
        c.remove(force=True, v=True)
        counts["containers"] += 1
    for n in docker.networks.list(filters={"label": label}):
        n.remove()
        counts["networks"] += 1
    for v in docker.volumes.list(filters={"label": label}):
        v.remove(force=True)
        counts["volumes"] += 1
    return counts
