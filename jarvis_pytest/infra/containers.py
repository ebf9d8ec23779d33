"""One container of a task: labelled, limited, published on 127.0.0.1 only, and waited for while it is watched.

Every resource we create carries `labels()`: the run id, the worker, the role (`device`, `transfer`, `network`),
the platform, and the host and process that own it (so `jarvis cleanup` can tell orphans from live runs).
"""

from __future__ import annotations

import os
import re
import socket
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Literal

from jarvis_pytest.errors import ConfigError, InfrastructureError
from jarvis_pytest.infra import egress

# A "backend" here is a `devices.backend.Backend`, read by its attributes only (image_ref, port, identity,
# container_options, platform, label, wait_ready): this layer sits below devices/ and imports nothing from it.
Backend = Any

LABEL_RUN = "org.jarvis.run"
LABEL_WORKER = "org.jarvis.worker"
LABEL_ROLE = "org.jarvis.role"
LABEL_PLATFORM = "org.jarvis.platform"
LABEL_HOST = "org.jarvis.host"
LABEL_PID = "org.jarvis.pid"
LABEL_KEEP = "org.jarvis.keep"  # "1": made by a run started with --keep-devices; no sweep removes it

READY_SLICE = 1.0  # seconds one readiness check may take before we look at the container again

# Every container gets a process limit (cgroup `pids.max`, threads included): a device's user has passwordless
# sudo, and without one a fork bomb in one task fills the host's process table (here `kernel.pid_max` is 32768)
# for every other task and for the host. Measured peaks of `pids.current` (sampled once a second over 696 Ubuntu
# and 351 Wine devices of three oracle benchmark runs, the project's tests and oracle runs of Chromium, GIMP,
# LibreOffice, VLC and WordPad tasks, and 20 times a second over five of them): an Ubuntu device 219 (Chromium
# printing a page), a Wine device 70, the transfer drive 22, a port holder 6 (and of memory, for the backends'
# limits: 583 MB, 242 MB, 36 MB, 4 MB). PIDS_LIMIT is over four times the largest; $JARVIS_DEVICE_PIDS overrides
# it for devices and drives (a whole number, or `none` for no limit); a backend may set `pids_limit` in its
# `container_options`.
PIDS_LIMIT = 1024
PIDS_ENV = "JARVIS_DEVICE_PIDS"
HOLDER_PIDS_LIMIT = 64  # `sleep`, and what is run in it with docker exec (the `ip route` that cuts its route)


def pids_limit(environ: dict[str, str] | None = None) -> int | None:
    """The process limit of a device or drive container: $JARVIS_DEVICE_PIDS (None for `none`), else PIDS_LIMIT.
    A bad value is a ConfigError naming the variable."""
    raw = (os.environ if environ is None else environ).get(PIDS_ENV, "").strip()
    if not raw:
        return PIDS_LIMIT
    if raw.lower() == "none":
        return None
    if raw.isdigit() and int(raw) > 0:
        return int(raw)
    raise ConfigError(f"{raw!r} is not a process limit", field=PIDS_ENV,
                      fix=f"give a whole number of processes (default {PIDS_LIMIT}), or `none` for no limit")


_ENGINE_CPUS: dict[str, int] = {}  # engine URL → its CPUs, asked once


def cpus_of(cores: int) -> float:
    """The default CPU limit of a device on an engine with `cores`: all but one where it has more than two, so
    that a device that spins every core leaves one to the harness, the engine and the other tasks' devices; all of
    them on two or fewer, where one core cost 6 oracle tasks in a row 20-40 % of their time (64 and 74 s against
    54 and 45 s without, on 2 busy cores). Between devices the CPU weights (`BootPriority`) share the cores
    fairly either way."""
    return float(cores - 1 if cores > 2 else max(1, cores))


