"""The head's pool of task environments on a Ray cluster: what `harness/environments.make_environments` is for
one machine (`acquire(platforms)`, `prewarm(platforms)`, `close()`), with each environment on a node.

Where: a task's devices need room on one node: one `jarvis_device_slots` per device, the Ray `memory` its devices
and drive hold once booted (`lifecycle.booted_memory_mb`), and `kvm` when a backend runs KVM guests. The head asks
Ray for that room as a one-bundle placement group, so Ray's scheduler picks the node and holds the room until the
task's environment is closed (a pre-warm holds its own). On that node, the pytest worker's agent (`node.py`,
one actor per worker and node, made on first use, pinned there) boots the environment with the local code.
Before an agent's first task the node's engine gets the images the run needs (copied from the head's engine,
`docker save` streamed into the node's `docker load` through the actor, only where the image id differs).

Why the agent loop stays on the head: the agent (its model client, its memory, the person in the player) and
the results folder are the pytest worker's; only device traffic crosses to the node, one actor call per
observation, action or evaluator read (about a millisecond on one machine: `jarvis bench throughput --ray`).

A node lost while it holds a task's devices (its raylet killed, the machine gone) makes every call to them raise
InfrastructureError: the task ends as an infrastructure error, `--resume` runs it again, and later tasks go to
the nodes left (the lost node's agent is dropped; Ray re-places rooms it held).
"""

from __future__ import annotations

import itertools
import sys
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

from jarvis_pytest.cluster.connect import connect, lost_node, require_nodes
from jarvis_pytest.cluster.facts import (ACTOR_READY_TIMEOUT, DEVICE_SLOTS, IMAGE_CHUNK, IMAGE_CHUNKS_IN_FLIGHT, KVM,
                                         PLACEMENT_TIMEOUT, agent_name)
from jarvis_pytest.cluster.remote import NodeLink, RemoteEnvironment
from jarvis_pytest.errors import InfrastructureError


BOOT_ATTEMPTS = 3      # boots of one environment when nodes are lost under it before it is handed out
LOST_NODE_RETRY = 2.0  # seconds between placements while Ray still offers a node this worker found lost
LOST_NODE_WINDOW = 60.0  # seconds a node found lost is passed over (Ray drops a dead node within about 10 s; one
                         # whose agent alone died is used again after)


class NodeUnavailable(InfrastructureError):
    """A node's agent could not be started or reached (the node is going or gone)."""


def needs_kvm(backend: Any) -> bool:
    """Whether a backend's devices are KVM guests (they pass /dev/kvm into their container, or run VMs on KVM)."""
    devices = " ".join(map(str, (backend.container_options or {}).get("devices", [])))
    return "/dev/kvm" in devices or backend.name == "kvm"


