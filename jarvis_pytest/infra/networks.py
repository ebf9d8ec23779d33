"""Task networks: each live task has a private Docker bridge of its own, closed to everything else
(`infra/egress.py`). A worker may keep the networks of its finished tasks for its next ones, each with its
transfer drive still running on it.

Creating and removing a bridge costs the engine about 40 firewall calls and a bridge interface: here a boot and
close of an Ubuntu environment took 1.61 s with a new network and 1.39 s with a kept one. Around the drive's
server (whose start costs the same either way), a new drive container costs the engine about 0.36 CPU-s to
create, start, publish and remove; renewing a kept one in place about 0.02 (a signal: the drive's PID 1 starts
a new server on a wiped drive; `Lifecycle` then checks that it answers and is empty). So `TaskNetworks(keep=N)`
keeps up to N networks whose task has ended, with their drive (`KeptDrive`) when the lifecycle keeps drives. It
hands one out again only once the engine lists no container on it but that drive. At any moment, then, a network
holds the containers of at most one task, as a new network would. What is not kept is removed: the drive and its
volume, the network's firewall rule, then its bridge. `close` removes the kept ones. A worker that is killed
leaves them to `jarvis cleanup`: they carry the labels and process id of their worker, like the devices.

A kept network also keeps its device holders (`containers.PortHolder`: a namespace with an address and a
published control port, per platform), which spare each later device the engine's network set-up. A holder is
kept only while its /etc/hosts, /etc/resolv.conf and /etc/hostname are as Docker made them (a device's root can
write them), and handed out again only once no container of the run runs in its namespace.
"""

from __future__ import annotations

import sys
import threading
import time
from dataclasses import dataclass
from typing import Any

from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.infra import containers as ctr
from jarvis_pytest.infra import egress as egress_policy

# Networks a worker keeps for its next tasks: the one its finished task leaves while the next task runs and the
# one after is pre-warmed.
KEEP_PER_WORKER = 2


def create_network(docker: Any, name: str, run_id: str, worker: str, egress: bool) -> Any:
    """A new task network `name`: a bridge with this process's labels, closed unless `egress`."""
    try:
        network = docker.networks.create(name, driver="bridge", options=egress_policy.network_options(name, egress),
                                         labels=ctr.labels(run_id, worker, "network"))
        if not egress:
            egress_policy.open_within(name)
        return network
    except Exception as exc:
        hint = (" — Docker ran out of address pools, most likely networks left by crashed runs: run "
                "`jarvis cleanup`" if "address pool" in str(exc) else "")
        raise InfrastructureError(f"cannot create network {name}: {exc}{hint}") from exc


def remove_network(network: Any) -> list[str]:
    """Remove a task network: its firewall rule first (no rule ever names a bridge that is gone), then the
    bridge. What is already gone is fine. Returns what could not be removed."""
    import docker.errors

    egress_policy.close_within(network.name)
    last: Exception | None = None
    for attempt in range(5):  # a container removal racing ours may keep the network busy for a moment
        if attempt:
            time.sleep(0.2)
        try:
            network.remove()
            return []
        except docker.errors.NotFound:
            return []
        except Exception as exc:
            last = exc
    return [f"network {network.name}: {last}"]


def attached(network: Any) -> list[str]:
    """The names of the containers the engine lists on `network` now (a network that is gone has none)."""
    import docker.errors

    try:
        network.reload()
    except docker.errors.NotFound:
        return []
    return sorted(c.get("Name", cid) for cid, c in (network.attrs.get("Containers") or {}).items())


@dataclass
class KeptDrive:
    """A finished task's transfer drive, left running on its network for the worker's next task (which renews it
    before use: `Lifecycle.boot`)."""

    container: Any
    url: str                 # its published http://127.0.0.1:<port>
    volume: Any = None       # its storage when a device mounts it (the Windows S: drive), else None

    def remove(self) -> list[str]:
        """Remove the container, then its volume. Returns what could not be removed."""
        return ctr.remove_all([self.container]) + ctr.remove_volumes([self.volume] if self.volume else [])


Holders = dict[str, ctr.PortHolder]  # platform → its kept holder