def device_cpus(docker: Any = None) -> float:
    """The default CPU limit of a device container (`--device-cpus` and a backend's own limit come first):
    `cpus_of` the cores of `docker`'s engine (this machine's without one). Docker refuses a limit above the
    engine's own count, which this process may not share."""
    cores = os.cpu_count() or 1
    if docker is not None:
        url = str(getattr(getattr(docker, "api", None), "base_url", ""))
        if url not in _ENGINE_CPUS:
            try:
                _ENGINE_CPUS[url] = int(docker.info()["NCPU"])
            except Exception:  # the limit is a safeguard: this machine's count will do
                _ENGINE_CPUS[url] = cores
        cores = _ENGINE_CPUS[url]
    return cpus_of(cores)


_KEEP = {"devices": False}


def keep_devices(keep: bool) -> None:
    """Whether the resources this process makes from now on are kept after its run (--keep-devices): they carry
    `LABEL_KEEP`, so every sweep leaves them, whichever run-lock folder it reads, until `jarvis cleanup --kept`."""
    _KEEP["devices"] = keep


def labels(run_id: str, worker: str, role: str, platform: str = "") -> dict[str, str]:
    """The labels of one resource of this process."""
    out = {LABEL_RUN: run_id, LABEL_WORKER: worker, LABEL_ROLE: role, LABEL_PLATFORM: platform,
           LABEL_HOST: socket.gethostname(), LABEL_PID: str(os.getpid())}
    if _KEEP["devices"]:
        out[LABEL_KEEP] = "1"
    return out


def docker_name(*parts: str) -> str:
    """A valid container/network name from `parts` (other characters become `-`)."""
    return re.sub(r"[^a-zA-Z0-9_.-]", "-", "-".join(p for p in parts if p)).strip("-.") or "jarvis"


class BootPriority:
    """The CPU weight (cgroup `cpu.shares`) of the containers one pooled boot makes, over the boot's life.

    - A pre-warm is speculative: its containers start at `LOW`, so that when the cores are full the devices tasks
      act on come first, and it takes only what they leave.
    - `urgent()`: a task now waits for the boot. Its containers rise above Docker's default (the devices of
      running tasks), the more the older the boot (`urgent_weight`). Among the boots tasks wait for, the one begun
      first (the one furthest along) then gets most of the CPU and is done first, then the next; an equal share
      would keep every waiting worker idle until nearly all are done. It is work-conserving: no boot stops while
      another runs. Containers the boot makes after that start at the same weight.
    - `settle()`: the boot is done (or was never waited for): Docker's default from now on, as for any device.
    """

    # Half the default: 128 starved pre-warms on a saturated machine (in one 8-worker run, tasks then waited 67
    # worker-seconds for pre-warms not done, against 1.5 at the default weight); 512 waited 7.5.
    LOW, DEFAULT, HIGHEST = 512, 1024, 262144  # HIGHEST: the kernel's largest cpu.shares

    def __init__(self, low: bool = False):
        self._low = low
        self._urgent: int | None = None  # the weight while a task waits for the boot
        self._made: list[Any] = []
        self._lock = threading.Lock()
        self.started = time.monotonic()

    def urgent_weight(self, now: float | None = None) -> int:
        """The weight of this boot were a task to wait for it now: twice the default (above the devices of
        running tasks), doubled for each second it has been booting, at most HIGHEST."""
        age = max(0.0, (time.monotonic() if now is None else now) - self.started)
        return int(min(self.HIGHEST, 2 * self.DEFAULT * 2 ** min(age, 18.0)))

    def shares(self) -> int | None:
        """The `cpu_shares` to create a container with now (None: Docker's default)."""
        with self._lock:
            return self.LOW if self._low else self._urgent

    def made(self, container: Any, shares: int | None) -> None:
        """`container` was created with `shares`; changed at once if the boot's weight changed meanwhile."""
        with self._lock:
            if self._low or self._urgent is not None:
                self._made.append(container)
            now = self.LOW if self._low else self._urgent
        if shares != now:
            _set_shares(container, now or self.DEFAULT)

    def urgent(self) -> None:
        """A task waits for this boot: its containers get the weight of its age (`urgent_weight`)."""
        weight = self.urgent_weight()
        with self._lock:
            self._low, self._urgent, made = False, weight, list(self._made)
        for container in made:
            _set_shares(container, weight)

    def settle(self) -> None:
        """The boot is done: its containers get Docker's default weight, now and from now on."""
        with self._lock:
            self._low, self._urgent, made, self._made = False, None, self._made, []
        for container in made:
            _set_shares(container, self.DEFAULT)


