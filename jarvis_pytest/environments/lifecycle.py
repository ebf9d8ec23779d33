"""The containers and network of one task: a fresh device per platform and a transfer drive on a private network.

`Lifecycle(run_id, worker).boot(("ubuntu",))` takes a Docker network for the task (closed to everything but
its own members unless egress is allowed: `infra/egress.py`; new, or one a finished task of this worker left:
`infra/networks.py`), starts the transfer drive on it under the alias `transfer` (devices reach it at
`http://transfer:5244`; a finished task's drive left on the network is renewed instead: a fresh server on a wiped
drive, checked empty) and one device per platform through its backend
(`devices/backend.py`; the run's, resolved once, or each platform's default), all in parallel, and returns a
`TaskEnvironment` once every device and the drive answer, saying what each device really is (`device_os`).
Ports are published on 127.0.0.1 only. A backend that mounts the drive's storage (`Backend.drive_mount`, e.g.
the Windows `S:` drive) shares a volume of the task with the drive. A failed boot removes what it created and
raises `InfrastructureError` with the failing container's logs. `TaskEnvironment.close()` removes it all (its
network it gives back, for reuse or removal). One `Lifecycle` per worker process, closed at the end
(`Lifecycle.close`, which removes the networks it kept); names are unique per run, worker and instance.
"""

from __future__ import annotations

import secrets
import sys
import threading
import time
from concurrent.futures import FIRST_EXCEPTION, ThreadPoolExecutor, wait
from dataclasses import dataclass, field
from collections.abc import Mapping
from typing import Any, Callable

from jarvis_pytest.devices.backend import Backend, Backends
from jarvis_pytest.devices.base import Device
from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.infra import containers as ctr
from jarvis_pytest.infra import drive_ledger
from jarvis_pytest.infra import egress as egress_policy
from jarvis_pytest.infra import engines
from jarvis_pytest.infra.networks import KeptDrive, TaskNetworks, remove_network
from jarvis_pytest.infra.transfer import TransferClient, check_empty
from jarvis_pytest.infra.transfer_server import (TRANSFER_ALIAS, TRANSFER_PASSWORD, TRANSFER_USER, TransferServer,
                                                 served_generation, transfer_server)

TRANSFER_ROLE = "transfer"
TRANSFER_READY_TIMEOUT = 60.0
RENEW_TIMEOUT = 10.0   # seconds a kept drive may take to start its next server (about 0.05 here)
RENEW_POLL = 0.02      # seconds between looks at its log (each one request to the engine, about 2.5 ms of its CPU)


@dataclass(frozen=True)
class Limits:
    """Overrides of the backends' own resources (None: each backend's default) and the drive's memory."""

    memory: str | None = None             # per device container (docker `mem_limit`)
    cpus: float | None = None             # per device container (docker `nano_cpus`)
    ready_timeout: float | None = None    # seconds from create until a device must be ready
    transfer_memory: str | None = "512m"  # the transfer drive's container