def _others_on(network: Any, on_it: list[str], drive: KeptDrive | None, holders: Holders,
               run_id: str | None) -> list[str]:
    """The containers on `network` (`on_it`: `attached(network)`) other than its kept `drive` and `holders`, and,
    given `run_id`, those of that run that run in a holder's namespace (a device there is not listed on the
    network; one more request to the engine)."""
    mine = {h.container.name for h in holders.values()} | ({drive.container.name} if drive else set())
    others = [n for n in on_it if n not in mine]
    if holders and run_id is not None:
        modes = {h.network_mode for h in holders.values()}
        others += sorted(c["Names"][0].lstrip("/") for c in network.client.api.containers(
            all=True, filters={"label": f"{ctr.LABEL_RUN}={run_id}"})
            if (c.get("HostConfig") or {}).get("NetworkMode") in modes)
    return others


def _remove(network: Any, drive: KeptDrive | None, holders: Holders | None = None) -> list[str]:
    """Remove the kept drive (if any) and holders, then the network. Returns what could not be removed."""
    return ((drive.remove() if drive else []) + ctr.remove_all([h.container for h in (holders or {}).values()])
            + remove_network(network))


class TaskNetworks:
    """The task networks of one worker's `Lifecycle`: `take` one for a task, `give_back` it when the task's
    devices are gone, `close` at the end. Thread-safe (a pre-warm boots in a thread of its own)."""

    def __init__(self, docker: Any, run_id: str, worker: str, egress: bool, keep: int = 0,
                 keep_drives: bool = False):
        self.docker, self.run_id, self.worker, self.egress = docker, run_id, worker, egress
        self.keep = keep  # networks kept for later tasks, at most (0: every network is removed with its task)
        self.keep_drives = bool(keep) and keep_drives  # give_back may keep a network's drive with it
        self._free: list[tuple[Any, KeptDrive | None, Holders]] = []
        self._lock = threading.Lock()
        self._closed = False
        self.created = 0  # networks this created, for tests and benchmarks

    def take(self, name: str, volume: bool = False) -> tuple[Any, KeptDrive | None, Holders]:
        """A network no container is on but its kept drive and holders, if any: a kept one with them (the oldest
        whose drive has a volume exactly when `volume`, else the oldest), else a new one named `name` (with no
        drive or holders)."""
        while True:
            with self._lock:
                fits = [i for i, (_, d, _) in enumerate(self._free) if d and (d.volume is not None) == volume]
                network, drive, holders = self._free.pop(fits[0] if fits else 0) if self._free else (None, None, {})
            if network is None:
                break
            names = attached(network)
            on_it = _others_on(network, names, drive, holders, self.run_id)
            if not on_it:  # a holder that stopped (killed, out of memory) has left the network: a new one is made
                stopped = [h.container for h in holders.values() if h.container.name not in names]
                report = ctr.remove_all(stopped)
                if report:
                    print(f"[jarvis] could not remove {'; '.join(report)}", file=sys.stderr, flush=True)
                return network, drive, {p: h for p, h in holders.items() if h.container not in stopped}
            problems = (drive.remove() if drive else []) + ctr.remove_all([h.container for h in holders.values()])
            print(f"[jarvis] network {network.name} still has {', '.join(on_it)} on it: not reused"
                  + (f" (could not remove {'; '.join(problems)})" if problems else ""), file=sys.stderr, flush=True)
        network = create_network(self.docker, name, self.run_id, self.worker, self.egress)
        with self._lock:
            self.created += 1
        return network, None, {}

    def give_back(self, network: Any, reuse: bool = True, drive: KeptDrive | None = None,
                  holders: Holders | None = None) -> list[str]:
        """Keep `network`, with `drive` and `holders` still on it, for a later task when `reuse`, no other
        container is on it and fewer than `keep` are kept; else remove them and the network. Returns what could not
        be removed. What still runs in a holder (a device whose removal failed) is looked for once, by `take`."""
        holders = dict(holders or {})
        if reuse and self.keep > 0 and not _others_on(network, attached(network), drive, holders, None):
            changed = [h.container for h in holders.values() if not h.untouched()]
            problems = ctr.remove_all(changed)  # a holder whose files a device changed serves no other device
            holders = {p: h for p, h in holders.items() if h.container not in changed}
            with self._lock:
                if not self._closed and len(self._free) < self.keep:
                    self._free.append((network, drive, holders))
                    return problems
            return problems + _remove(network, drive, holders)
        return _remove(network, drive, holders)

    def close(self) -> list[str]:
        """Remove the kept drives, holders and networks; later `give_back`s remove theirs (idempotent). Returns
        what could not be removed."""
        with self._lock:
            self._closed = True
            free, self._free = self._free, []
        return [p for network, drive, holders in free for p in _remove(network, drive, holders)]