def _set_shares(container: Any, shares: int) -> None:
    import docker.errors

    try:
        container.update(cpu_shares=shares)
    except docker.errors.NotFound:
        pass  # removed (a failed or cancelled boot)
    except docker.errors.APIError as exc:  # the device still works, only with less of the CPU: never a task error
        print(f"[jarvis] could not set the CPU weight of {container.name} to {shares}: {exc.explanation or exc}",
              file=sys.stderr, flush=True)


def start_container(docker: Any, image: str, name: str, *, network: Any, labels: dict[str, str], port: int | None,
                    aliases: tuple[str, ...] = (), memory: str | None = None, cpus: float | None = None,
                    options: dict[str, Any] | None = None, priority: BootPriority | None = None,
                    pids: int | None | Literal["default"] = "default") -> Any:
    """Create and start a detached container on `network` with `port` published on a free 127.0.0.1 port
    (`network` None: no network or port of its own; `options` then say whose namespace it joins), at the CPU
    weight of `priority` (default: Docker's), with at most `pids` processes (default: `pids_limit()`) and, with
    `memory`, no swap beyond it (a runaway is stopped by the kernel's OOM killer in its container instead of
    swapping the machine to a halt). `options` override all of these."""
    kwargs: dict[str, Any] = dict(detach=True, name=name, labels=labels)
    pids = pids_limit() if pids == "default" else pids
    if pids is not None:
        kwargs["pids_limit"] = pids
    shares = priority.shares() if priority is not None else None
    if shares is not None:
        kwargs["cpu_shares"] = shares
    if network is not None:
        kwargs.update(
            network=network.name,
            networking_config={network.name: docker.api.create_endpoint_config(aliases=list(aliases) or None)},
            ports={f"{port}/tcp": ("127.0.0.1", None)})
    if memory:
        kwargs["mem_limit"] = kwargs["memswap_limit"] = memory
    if cpus:
        kwargs["nano_cpus"] = int(cpus * 1e9)
    kwargs.update(options or {})
    try:
        container = docker.containers.create(image, **kwargs)
    except Exception as exc:
        raise InfrastructureError(f"cannot create container {name} from image {image}: {exc} "
                                  "(build device images with `jarvis images build`)") from exc
    if priority is not None:
        priority.made(container, shares)
    try:
        container.start()
    except Exception as exc:
        container.remove(force=True, v=True)
        raise InfrastructureError(f"cannot start container {name} from image {image}: {exc}") from exc
    return container


def host_url(container: Any, port: int) -> str:
    """`http://127.0.0.1:<published port>` of `port` inside the container."""
    container.reload()
    for b in container.attrs["NetworkSettings"]["Ports"].get(f"{port}/tcp") or []:
        if b.get("HostIp") == "127.0.0.1":
            return f"http://127.0.0.1:{b['HostPort']}"
    raise _failure(container, exited(container) or f"container {container.name} has no port {port} published on "
                                                   "127.0.0.1")


def exited(container: Any) -> str | None:
    """Why the (reloaded) container is no longer running, or None while it runs."""
    state = container.attrs.get("State", {})
    if state.get("Status") in ("exited", "dead"):
        return (f"container {container.name} exited with code {state.get('ExitCode')} before it was ready "
                f"({state.get('Error') or 'no error from Docker'})")
    return None


def logs(container: Any, lines: int = 60) -> str:
    """The last `lines` lines of the container's output (never raises)."""
    try:
        return container.logs(tail=lines).decode("utf-8", "replace").rstrip() or "(no output)"
    except Exception as exc:
        return f"(no logs: {exc.__class__.__name__}: {exc})"


def _failure(container: Any, message: str) -> InfrastructureError:
    return InfrastructureError(f"{message}\n--- last lines of `docker logs {container.name}` ---\n{logs(container)}")


