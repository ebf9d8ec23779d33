"""What a Ray node of a jarvis run is, in one place: the resources it declares, how the harness names its actors,
and the settings every Ray process of ours starts with.

A node offers task environments when it declares `jarvis_device_slots` (how many devices it runs at once) with
`ray start --resources '{"jarvis_device_slots": 8}'`, adds `"kvm": 1` where it runs KVM guests (a Windows VM, the
Android emulator), and sets the Ray `memory` it may give (`ray start --memory`, default: what the machine has).
Its Docker engine is the one `ray start` was started with: `$DOCKER_HOST`, else the local socket.
"""

from __future__ import annotations

DEVICE_SLOTS = "jarvis_device_slots"   # custom resource: devices a node runs at once
KVM = "kvm"                            # custom resource: the node runs KVM guests
NAMESPACE = "jarvis"                   # Ray namespace of the harness's actors
RAY_EXTRA = "pip install 'jarvis-pytest[ray]'"  # how a user gets Ray

# Set for the harness's own Ray processes (drivers) and for `ray start` by `cluster/local.py`: no usage report
# leaves the machine, and Ray's output stays out of pytest's.
RAY_ENVIRONMENT = {"RAY_USAGE_STATS_ENABLED": "0", "RAY_DISABLE_IMPORT_WARNING": "1"}

PLACEMENT_TIMEOUT = 1800.0  # seconds a task waits for a node with room for its devices (the cluster is busy)
ACTOR_READY_TIMEOUT = 120.0  # seconds a node's agent may take to start (a Python process importing the harness)
IMAGE_CHUNK = 16 * 2**20     # bytes of `docker save` output sent to a node per call when it lacks an image
IMAGE_CHUNKS_IN_FLIGHT = 3   # calls sent ahead of the node's `docker load`


def agent_name(run_id: str, worker: str, node_id: str) -> str:
    """The name of the actor that holds one pytest worker's environments on one node."""
    return f"jarvis-{run_id}-{worker}-{node_id[:16]}"
