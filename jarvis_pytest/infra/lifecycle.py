"""Containers and networks of one task: a fresh device per platform and a transfer drive on a private network.

Everything created carries the labels `org.jarvis.run`, `org.jarvis.worker`, `org.jarvis.role` and
`org.jarvis.platform`, so `jarvis cleanup` can find what a crashed run left. Ports are published on 127.0.0.1
only; devices reach the drive as `http://transfer:5244` on the task's network.
"""

from __future__ import annotations

import itertools
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

from jarvis_pytest.devices.backend import (TRANSFER_ALIAS, TRANSFER_PASSWORD, TRANSFER_PORT, TRANSFER_USER,
                                           backend_for)
from jarvis_pytest.devices.base import Device
from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.infra.images import image_tag
from jarvis_pytest.infra.transfer import TRANSFER_CLIENTS

LABEL_RUN, LABEL_WORKER, LABEL_ROLE, LABEL_PLATFORM = ("org.jarvis.run", "org.jarvis.worker", "org.jarvis.role",
                                                       "org.jarvis.platform")
TRANSFER_IMAGE = "transfer"
TRANSFER_READY_TIMEOUT = 60.0  # the drive's own allowance; `Limits.ready_timeout` is the devices'


@dataclass(frozen=True)
class Limits:
    """Resources of each device container."""

    memory: str | None = "4g"
    cpus: float | None = None
    ready_timeout: float = 60.0  # seconds for a device to become ready


@dataclass
class TaskEnvironment:
    """The booted devices of one task, its transfer drive and what is needed to remove them."""

    devices: dict[str, Device]
    transfer: Any
    image_ids: dict[str, str]
    network: Any
    containers: dict[str, Any]
    urls: dict[str, str] = field(default_factory=dict)
    _closed: bool = False

    def describe(self) -> str:
        lines = [f"network {self.network.name}"]
        for role, c in sorted(self.containers.items()):
            lines.append(f"  {role}: {self.urls.get(role, '')}  (docker exec -it {c.name} bash)")
        lines.append(f"  remove with: docker rm -f {' '.join(c.name for c in self.containers.values())} "
                     f"&& docker network rm {self.network.name}")
        return "\n".join(lines)

    def close(self) -> None:
        """Remove the containers and the network (idempotent)."""
        if self._closed:
            return
        self._closed = True
        for dev in list(self.devices.values()) + [self.transfer]:
            getattr(dev, "close", lambda: None)()
        remove_all(list(self.containers.values()), self.network)


def remove_all(containers: list[Any], network: Any) -> None:
    for c in containers:
        try:
            c.remove(force=True, v=True)
        except Exception:
            pass
    if network is not None:
        try:
            network.remove()
        except Exception:
            pass


def _host_port(container: Any, port: int) -> int:
    container.reload()
    bindings = container.attrs["NetworkSettings"]["Ports"].get(f"{port}/tcp") or []
    for b in bindings:
        if b.get("HostIp") == "127.0.0.1":
            return int(b["HostPort"])
    raise InfrastructureError(f"container {container.name} has no port {port} published on 127.0.0.1")


def _logs(container: Any, lines: int = 40) -> str:
    try:
        return container.logs(tail=lines).decode("utf-8", "replace")
    except Exception as exc:
        return f"(no logs: {exc})"


class Lifecycle:
    """Creates task environments for one run and worker."""

    def __init__(self, run_id: str, worker: str = "main", limits: Limits | None = None, transfer_flavour: str = "copyparty"):
        from jarvis_pytest.infra.engine import client

        self.docker = client()
        self.run_id, self.worker = run_id, worker
        self.limits = limits or Limits()
        self.transfer_flavour = transfer_flavour
        self._counter = itertools.count()
        self._lock = threading.Lock()

    def labels(self, role: str, platform: str = "") -> dict[str, str]:
        return {LABEL_RUN: self.run_id, LABEL_WORKER: self.worker, LABEL_ROLE: role, LABEL_PLATFORM: platform}

    def _name(self) -> str:
        with self._lock:
            n = next(self._counter)
        return f"jarvis-{self.run_id}-{self.worker}-{n}"

    def _run(self, image: str, name: str, network: Any, role: str, platform: str, port: int,
             extra: dict[str, Any], aliases: list[str] | None = None) -> Any:
        kwargs: dict[str, Any] = dict(
            detach=True, name=name, labels=self.labels(role, platform), network=network.name,
            ports={f"{port}/tcp": ("127.0.0.1", None)},
        )
        if role == "device":
            if self.limits.memory:
                kwargs["mem_limit"] = self.limits.memory
            if self.limits.cpus:
                kwargs["nano_cpus"] = int(self.limits.cpus * 1e9)
        kwargs.update(extra)
        try:
            container = self.docker.containers.create(image_tag(image), **kwargs)
        except Exception as exc:
            raise InfrastructureError(f"cannot create the {platform or role} container from {image_tag(image)}: "
                                      f"{exc} (build it with `jarvis images build`)") from exc
        if aliases:
            network.disconnect(container)
            network.connect(container, aliases=aliases)
        container.start()
        return container

    def boot(self, platforms: tuple[str, ...]) -> TaskEnvironment:
        """A network with a transfer drive and one fresh, ready device per platform (booted in parallel)."""
        base = self._name()
        network = self.docker.networks.create(base, driver="bridge", labels=self.labels("network"))
        containers: dict[str, Any] = {}
        try:
            backends = {p: backend_for(p) for p in platforms}
            containers["transfer"] = self._run(TRANSFER_IMAGE, f"{base}-transfer", network, "transfer", "",
                                               TRANSFER_PORT, {}, aliases=[TRANSFER_ALIAS])
            for p, b in backends.items():
                containers[p] = self._run(b.image, f"{base}-{p}", network, "device", p, b.port,
                                          dict(b.container_options))
            urls = {role: f"http://127.0.0.1:{_host_port(c, TRANSFER_PORT if role == 'transfer' else backends[role].port)}"
                    for role, c in containers.items()}
            transfer = TRANSFER_CLIENTS[self.transfer_flavour](urls["transfer"], TRANSFER_USER, TRANSFER_PASSWORD)

            def ready(role: str) -> None:
                try:
                    if role == "transfer":
                        transfer.wait_ready(TRANSFER_READY_TIMEOUT)
                    else:
                        backends[role].wait_ready(urls[role], self.limits.ready_timeout)
                except InfrastructureError as exc:
                    raise InfrastructureError(f"{exc}\n--- logs of {containers[role].name} ---\n"
                                              f"{_logs(containers[role])}") from None

            with ThreadPoolExecutor(max_workers=len(containers)) as pool:
                for f in [pool.submit(ready, role) for role in containers]:
                    f.result()
            devices = {p: backends[p].connect(urls[p]) for p in platforms}
            image_ids = {role: c.image.id for role, c in containers.items()}
            return TaskEnvironment(devices=devices, transfer=transfer, image_ids=image_ids, network=network,
                                   containers=containers, urls=urls)
        except BaseException:
            remove_all(list(containers.values()), network)
            raise