def wait_until_ready(container: Any, check: Callable[[float], None], timeout: float, what: str) -> None:
    """Call `check(seconds)` (raises InfrastructureError while not ready) until it returns, for at most `timeout`.

    Between calls the container is looked at: if it exited, fail at once. Every failure carries its logs.
    """
    deadline = time.monotonic() + timeout
    last = "not checked"
    while True:
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            raise _failure(container, f"{what} ({container.name}) not ready after {timeout:.0f} s: {last}")
        try:
            check(min(READY_SLICE, remaining))
            return
        except InfrastructureError as exc:
            last = str(exc)
        except Exception as exc:
            raise _failure(container, f"{what} ({container.name}): readiness check failed: "
                                      f"{exc.__class__.__name__}: {exc}") from exc
        try:
            container.reload()
        except Exception as exc:
            raise _failure(container, f"{what} ({container.name}) vanished while booting: {exc}") from None
        if exited(container):
            raise _failure(container, f"{what}: {exited(container)}")


def remove_all(containers: list[Any]) -> list[str]:
    """Remove containers (in parallel, with their anonymous volumes); what is already gone is fine. Returns what
    could not be removed (empty when all went), so callers can say so instead of raising in `finally` blocks.
    A task's network goes with `networks.remove_network` (or back to the worker's `TaskNetworks`)."""
    import docker.errors

    def remove(c: Any) -> str | None:
        try:
            c.remove(force=True, v=True)
        except docker.errors.NotFound:
            pass
        except Exception as exc:
            return f"container {c.name}: {exc}"
        return None

    try:
        with ThreadPoolExecutor(max_workers=max(1, len(containers))) as pool:
            results = list(pool.map(remove, containers))
    except RuntimeError:  # at interpreter exit (atexit hooks) no new threads may be scheduled
        results = [remove(c) for c in containers]
    return [p for p in results if p]


def remove_volumes(volumes: list[Any]) -> list[str]:
    """Remove named volumes (a task's drive storage); what is already gone is fine. Returns what could not be
    removed."""
    problems = []
    for v in volumes:
        try:
            v.remove(force=True)
        except Exception as exc:
            if "No such volume" not in str(exc):
                problems.append(f"volume {v.name}: {exc}")
    return problems


HOLDER_ROLE = "holder"
HOLDER_MEMORY = "16m"


NETWORK_FILES = ("HostsPath", "ResolvConfPath", "HostnamePath")  # Docker's files of a container's namespace


def network_files(container: Any) -> dict[str, bytes] | None:
    """The /etc/hosts, /etc/resolv.conf and /etc/hostname Docker keeps for `container`'s network namespace (a
    device that joins it gets the same files, writable by its root), read where the engine keeps them; None
    where this process cannot read them (an engine on another machine, no permission)."""
    files = {}
    for key in NETWORK_FILES:
        try:
            files[key] = Path(container.attrs[key]).read_bytes()
        except (OSError, KeyError, TypeError):
            return None
    return files


@dataclass
class PortHolder:
    """A container that only holds a network namespace on a task network: a device's address there and its
    control port, published on 127.0.0.1. A device of a backend with `Backend.holder` runs in it (Docker's
    `network_mode: container:`), so its start costs the engine no network set-up. Here that set-up cost dockerd
    about 0.15 CPU-s a container: three re-executions of itself (a new namespace, its IPv6 setting, the
    `libnetwork-setkey` prestart hook), an endpoint, firewall rules and a port proxy. The holder outlives its
    device: its network keeps it for the next device of its platform (`infra/networks.py`)."""

    container: Any
    url: str                 # http://127.0.0.1:<published port> of the control port
    files: dict[str, bytes] | None = None  # `network_files` as Docker made them (None: they cannot be read here)

    def untouched(self) -> bool:
        """Whether its /etc/hosts, /etc/resolv.conf and /etc/hostname are as Docker made them, so a next device
        may join it: a device's root can write them, and a changed /etc/hosts would send a later task's device
        elsewhere. False where they cannot be read here: such a holder serves one device only."""
        return self.files is not None and network_files(self.container) == self.files

    @property
    def network_mode(self) -> str:
        """The `network_mode` of a device that runs in this holder's namespace."""
        return f"container:{self.container.id}"