class ClusterEnvironments:
    """One pytest worker's task environments on the cluster at `address` (see the module's docstring)."""

    def __init__(self, address: str, backends: Any, *, run_id: str, worker: str, settings: dict[str, Any],
                 images: dict[str, str]):
        self.address, self.backends, self.run_id, self.worker = address, backends, run_id, worker
        self.settings = {**settings, "run_id": run_id, "worker": worker, "docker_hosts": ()}
        self.images = images                      # tag → image id on the head's engine, wanted on every node
        self.ray = connect(address)
        self.links: dict[str, NodeLink] = {}      # node id → this worker's agent there
        self._lock = threading.Lock()
        self._prewarmed: dict[tuple[str, ...], Future] = {}  # platforms → (placement group, link) being booted
        self._executor = ThreadPoolExecutor(max_workers=4, thread_name_prefix="ray-prewarm")
        self._closed = False
        self.lost_nodes: dict[str, float] = {}    # node → when this worker found it lost (Ray may still place there)
        self._making: dict[str, threading.Lock] = {}  # node → held while this worker's agent there is made
        self._made = itertools.count(1)
        from jarvis_pytest.cluster.node import harness_digest

        self.harness = harness_digest()  # every node's agent must run the same

    # -- room on a node -------------------------------------------------------------------------------------
    def room(self, platforms: tuple[str, ...]) -> dict[str, float]:
        """The resources one environment of `platforms` holds on its node."""
        from jarvis_pytest.environments.lifecycle import booted_memory_mb
        from jarvis_pytest.infra.transfer_server import transfer_server

        backends = [self.backends.backend(p) for p in dict.fromkeys(platforms)]
        memory_mb = booted_memory_mb(backends, transfer_server(self.settings.get("transfer")))
        room = {DEVICE_SLOTS: float(len(backends)), "memory": float(memory_mb * 2**20)}
        if any(needs_kvm(b) for b in backends):
            room[KVM] = 1.0
        return room

    def _place(self, platforms: tuple[str, ...]) -> tuple[Any, str]:
        """A placement group holding the room of `platforms` on one node, and that node's id; waits while the
        cluster is full, raises when no node could ever hold it or none is left."""
        from ray.util.placement_group import placement_group, placement_group_table, remove_placement_group

        room = self.room(platforms)
        nodes = require_nodes(self.ray, self.address)
        if not _any_fits(room, nodes):
            raise InfrastructureError(
                f"no node of the Ray cluster at {self.address} can hold the devices of {list(platforms)} (they need "
                f"{_room_text(room)}; the nodes offer {'; '.join(_room_text(n.resources) for n in nodes)}): start "
                f"one that can (`ray start --resources`, see the README)")
        try:
            pg = placement_group([room], strategy="STRICT_PACK")
        except Exception as exc:
            raise InfrastructureError(f"the Ray cluster at {self.address} did not take a placement group for the "
                                      f"devices of {list(platforms)}: {exc.__class__.__name__}: {exc}") from None
        deadline = time.monotonic() + PLACEMENT_TIMEOUT
        while True:
            ready, _ = self.ray.wait([pg.ready()], timeout=5)
            if ready:
                break
            if time.monotonic() > deadline or not _any_fits(room, require_nodes(self.ray, self.address)):
                remove_placement_group(pg)
                raise InfrastructureError(f"no Ray node had room for the devices of {list(platforms)} "
                                          f"({_room_text(room)}) within {PLACEMENT_TIMEOUT:g} s")
        node_id = placement_group_table(pg)["bundles_to_node_id"][0]
        if time.monotonic() - self.lost_nodes.get(node_id, -LOST_NODE_WINDOW) < LOST_NODE_WINDOW:
            # Ray has not yet seen the node go (about 10 s after its raylet): not there, ask again
            remove_placement_group(pg)
            time.sleep(LOST_NODE_RETRY)
            return self._place(platforms)
        return pg, node_id

    def _free(self, pg: Any) -> None:
        from ray.util.placement_group import remove_placement_group

        try:
            remove_placement_group(pg)
        except Exception:
            pass  # the cluster is gone: nothing holds the room

    # -- the agents -----------------------------------------------------------------------------------------
    def link(self, node_id: str) -> NodeLink:
        """This worker's agent on `node_id`, made (and the node's images seen to) on first use (one maker at a time
        per node: a pre-warm and a task may ask together)."""
        with self._lock:
            making = self._making.setdefault(node_id, threading.Lock())
        with making:
            return self._link(node_id)

    def _link(self, node_id: str) -> NodeLink:
        with self._lock:
            link = self.links.get(node_id)
            if link is not None and link.lost is None:
                return link
            if link is not None:  # lost: the node is passed over a while, then gets a new agent
                self.lost_nodes[node_id] = time.monotonic()
                del self.links[node_id]
                raise NodeUnavailable(link.lost)
        from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

        from jarvis_pytest.cluster.node import NodeAgent

        node = next((n for n in require_nodes(self.ray, self.address) if n.node_id == node_id), None)
        where = f"{node.address} {node_id[:12]}" if node else node_id[:12]
        actor_class = self.ray.remote(NodeAgent)
        actor = actor_class.options(
            name=f"{agent_name(self.run_id, self.worker, node_id)}-{next(self._made)}",  # a lost agent's is not reused
            num_cpus=0, max_concurrency=32, max_restarts=0,
            scheduling_strategy=NodeAffinitySchedulingStrategy(node_id, soft=False),
        ).remote(self.backends.decided(), self.backends.given(), self.settings)
        link = NodeLink(self.ray, actor, node_id, where)
        try:
            info = self.ray.get(actor.info.remote(), timeout=ACTOR_READY_TIMEOUT)
        except Exception as exc:
            if isinstance(exc, self.ray.exceptions.GetTimeoutError) or lost_node(self.ray, exc):
                try:
                    self.ray.kill(actor)
                except Exception:
                    pass
                raise NodeUnavailable(f"the jarvis agent on Ray node {where} did not start "
                                          f"({exc.__class__.__name__}: {str(exc).splitlines()[0][:200]})") from None
            raise
        link.host = f"{info['hostname']} ({node.address})" if node else info["hostname"]
        link.describe = f"{link.host} {node_id[:12]}"
        link.engine = info["engine"]
        if info["harness"] != self.harness:
            self.ray.kill(actor)
            raise InfrastructureError(f"the harness on Ray node {link.describe} is not this one (its files' digest "
                                      f"{info['harness']}, here {self.harness}): install the same jarvis-pytest on "
                                      "every node")
        try:
            self._provide_images(link)
        except Exception as exc:
            if lost_node(self.ray, exc) or link.lost is not None:
                raise NodeUnavailable(f"the Ray node {link.describe} was lost while it got the run's images "
                                      f"({exc.__class__.__name__})") from None
            raise
        with self._lock:
            self.links[node_id] = link
        return link

    def _provide_images(self, link: NodeLink) -> None:
        """Copy to the node's engine each image of the run it lacks (or has with another id): the head's
        `docker save` streamed through the agent into the node's `docker load`."""
        missing = link.ask("images_to_load", self.images)
        if not missing:
            return
        from jarvis_pytest.infra.engine import client

        source = client(timeout=1800)
        for tag in missing:
            if not link.ask("image_begin", tag, self.images[tag]):
                continue  # another worker's agent loaded it meanwhile
            print(f"[jarvis] copying {tag} to Ray node {link.describe} ({link.engine})", file=sys.stderr, flush=True)
            pending: list[Any] = []
            sent: list[int] = []
            buffer = bytearray()
            try:
                for chunk in source.api.get_image(tag, chunk_size=2**21):
                    buffer += chunk
                    if len(buffer) >= IMAGE_CHUNK:
                        pending.append(link.actor.image_chunk.remote(len(sent), bytes(buffer)))
                        sent.append(len(buffer))
                        buffer.clear()
                        if len(pending) >= IMAGE_CHUNKS_IN_FLIGHT:
                            self.ray.get(pending.pop(0))
                if buffer:
                    pending.append(link.actor.image_chunk.remote(len(sent), bytes(buffer)))
                self.ray.get(pending)
            finally:
                link.ask("image_end")

    # -- the pool's interface ---------------------------------------------------------------------------------
    def _boot(self, platforms: tuple[str, ...], pg: Any = None, node_id: str | None = None,
              attempts: int = BOOT_ATTEMPTS) -> RemoteEnvironment:
        """Boot on the node of `pg` (placed now when None). A node lost before the environment is handed out
        costs nothing of the task: it is booted again on another node, up to `attempts` boots in all."""
        if pg is None:
            pg, node_id = self._place(platforms)
        link = None
        try:
            link = self.link(node_id)
            answer = link.ask("acquire", list(platforms))
        except BaseException as exc:
            self._free(pg)
            gone = isinstance(exc, NodeUnavailable) or (link is not None and link.lost is not None)
            if not gone or attempts <= 1:
                raise
            self.lost_nodes[node_id] = time.monotonic()
            print(f"[jarvis] Ray node {node_id[:12]} was lost before the task's devices were ready; booting them "
                  "on another node", file=sys.stderr, flush=True)
            return self._boot(platforms, attempts=attempts - 1)
        return RemoteEnvironment.of(link, answer, link.host, on_close=lambda: self._free(pg))

    def acquire(self, platforms: tuple[str, ...] | list[str]) -> RemoteEnvironment:
        """A fresh, ready environment for `platforms` on a node with room: the pre-warmed one, else booted now."""
        key = tuple(sorted(set(platforms)))
        with self._lock:
            future = self._prewarmed.pop(key, None)
            others = [(k, self._prewarmed.pop(k)) for k in list(self._prewarmed)]
        for other, held in others:  # a wrong guess gives its room back: on a full cluster it could hold the room
            self._executor.submit(self._discard, other, held)  # this task waits for (locally it waits for its key)
        if future is not None:
            try:
                pg, node_id = future.result()
                return self._boot(key, pg, node_id)
            except InfrastructureError as exc:
                print(f"[jarvis] pre-warm of {list(key)} on the Ray cluster failed ({exc}); placing again",
                      file=sys.stderr, flush=True)
        return self._boot(key)

    def prewarm(self, platforms: tuple[str, ...] | list[str]) -> None:
        """Hold room for `platforms` on a node and start booting there (in the background)."""
        key = tuple(sorted(set(platforms)))
        with self._lock:
            if self._closed or key in self._prewarmed:
                return
            self._prewarmed[key] = self._executor.submit(self._prewarm, key)

    def _prewarm(self, key: tuple[str, ...]) -> tuple[Any, str]:
        pg, node_id = self._place(key)
        try:
            self.link(node_id).raw("prewarm", list(key))
        except BaseException:
            self._free(pg)
            raise
        return pg, node_id

    def _discard(self, key: tuple[str, ...], held: Future) -> None:
        try:
            pg, node_id = held.result()
        except Exception:
            return  # its placement or boot failed: it holds nothing
        try:
            self.link(node_id).raw("discard", list(key))
        except Exception:
            pass  # a lost node's pre-warm went with it
        self._free(pg)

    def close(self) -> None:
        """Give back the pre-warmed rooms and close every agent of this worker (their pre-warmed environments and
        kept networks go with them); idempotent; a lost node's leftovers wait for `jarvis cleanup --ray`."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            futures, self._prewarmed = list(self._prewarmed.values()), {}
            links, self.links = list(self.links.values()), {}
        for future in futures:
            try:
                pg, _ = future.result()
                self._free(pg)
            except Exception:
                pass
        self._executor.shutdown(wait=True)
        for link in links:
            if link.lost is None:
                try:
                    link.raw("close")
                except Exception as exc:
                    print(f"[jarvis] could not close the agent on Ray node {link.describe}: {exc}", file=sys.stderr,
                          flush=True)
            try:
                self.ray.kill(link.actor)
            except Exception:
                pass


def _any_fits(room: dict[str, float], nodes: list[Any]) -> bool:
    """Whether some node declares at least `room` in all (busy or not: it could hold it once free)."""
    return any(all(n.resources.get(k, 0) >= v for k, v in room.items()) for n in nodes)


def _room_text(resources: dict[str, float]) -> str:
    shown = {k: v for k, v in resources.items() if k in (DEVICE_SLOTS, KVM, "memory")}
    return ", ".join(f"{k} {v / 2**20:.0f} MB" if k == "memory" else f"{k} {v:g}" for k, v in sorted(shown.items())) \
        or "nothing"


def run_images(backends: Any, transfer: str | None, platforms: set[str]) -> dict[str, str]:
    """Tag → image id on the head's engine of every built image the run's tasks need (`platforms`) and the drive."""
    from jarvis_pytest.infra.engine import client
    from jarvis_pytest.infra.transfer_server import transfer_server

    docker = client()
    tags = {transfer_server(transfer).image} | {backends.backend(p).image_ref for p in platforms
                                                 if backends.backend(p).image_kind == "built"}
    out = {}
    for tag in sorted(tags):
        try:
            out[tag] = docker.images.get(tag).id
        except Exception:
            raise InfrastructureError(f"image {tag} is not on this machine's engine, so it cannot be copied to the "
                                      "Ray nodes: run `jarvis images build` first") from None
    return out


def make_cluster_environments(address: str, backends: Any, *, run_id: str, worker: str,
                              platforms: set[str] | None = None, **settings: Any) -> ClusterEnvironments:
    """The worker's pool on the cluster at `address`; `settings` are `make_environments`'s (device limits, drive,
    egress, pre-warm, keep_devices), applied on every node; `platforms`: those the run's tasks need (their images
    go to the nodes; None: every platform with a backend)."""
    wanted = set(platforms) if platforms is not None else set(backends)
    images = run_images(backends, settings.get("transfer"), {p for p in wanted if p in backends})
    return ClusterEnvironments(address, backends, run_id=run_id, worker=worker, settings=settings, images=images)