@dataclass
class TaskEnvironment:
    """The booted devices of one task, its transfer drive and what is needed to remove them."""

    devices: dict[str, Device]            # platform → host-side device client
    transfer: TransferClient              # host-side client of the drive, on its 127.0.0.1 port
    image_ids: dict[str, str]             # role (platform or "transfer") → image id, for the results
    network: Any                          # the task's Docker network (of `networks`, which it goes back to)
    containers: dict[str, Any]            # role → Docker container
    urls: dict[str, str] = field(default_factory=dict)  # role → http://127.0.0.1:<port>
    run_id: str = ""
    backends: dict[str, str] = field(default_factory=dict)  # platform → backend label, e.g. "windows (wine)"
    device_os: dict[str, str] = field(default_factory=dict)  # platform → what the device is, read inside it
    provenance: dict[str, dict[str, Any]] = field(default_factory=dict)  # platform → what its device is made from
                                                                         # (`Backend.provenance`), for the results
    stand_ins: tuple[str, ...] = ()       # platforms whose backend is a stand-in for the real platform
    egress: bool = False
    volumes: list[Any] = field(default_factory=list)
    engine: str = engines.LOCAL           # the Docker engine it runs on (`infra/engines.py`)
    worker: str = ""                      # the xdist worker (gw0, …; main without xdist) it was booted for
    boot_started: float = 0.0             # wall-clock time (time.time()) its boot began
    networks: TaskNetworks | None = None  # where its network came from (None: removed with it)
    holders: dict[str, ctr.PortHolder] = field(default_factory=dict)  # platform → holder its device ran in
    ledger_signal: str | None = None      # asks the drive for a mark in its ledger (None: it keeps none)
    _booted: list[Any] = field(default_factory=list)
    _closed: bool = False

    def mark_drive(self) -> int | None:
        """A mark in the drive's ledger of what it received and served (`infra/drive_ledger.py`), once everything
        before it is recorded; None when the drive keeps no ledger."""
        if self.ledger_signal is None:
            return None
        return drive_ledger.mark(self.containers[TRANSFER_ROLE], self.ledger_signal)

    def drive_ledger(self) -> tuple[str, Callable[[str], bytes | None]] | None:
        """The drive's ledger (its JSON lines) and a reader of the bytes it kept by SHA-256; None when it keeps
        none."""
        if self.ledger_signal is None:
            return None
        drive = self.containers[TRANSFER_ROLE]
        return drive_ledger.read_events(drive), lambda sha: drive_ledger.read_object(drive, sha)

    def describe(self) -> str:
        """How to reach and remove the environment by hand (for --keep-devices)."""
        lines = [f"network {self.network.name}"]
        for role, c in sorted(self.containers.items()):
            lines.append(f"  {role}: {self.urls.get(role, '')}  (docker exec -it {c.name} bash)")
        names = [c.name for c in self.containers.values()] + [h.container.name for h in self.holders.values()]
        lines.append(f"  kept until: jarvis cleanup --run {self.run_id}  (or `jarvis cleanup --kept` once the run "
                     f"ended, or docker rm -f {' '.join(names)} && docker network rm {self.network.name})")
        return "\n".join(lines)

    def close(self) -> None:
        """Close the clients, remove the devices, the drive and volumes, and give the network back (idempotent;
        never raises)."""
        if self._closed:
            return
        self._closed = True
        for client in [*self.devices.values(), self.transfer]:
            try:
                getattr(client, "close", lambda: None)()
            except Exception:
                pass
        problems: list[str] = []
        for booted in self._booted:  # each backend removes its own device
            try:
                problems += booted.backend.close(booted)
            except Exception as exc:
                problems.append(f"{booted.backend.label}: {exc}")
        owned = {id(b.container) for b in self._booted}
        drive = self.containers.get(TRANSFER_ROLE)
        rest = [c for c in self.containers.values() if id(c) not in owned and c is not drive]
        problems += ctr.remove_all(rest)
        if self.networks is None:
            problems += ctr.remove_all([h.container for h in self.holders.values()])
        if drive is not None and self.networks is not None and self.networks.keep_drives:
            kept = KeptDrive(drive, self.urls[TRANSFER_ROLE], self.volumes[0] if self.volumes else None)
            problems += self.networks.give_back(self.network, drive=kept, holders=self.holders)  # kept, or removed
        else:
            problems += ctr.remove_all([drive] if drive is not None else [])
            problems += (self.networks.give_back(self.network, holders=self.holders) if self.networks
                         else remove_network(self.network))
            problems += ctr.remove_volumes(self.volumes)
        report_leftovers(problems, self.run_id)


def report_leftovers(problems: list[str], run_id: str) -> None:
    """Say on stderr what could not be removed, and how to remove it (nothing when `problems` is empty)."""
    if problems:
        print(f"[jarvis] could not remove {'; '.join(problems)}; run `jarvis cleanup --run {run_id}`",
              file=sys.stderr, flush=True)


_DESCRIBED: dict[tuple[str, str], str] = {}  # (backend label, image id or device URL) → what the device is
_DESCRIBED_LOCK = threading.Lock()


