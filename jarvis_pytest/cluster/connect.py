"""Reaching the Ray cluster of `--ray ADDRESS` from a harness process: Ray imported with our settings, the driver
connected once per process, and the cluster's jarvis nodes (those that declare device slots)."""

from __future__ import annotations

import os
import re
import socket
import threading
from dataclasses import dataclass
from typing import Any

from jarvis_pytest.cluster.facts import DEVICE_SLOTS, KVM, NAMESPACE, RAY_ENVIRONMENT, RAY_EXTRA
from jarvis_pytest.errors import ConfigError, InfrastructureError

ADDRESS = re.compile(r"^(?P<host>[A-Za-z0-9.\-]+|\[[0-9A-Fa-f:]+\]):(?P<port>\d{1,5})$")
_LOCK = threading.Lock()
_CONNECTED: str | None = None


@dataclass(frozen=True)
class Node:
    """A live node of the cluster that offers task environments."""

    node_id: str
    address: str                 # the node's IP as Ray knows it
    slots: float                 # `jarvis_device_slots` it declares
    memory_mb: float             # Ray `memory` it declares
    kvm: bool                    # it declares `kvm`
    resources: dict[str, float]  # everything it declares

    @property
    def short(self) -> str:
        return self.node_id[:12]


def check_address(address: str, field: str = "--ray") -> str:
    """The address as given when it is HOST:PORT of a Ray head's GCS; one ConfigError naming `field` otherwise."""
    text = str(address).strip()
    if not ADDRESS.match(text) or not 0 < int(text.rsplit(":", 1)[1]) < 65536:
        raise ConfigError(f"{address!r} is not the address of a Ray cluster", field=field,
                          fix="give HOST:PORT of its head, as `ray start --head --port PORT` printed it, e.g. "
                              "127.0.0.1:6379")
    return text


def configured(cli: str | None, rootdir: Any) -> str | None:
    """The cluster asked for: `--ray ADDRESS`, else `[tool.jarvis] ray` of rootdir/pyproject.toml; None: no Ray."""
    from jarvis_pytest.project_settings import tool_table

    if cli:
        return check_address(cli, "--ray")
    pyproject, table = tool_table(rootdir)
    value = table.get("ray")
    if value in (None, ""):
        return None
    if not isinstance(value, str):
        raise ConfigError(f"{value!r} is not an address", path=pyproject, field="tool.jarvis.ray",
                          fix='write ray = "HOST:PORT" (the Ray head\'s address)')
    return check_address(value, f"{pyproject}: tool.jarvis.ray")


def import_ray(field: str = "--ray") -> Any:
    """Ray, imported with the harness's settings (`facts.RAY_ENVIRONMENT`); ConfigError naming the extra if absent."""
    for key, value in RAY_ENVIRONMENT.items():
        os.environ.setdefault(key, value)
    try:
        import ray
    except ImportError:
        raise ConfigError("Ray is not installed", field=field, fix=f"{RAY_EXTRA}, or run without {field}") from None
    return ray


def connect(address: str, field: str = "--ray") -> Any:
    """This process's driver, connected to the cluster at `address` (once; the same address again is a no-op).
    An address nothing answers at is one InfrastructureError, found in seconds, not after Ray's own retries."""
    global _CONNECTED
    address = check_address(address, field)
    ray = import_ray(field)
    with _LOCK:
        if _CONNECTED == address and ray.is_initialized():
            return ray
        host, port = address.rsplit(":", 1)
        try:
            socket.create_connection((host.strip("[]"), int(port)), timeout=5).close()
        except OSError as exc:
            raise InfrastructureError(f"{field} {address}: no Ray head answers there ({exc.strerror or exc}); start "
                                      "one with `ray start --head --port PORT` (or `jarvis cluster start`)") from None
        if ray.is_initialized():
            ray.shutdown()
        try:
            ray.init(address=address, namespace=NAMESPACE, log_to_driver=False, logging_level="ERROR")
        except Exception as exc:
            raise InfrastructureError(f"{field} {address}: cannot join the Ray cluster "
                                      f"({exc.__class__.__name__}: {str(exc).splitlines()[0][:300]})") from None
        _CONNECTED = address
    return ray


def jarvis_nodes(ray: Any) -> list[Node]:
    """The cluster's live nodes that declare device slots, in a stable order."""
    out = []
    for n in ray.nodes():
        resources = {k: float(v) for k, v in (n.get("Resources") or {}).items()}
        if n.get("Alive") and resources.get(DEVICE_SLOTS, 0) > 0:
            out.append(Node(node_id=n["NodeID"], address=n.get("NodeManagerAddress", ""),
                            slots=resources[DEVICE_SLOTS], memory_mb=resources.get("memory", 0) / 2**20,
                            kvm=resources.get(KVM, 0) > 0, resources=resources))
    return sorted(out, key=lambda node: node.node_id)


def require_nodes(ray: Any, address: str, field: str = "--ray") -> list[Node]:
    """The jarvis nodes; an InfrastructureError saying how a node joins when there is none."""
    nodes = jarvis_nodes(ray)
    if not nodes:
        raise InfrastructureError(
            f"{field} {address}: no node of the cluster offers devices: start one with `ray start --address "
            f"{address} --resources '{{\"{DEVICE_SLOTS}\": 4}}'` on a machine with a Docker engine and the images "
            "(see the README, \"Many machines: Ray\")")
    return nodes


def lost_node(ray: Any, exc: BaseException) -> bool:
    """Whether `exc` says the node (or the agent's process on it) is gone: an actor, object, worker or node lost
    to Ray, not an error of the work it carried (that comes back as a value: `node.outcome`)."""
    errors = ray.exceptions
    return isinstance(exc, (errors.RayActorError, errors.ObjectLostError, errors.NodeDiedError,
                            errors.WorkerCrashedError, errors.RaySystemError, errors.LocalRayletDiedError))
