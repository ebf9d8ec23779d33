"""The containers and network of one task: a fresh device per platform and a transfer drive on a private network.

`Lifecycle(run_id, worker, limits).boot(("ubuntu",))` creates a Docker network for the task, starts the transfer
drive on it under the alias `transfer` (devices reach it at `http://transfer:5244`) and one container per
platform from its backend's image, all in parallel, and returns a `TaskEnvironment` once every device's
`wait_ready` and the drive's listing answer. Ports are published on 127.0.0.1 only. A failed boot removes what it
created and raises `InfrastructureError` with the failing container's logs. `TaskEnvironment.close()` removes it
all. One `Lifecycle` per worker process; names are unique per run, worker and instance.
"""

from __future__ import annotations

import secrets
import sys
import threading
from concurrent.futures import FIRST_EXCEPTION, ThreadPoolExecutor, wait
from dataclasses import dataclass, field
from typing import Any

from jarvis_pytest.devices.backend import TRANSFER_ALIAS, TRANSFER_PASSWORD, TRANSFER_USER, backend_for
from jarvis_pytest.devices.base import Device
from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.infra import containers as ctr
from jarvis_pytest.infra.images import image_tag
from jarvis_pytest.infra.transfer import TransferClient
from jarvis_pytest.infra.transfer_server import TransferServer, transfer_server

TRANSFER_ROLE = "transfer"
TRANSFER_READY_TIMEOUT = 60.0  # the drive's own allowance; `Limits.ready_timeout` is the devices'


@dataclass(frozen=True)
class Limits:
    """Resources of each container and how long a device may take to boot."""

    memory: str | None = "4g"             # per device container (docker `mem_limit`), None: unlimited
    cpus: float | None = None             # per device container (docker `nano_cpus`), None: unlimited
    ready_timeout: float = 60.0           # seconds from create until a device must be ready
    transfer_memory: str | None = "512m"  # the transfer drive's container


@dataclass
class TaskEnvironment:
    """The booted devices of one task, its transfer drive and what is needed to remove them."""

    devices: dict[str, Device]            # platform → host-side device client
    transfer: TransferClient              # host-side client of the drive, on its 127.0.0.1 port
    image_ids: dict[str, str]             # role (platform or "transfer") → image id, for the results
    network: Any                          # the task's Docker network
    containers: dict[str, Any]            # role → Docker container
    urls: dict[str, str] = field(default_factory=dict)  # role → http://127.0.0.1:<port>
    run_id: str = ""
    _closed: bool = False

    def describe(self) -> str:
        """How to reach and remove the environment by hand (for --keep-devices)."""
        lines = [f"network {self.network.name}"]
        for role, c in sorted(self.containers.items()):
            lines.append(f"  {role}: {self.urls.get(role, '')}  (docker exec -it {c.name} bash)")
        lines.append(f"  remove with: jarvis cleanup --run {self.run_id}  (or docker rm -f "
                     f"{' '.join(c.name for c in self.containers.values())} && docker network rm {self.network.name})")
        return "\n".join(lines)

    def close(self) -> None:
        """Close the clients and remove the containers and the network (idempotent; never raises)."""
        if self._closed:
            return
        self._closed = True
        for client in [*self.devices.values(), self.transfer]:
            try:
                getattr(client, "close", lambda: None)()
            except Exception:
                pass
        problems = ctr.remove_all(list(self.containers.values()), self.network)
        if problems:
            print(f"[jarvis] could not remove {'; '.join(problems)}; run `jarvis cleanup --run {self.run_id}`",
                  file=sys.stderr, flush=True)


@dataclass(frozen=True)
class _Role:
    """How to start one container of a task."""

    name: str
    platform: str
    image: str
    port: int
    options: dict[str, Any]
    memory: str | None
    cpus: float | None
    aliases: tuple[str, ...] = ()