def describe_device(backend: Backend, device: Device, key: str) -> str:
    """What a booted device really is (`Backend.describe`: its system's name and version, read inside it), asked
    once per backend and image (`key`) in this process; a device that cannot say is "unknown (why)" and is asked
    again next time. Never raises: a task does not fail for it."""
    with _DESCRIBED_LOCK:
        known = _DESCRIBED.get((backend.label, key))
    if known is not None:
        return known
    try:
        text = backend.describe(device).strip()
    except Exception as exc:
        return f"unknown ({exc.__class__.__name__}: {str(exc)[:200]})"
    with _DESCRIBED_LOCK:
        _DESCRIBED[(backend.label, key)] = text
    return text


def device_provenance(backend: Backend) -> dict[str, Any]:
    """What `backend`'s devices are made from (`Backend.provenance`), for a task's result; never raises (a task does
    not fail for it): {"unknown": why} when it cannot say."""
    try:
        return dict(backend.provenance()) if backend.provenance is not None else {}
    except Exception as exc:
        return {"unknown": f"{exc.__class__.__name__}: {str(exc)[:200]}"}


def booted_memory_mb(backends: list[Backend], server: TransferServer) -> int:
    """About what a freshly booted environment holds: one device of each backend, and the drive of `server`."""
    return sum(b.booted_memory_mb for b in backends) + server.booted_memory_mb