def start_holder(backend: Backend, request: "BootRequest") -> PortHolder:
    """A new holder for `backend`'s devices on the request's network: its image, doing nothing but `sleep`, with
    the control port published and (unless egress is allowed) no default route."""
    c = start_container(request.docker, backend.image_ref, f"{request.name}-net", network=request.network,
                        labels={**request.labels, LABEL_ROLE: HOLDER_ROLE}, port=backend.port,
                        memory=HOLDER_MEMORY, pids=HOLDER_PIDS_LIMIT,
                        options=with_identity(backend.identity, {"entrypoint": ["sleep", "infinity"]}))
    request.started.append(c)
    if not request.egress:
        egress.cut_default_route(c)
    url = host_url(c, backend.port)  # reloads the container: its attributes name its network files
    return PortHolder(c, url, network_files(c))


@dataclass
class BootRequest:
    """What `infra/` hands a backend to boot one device of a task."""

    docker: Any
    name: str                        # the container's name
    network: Any                     # the task's Docker network
    labels: dict[str, str]
    memory: str | None               # the option's value, else the backend's default
    cpus: float | None               # the option's value, else the backend's; None: `device_cpus()`
    ready_timeout: float
    egress: bool = False             # --allow-egress: keep the device's default route
    volumes: dict[str, dict[str, str]] = field(default_factory=dict)  # docker-py `volumes` (e.g. the drive)
    stop: threading.Event = field(default_factory=threading.Event)    # set when the task's boot is abandoned
    started: list[Any] = field(default_factory=list)  # containers made so far: removed if the boot fails
    holder: PortHolder | None = None # the namespace a device of a `Backend.holder` backend joins
    priority: BootPriority | None = None  # the CPU weight of the containers it makes (a pre-warm's starts low)


@dataclass
class BootedDevice:
    """A ready device: its container (or other handle) and the base URL of its control server on 127.0.0.1."""

    container: Any
    url: str
    backend: Backend


def with_identity(identity: dict[str, Any], options: dict[str, Any], *, hostname: bool = True) -> dict[str, Any]:
    """`options` (docker-py container options) with a device's `identity` (`Backend.identity`: its hostname and the
    environment entries that fix its time zone and locale; the backend's own environment entries come first), so
    that nothing of the device comes from the host or from Docker's random container id. `hostname` False: a
    device in a holder's namespace has the holder's."""
    given = options.get("environment") or {}
    if isinstance(given, (list, tuple)):
        given = dict(item.split("=", 1) if "=" in item else (item, "") for item in given)
    out = {**options, "environment": {**identity.get("environment", {}), **given}}
    if hostname and identity.get("hostname"):
        out["hostname"] = identity["hostname"]
    return out


def boot_container(backend: Backend, request: BootRequest) -> BootedDevice:
    """The default boot of a backend: one container of its image on the task network, its control port published
    on 127.0.0.1, no way out unless egress is allowed, then `wait_ready` while the container is watched. With
    `request.holder` the container runs in the holder's network namespace instead, which has all of that."""
    options = with_identity(backend.identity, dict(backend.container_options), hostname=request.holder is None)
    if request.volumes:
        options["volumes"] = {**options.get("volumes", {}), **request.volumes}
    holder = request.holder
    if holder is not None:
        options["network_mode"] = holder.network_mode
    c = start_container(request.docker, backend.image_ref, request.name,
                        network=None if holder else request.network, labels=request.labels,
                        port=None if holder else backend.port, memory=request.memory,
                        cpus=request.cpus or device_cpus(request.docker),
                        options=options, priority=request.priority)
    request.started.append(c)
    booted = BootedDevice(container=c, url="", backend=backend)
    if request.stop.is_set():
        raise InfrastructureError("boot cancelled")
    if holder is not None:
        booted.url = holder.url
    else:
        if not request.egress:
            egress.cut_default_route(c)
        booted.url = host_url(c, backend.port)
    wait_until_ready(c, lambda t: backend.wait_ready(booted.url, t), request.ready_timeout,
                     f"the {backend.label} device")
    return booted
