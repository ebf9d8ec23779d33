"""A Ray cluster on this one machine, made with `ray start` (tests, `jarvis bench throughput --ray`, and users
trying `--ray` before they have machines): a head that offers no devices and N nodes, node i on its own Docker
engine (`jarvis engine extra <i+1>`, started here), each declaring `jarvis_device_slots`. `jarvis cluster start
--nodes 2` prints the address for `--ray`; `jarvis cluster stop` ends it.

Ray names every node of this machine by the machine's own address (it turns 127.0.0.1 into it:
`ray._private.services.resolve_ip_for_localhost`); traffic to one's own address never leaves the machine (the
kernel's `local` routing table sends it over `lo`: `ip route get <address>` says `local ... dev lo`).
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

from jarvis_pytest.cluster.facts import DEVICE_SLOTS, RAY_ENVIRONMENT
from jarvis_pytest.errors import InfrastructureError

STATE = Path(tempfile.gettempdir()) / "jarvis-ray-local.json"  # the cluster `jarvis cluster start` made
DEFAULT_PORT = 26379
OBJECT_STORE_BYTES = 200 * 2**20  # per node: screenshots and image chunks pass through it, nothing large stays


@dataclass
class LocalCluster:
    """A cluster started here: its address, its Ray session (every process of it names it) and its nodes."""

    address: str
    session: str
    nodes: dict[str, str] = field(default_factory=dict)  # node id → its engine's URL

    def save(self, path: Path = STATE) -> None:
        path.write_text(json.dumps(asdict(self), indent=1))

    @classmethod
    def load(cls, path: Path = STATE) -> "LocalCluster | None":
        try:
            return cls(**json.loads(path.read_text()))
        except (OSError, ValueError, TypeError):
            return None


def _ray_binary() -> str:
    here = Path(sys.executable).with_name("ray")
    found = str(here) if here.exists() else shutil.which("ray")
    if not found:
        raise InfrastructureError("the `ray` command is not installed: pip install 'jarvis-pytest[ray]'")
    return found


def _ray_start(args: list[str], env: dict[str, str] | None = None) -> None:
    environment = {**os.environ, **RAY_ENVIRONMENT, **(env or {})}
    proc = subprocess.run([_ray_binary(), "start", "--disable-usage-stats", *args], env=environment,
                          capture_output=True, text=True, timeout=180)
    if proc.returncode != 0:
        raise InfrastructureError(f"`ray start {' '.join(args)}` failed:\n{(proc.stdout + proc.stderr)[-2000:]}")


def _node_ids() -> set[str]:
    return {line.split("--node_id=", 1)[1].split()[0] for line in _processes() if "raylet/raylet" in line
            and "--node_id=" in line}


def _processes() -> list[str]:
    return subprocess.run(["ps", "-ww", "-eo", "pid,args"], capture_output=True, text=True).stdout.splitlines()[1:]


def share_of_memory(nodes: int) -> int:
    """Bytes of Ray `memory` each of `nodes` nodes of this machine declares: an equal share of 80% of its memory
    (each would otherwise declare all of it, and Ray would place twice what fits)."""
    total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    return int(total * 0.8 / max(nodes, 1))


def add_node(cluster: LocalCluster, engine: str, slots: int = 4, memory: int | None = None) -> str:
    """Start one more node on engine URL `engine` (its raylet gets that engine as $DOCKER_HOST) declaring `slots`
    device slots and `memory` bytes (default: a share as if it were one of len(cluster.nodes)+1); its node id."""
    before = _node_ids()
    memory = memory or share_of_memory(len(cluster.nodes) + 1)
    _ray_start([f"--address={cluster.address}", "--num-cpus=1", f"--object-store-memory={OBJECT_STORE_BYTES}",
                f"--memory={memory}", f"--resources={json.dumps({DEVICE_SLOTS: slots})}"],
               env={"DOCKER_HOST": engine})
    new = sorted(_node_ids() - before)
    if len(new) != 1:
        raise InfrastructureError(f"started a Ray node on {engine} but found {len(new)} new raylets")
    cluster.nodes[new[0]] = engine
    return new[0]


def start(nodes: int = 2, slots: int = 4, port: int = DEFAULT_PORT, first_engine: int = 2) -> LocalCluster:
    """A head on 127.0.0.1:`port` and `nodes` nodes, node i on extra engine `first_engine + i` (started here when
    it does not run); raises InfrastructureError naming what failed (what started is stopped again)."""
    from jarvis_pytest.infra.engine import start_extra_engine

    engines = [start_extra_engine(first_engine + i) for i in range(nodes)]
    _ray_start(["--head", f"--port={port}", "--num-cpus=0", "--include-dashboard=false",
                f"--object-store-memory={OBJECT_STORE_BYTES}"])
    session = Path(tempfile.gettempdir(), "ray", "session_latest").resolve().name
    cluster = LocalCluster(address=f"127.0.0.1:{port}", session=session)
    try:
        for engine in engines:
            add_node(cluster, engine, slots, share_of_memory(nodes))
    except BaseException:
        stop(cluster)
        raise
    return cluster


def alive(cluster: LocalCluster) -> bool:
    """Whether the cluster's head still runs (a process of its session is the GCS server)."""
    return any(cluster.session in line and "gcs_server" in line for line in _processes())


def kill_node(node_id: str) -> None:
    """SIGKILL a node's raylet (what losing the machine does to the cluster; its devices' engine stays)."""
    for line in _processes():
        if "raylet/raylet" in line and f"--node_id={node_id}" in line:
            os.kill(int(line.split()[0]), signal.SIGKILL)
            return
    raise InfrastructureError(f"no raylet of node {node_id[:12]} runs here")


def stop(cluster: LocalCluster, wait: float = 5.0) -> None:
    """Stop every process of the cluster's session (SIGTERM, then SIGKILL); other Ray clusters are left alone."""
    port = cluster.address.rsplit(":", 1)[1]

    def ours() -> list[int]:
        """The session's processes (and the head's Ray client server, which names the head's port), with every
        process they started (workers, agents: they rename themselves `ray::...`)."""
        table = [line.split(None, 2) for line in
                 subprocess.run(["ps", "-ww", "-eo", "pid,ppid,args"], capture_output=True, text=True).stdout.splitlines()[1:]]
        found = {int(pid) for pid, _, args in table if cluster.session in args
                 or ("ray.util.client.server" in args and f":{port} " in args)}
        grew = True
        while grew:
            more = {int(pid) for pid, ppid, _ in table if int(ppid) in found} - found
            found |= more
            grew = bool(more)
        return sorted(found - {os.getpid()})

    for sig in (signal.SIGTERM, signal.SIGKILL):
        for pid in ours():
            try:
                os.kill(pid, sig)
            except OSError:
                pass
        deadline = time.monotonic() + wait
        while ours() and time.monotonic() < deadline:
            time.sleep(0.2)
        if not ours():
            break