class Lifecycle:
    """Creates task environments for one run and worker.

    `backends` are the run's backends, resolved once (`devices.backend.resolve_backends`); without them each
    platform gets its default backend, resolved on first use (tests, `jarvis bench`).
    `egress` opens the task networks (recorded in results); by default they are closed (`infra/egress.py`).
    `keep_networks` networks of finished tasks are kept for later ones (`infra/networks.py`), with their drives
    when the drive's flavour can be renewed; `close` removes them.
    """

    def __init__(self, run_id: str, worker: str = "main", limits: Limits | None = None,
                 transfer: str | None = None, backends: Mapping[str, Backend] | None = None, egress: bool = False,
                 docker_host: str | None = None, keep_networks: int = 0):
        from jarvis_pytest.infra.engine import client

        self.docker_host = docker_host  # the engine of every environment this makes (None: the local engine)
        self.docker = client(host=docker_host)
        self.run_id, self.worker = run_id, worker
        self.limits = limits or Limits()
        self.egress = egress
        self.server: TransferServer = transfer_server(transfer)
        self.backends = backends if isinstance(backends, Backends) else Backends(backends, open=backends is None)
        self._prefix = ctr.docker_name("jarvis", run_id, worker, secrets.token_hex(2))
        self._counter = 0
        self._lock = threading.Lock()
        self._hold = True  # devices of `Backend.holder` backends run in holders (off where they cannot be checked)
        self._ensure_image(self.server.image, pull=not self.server.built_here)
        if not egress:
            egress_policy.ensure_rules()
        self.networks = TaskNetworks(self.docker, run_id, worker, egress, keep=keep_networks,
                                     keep_drives=self.server.renew_signal is not None)

    def close(self) -> None:
        """Remove the networks kept for later tasks (idempotent; environments still out are their holders' to
        close, and then remove their networks)."""
        report_leftovers(self.networks.close(), self.run_id)

    def backend(self, platform: str) -> Backend:
        return self.backends.backend(platform)

    def booted_memory_mb(self, platforms: tuple[str, ...] | list[str]) -> int:
        """About what a freshly booted environment of `platforms` holds: its devices and its drive."""
        return booted_memory_mb([self.backend(p) for p in dict.fromkeys(platforms)], self.server)

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

    def _drive_volume(self, name: str) -> Any:
        return self.docker.volumes.create(f"{name}-drive", labels=ctr.labels(self.run_id, self.worker, "volume"))

    def _renewed(self, kept: KeptDrive | None, mounted: bool) -> KeptDrive | None:
        """`kept` (a past task's drive on the network just taken; only flavours that renew keep drives) with a
        fresh server started on its wiped storage, when its storage suits the task (a volume exactly when a device
        mounts it); else None, with `kept` removed (a drive that fails to renew is reported: the task gets a new
        one)."""
        if kept is None:
            return None
        if (kept.volume is not None) == mounted:
            try:
                before = served_generation(kept.container)
                kept.container.kill(signal=self.server.renew_signal)
                deadline = time.monotonic() + RENEW_TIMEOUT
                while served_generation(kept.container) <= before:  # its old server gone, the drive wiped
                    if time.monotonic() > deadline:
                        raise InfrastructureError(f"no new server within {RENEW_TIMEOUT:g} s of "
                                                  f"{self.server.renew_signal} (still generation {before})")
                    time.sleep(RENEW_POLL)
                return kept
            except Exception as exc:
                why = f"renewal failed: {exc}"
                try:
                    kept.container.reload()
                    state = kept.container.attrs.get("State") or {}
                    if not state.get("Running"):
                        why = f"its server ended by itself (exit code {state.get('ExitCode')})"
                except Exception:
                    pass
            print(f"[jarvis] kept drive {kept.container.name}: {why}; a new drive is started",
                  file=sys.stderr, flush=True)
        report_leftovers(kept.remove(), self.run_id)
        return None

    def boot(self, platforms: tuple[str, ...] | list[str],
             priority: ctr.BootPriority | None = None) -> TaskEnvironment:
        """A network with a transfer drive and one fresh, ready device per platform (booted in parallel), the
        containers it makes at the CPU weight of `priority` (default: Docker's)."""
        platforms = tuple(dict.fromkeys(platforms))
        if not platforms or TRANSFER_ROLE in platforms:
            raise InfrastructureError(f"cannot boot platforms {list(platforms)}: give at least one device platform "
                                      f"(not {TRANSFER_ROLE!r}, which every task gets)")
        # unknown platforms, and those with no backend here, fail now, before anything exists; whether a backend
        # runs here was asked once, when the backends were resolved
        backends = {p: self.backend(p) for p in platforms}
        base = self._next_name()
        boot_started = time.time()
        mounted = any(b.drive_mount for b in backends.values())  # a device mounts the drive's storage
        network, kept, holders = self.networks.take(base, volume=mounted)
        volumes: list[Any] = []
        stop = threading.Event()
        started: list[Any] = [h.container for h in holders.values()]  # every container made (by any thread), or
                                                                      # taken: all removed if the boot fails
        booted: dict[str, ctr.BootedDevice] = {}
        clients: dict[str, Any] = {}
        urls: dict[str, str] = {}
        try:
            kept = self._renewed(kept, mounted)
            drive_volume = None
            if kept is not None:
                started.append(kept.container)
                if kept.volume is not None:
                    drive_volume = kept.volume
                    volumes.append(drive_volume)
            elif mounted:
                drive_volume = self._drive_volume(base)
                volumes.append(drive_volume)

            def bring_up_drive() -> None:
                if kept is not None:  # renewed: a fresh server on a wiped drive, in the container of a past task
                    url = urls[TRANSFER_ROLE] = kept.url
                    drive = clients[TRANSFER_ROLE] = self.server.client(url, TRANSFER_USER, TRANSFER_PASSWORD)
                    ctr.wait_until_ready(kept.container, lambda t: drive.wait_ready(t), TRANSFER_READY_TIMEOUT,
                                         "the renewed transfer drive")
                    check_empty(drive)
                    return
                options = {**self.server.container_options, "hostname": TRANSFER_ALIAS}  # not Docker's random id
                if drive_volume is not None:  # the drive's storage, shared with devices that mount it (S: on Windows)
                    options["volumes"] = {drive_volume.name: {"bind": self.server.storage, "mode": "rw"}}
                    tmpfs = {k: v for k, v in options.get("tmpfs", {}).items() if k != self.server.storage}
                    options.pop("tmpfs", None)
                    if tmpfs:
                        options["tmpfs"] = tmpfs
                c = ctr.start_container(self.docker, self.server.image, f"{base}-transfer", network=network,
                                        labels=ctr.labels(self.run_id, self.worker, "transfer"),
                                        port=self.server.port, aliases=(TRANSFER_ALIAS,),
                                        memory=self.limits.transfer_memory, options=options, priority=priority)
                started.append(c)
                if stop.is_set():
                    raise InfrastructureError("boot cancelled")
                if not self.egress:
                    egress_policy.cut_default_route(c)
                url = urls[TRANSFER_ROLE] = ctr.host_url(c, self.server.port)
                drive = clients[TRANSFER_ROLE] = self.server.client(url, TRANSFER_USER, TRANSFER_PASSWORD)
                if self.server.provision:
                    ctr.wait_until_ready(c, lambda t: drive.wait_ready(t), TRANSFER_READY_TIMEOUT,
                                         "the transfer drive's server")
                    self.server.provision(url)
                ctr.wait_until_ready(c, lambda t: drive.wait_ready(t), TRANSFER_READY_TIMEOUT, "the transfer drive")

            def bring_up(platform: str, backend: Backend) -> None:
                if stop.is_set():
                    raise InfrastructureError("boot cancelled")
                vols = {}
                if backend.drive_mount and drive_volume is not None:
                    vols = {drive_volume.name: {"bind": backend.drive_mount, "mode": "rw"}}
                request = ctr.BootRequest(
                    docker=self.docker, name=f"{base}-{platform}", network=network,
                    labels=ctr.labels(self.run_id, self.worker, "device", platform),
                    memory=self.limits.memory or backend.memory, cpus=self.limits.cpus or backend.cpus,
                    ready_timeout=self.limits.ready_timeout or backend.ready_timeout, egress=self.egress,
                    volumes=vols, stop=stop, started=started, priority=priority)
                if backend.holder and self._hold:
                    request.holder = holders.get(platform) or ctr.start_holder(backend, request)
                    holders[platform] = request.holder
                    if request.holder.files is None:  # cannot be checked, so never kept: one holder per device
                        self._hold = False            # would cost more than none
                    if stop.is_set():
                        raise InfrastructureError("boot cancelled")
                booted[platform] = backend.boot(request)
                urls[platform] = booted[platform].url

            executor = ThreadPoolExecutor(max_workers=len(platforms) + 1, thread_name_prefix=f"boot-{base}")
            try:
                futures = [executor.submit(bring_up_drive)]
                futures += [executor.submit(bring_up, p, b) for p, b in backends.items()]
                done, _ = wait(futures, return_when=FIRST_EXCEPTION)
                errors = [f.exception() for f in futures if f in done and f.exception() is not None]
                if errors:
                    stop.set()
                    ctr.remove_all(list(started))  # makes the other boot threads fail fast
                    raise errors[0]
            finally:
                executor.shutdown(wait=True, cancel_futures=True)
            devices = {p: backends[p].connect(booted[p].url) for p in platforms}
        except BaseException:
            stop.set()
            ctr.remove_all(list(started))  # everything made, also while we were removing
            self.networks.give_back(network, reuse=False)
            ctr.remove_volumes(volumes)  # a renewed drive's too: its container went with `started`
            for client in clients.values():
                client.close()
            raise
        containers: dict[str, Any] = {}
        for c in started:
            if c.labels.get(ctr.LABEL_ROLE) == ctr.HOLDER_ROLE:
                continue
            role = c.labels.get(ctr.LABEL_PLATFORM) or TRANSFER_ROLE
            containers[role] = c
        image_ids = {role: c.attrs["Image"] for role, c in containers.items()}
        device_os = {p: describe_device(b, devices[p], image_ids.get(p) or urls[p]) for p, b in backends.items()
                     if b.describe is not None}
        provenance = {p: device_provenance(b) for p, b in backends.items() if b.provenance is not None}
        return TaskEnvironment(devices=devices, transfer=clients[TRANSFER_ROLE], image_ids=image_ids,
                               network=network, containers=containers, urls=urls, run_id=self.run_id,
                               backends={p: b.label for p, b in backends.items()}, device_os=device_os,
                               provenance=provenance,
                               stand_ins=tuple(p for p, b in backends.items() if b.stand_in),
                               egress=self.egress, volumes=volumes, _booted=list(booted.values()),
                               engine=engines.name(self.docker_host), worker=self.worker, boot_started=boot_started,
                               networks=self.networks, holders=holders, ledger_signal=self.server.mark_signal)