class Lifecycle:
    """Creates task environments for one run and worker."""

    def __init__(self, run_id: str, worker: str = "main", limits: Limits | None = None,
                 transfer: str | None = None):
        from jarvis_pytest.infra.engine import client

        self.docker = client()
        self.run_id, self.worker = run_id, worker
        self.limits = limits or Limits()
        self.server: TransferServer = transfer_server(transfer)
        self._prefix = ctr.docker_name("jarvis", run_id, worker, secrets.token_hex(2))
        self._counter = 0
        self._lock = threading.Lock()
        self._ensure_image(self.server.image, pull=not self.server.built_here)

    def _ensure_image(self, image: str, pull: bool) -> None:
        import docker.errors

        try:
            self.docker.images.get(image)
            return
        except docker.errors.ImageNotFound:
            if not pull:
                raise InfrastructureError(f"image {image} is not built: run `jarvis images build`") from None
        try:
            self.docker.images.pull(image)
        except Exception as exc:
            first = str(exc).splitlines()[0][:300]
            raise InfrastructureError(f"cannot pull {image} for the {self.server.flavour} transfer drive ({first}); "
                                      "use the offline default (--transfer copyparty, or unset JARVIS_TRANSFER), "
                                      "or `docker pull` it where a registry is reachable (then `docker save`/"
                                      "`docker load` it here), or set JARVIS_ALIST_IMAGE to an image you have") from exc

    def _next_name(self) -> str:
        with self._lock:
            self._counter += 1
            return f"{self._prefix}-{self._counter}"

    def _network(self, name: str) -> Any:
        try:
            return self.docker.networks.create(name, driver="bridge",
                                               labels=ctr.labels(self.run_id, self.worker, "network"))
        except Exception as exc:
            hint = (" — Docker ran out of address pools, most likely networks left by crashed runs: run "
                    "`jarvis cleanup`" if "address pool" in str(exc) else "")
            raise InfrastructureError(f"cannot create network {name}: {exc}{hint}") from exc

    def _roles(self, base: str, platforms: tuple[str, ...]) -> dict[str, _Role]:
        if not platforms or TRANSFER_ROLE in platforms:
            raise InfrastructureError(f"cannot boot platforms {list(platforms)}: give at least one device platform "
                                      f"(not {TRANSFER_ROLE!r}, which every task gets)")
        backends = {p: backend_for(p) for p in platforms}
        roles = {TRANSFER_ROLE: _Role(f"{base}-transfer", "", self.server.image, self.server.port,
                                      dict(self.server.container_options), self.limits.transfer_memory, None,
                                      (TRANSFER_ALIAS,))}
        for p, b in backends.items():
            roles[p] = _Role(f"{base}-{p}", p, image_tag(b.image), b.port, dict(b.container_options),
                             self.limits.memory, self.limits.cpus)
        return roles

    def boot(self, platforms: tuple[str, ...] | list[str]) -> TaskEnvironment:
        """A network with a transfer drive and one fresh, ready device per platform (booted in parallel)."""
        platforms = tuple(dict.fromkeys(platforms))
        base = self._next_name()
        roles = self._roles(base, platforms)          # unknown platforms fail here, before anything exists
        network = self._network(base)
        started: dict[str, Any] = {}                   # role → container, filled by the boot threads
        clients: dict[str, Any] = {}
        stop = threading.Event()

        def bring_up(role: str, spec: _Role) -> str:
            if stop.is_set():
                raise InfrastructureError("boot cancelled")
            kind = "transfer" if role == TRANSFER_ROLE else "device"
            c = ctr.start_container(self.docker, spec.image, spec.name, network=network,
                                    labels=ctr.labels(self.run_id, self.worker, kind, spec.platform),
                                    port=spec.port, aliases=spec.aliases, memory=spec.memory, cpus=spec.cpus,
                                    options=spec.options)
            started[role] = c
            if stop.is_set():
                raise InfrastructureError("boot cancelled")
            url = ctr.host_url(c, spec.port)
            if role == TRANSFER_ROLE:
                drive = clients[role] = self.server.client(url, TRANSFER_USER, TRANSFER_PASSWORD)
                if self.server.provision:
                    ctr.wait_until_ready(c, lambda t: drive.wait_ready(t), TRANSFER_READY_TIMEOUT,
                                         "the transfer drive's server")
                    self.server.provision(url)
                ctr.wait_until_ready(c, lambda t: drive.wait_ready(t), TRANSFER_READY_TIMEOUT, "the transfer drive")
            else:
                backend = backend_for(role)
                ctr.wait_until_ready(c, lambda t: backend.wait_ready(url, t), self.limits.ready_timeout,
                                     f"the {role} device")
            return url

        executor = ThreadPoolExecutor(max_workers=len(roles), thread_name_prefix=f"boot-{base}")
        try:
            futures = {role: executor.submit(bring_up, role, spec) for role, spec in roles.items()}
            done, _ = wait(futures.values(), return_when=FIRST_EXCEPTION)
            errors = [f.exception() for f in futures.values() if f in done and f.exception() is not None]
            if errors:
                stop.set()
                ctr.remove_all(list(started.values()), None)  # makes the other boot threads fail fast
                raise errors[0]
            urls = {role: f.result() for role, f in futures.items()}
            devices = {p: backend_for(p).connect(urls[p]) for p in platforms}
        except BaseException:
            stop.set()
            ctr.remove_all(list(started.values()), None)
            executor.shutdown(wait=True, cancel_futures=True)
            ctr.remove_all(list(started.values()), network)  # also what was created while we removed
            for client in clients.values():
                client.close()
            raise
        executor.shutdown(wait=True)
        image_ids = {role: c.attrs["Image"] for role, c in started.items()}
        return TaskEnvironment(devices=devices, transfer=clients[TRANSFER_ROLE], image_ids=image_ids,
                               network=network, containers=dict(started), urls=urls, run_id=self.run_id)
