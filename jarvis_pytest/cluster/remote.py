"""The head's side of an environment on a Ray node: `RemoteEnvironment` has what the task engine uses of a local
`TaskEnvironment` (devices, drive client, what the results record, the drive's ledger, `close`), and each device
and the drive client is a `RemotePart` whose attributes and methods are those of the object on the node, each
read or call one actor call. A lost node (its raylet or the agent's process gone) raises InfrastructureError: the
task is an infrastructure error, never the agent's failure."""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from typing import Any, Callable

from jarvis_pytest.cluster.connect import lost_node
from jarvis_pytest.cluster.node import DRIVE
from jarvis_pytest.errors import InfrastructureError


class NodeLink:
    """The head's handle on one node's agent: `ask(method, *args)` calls it and returns the value (raising again
    what the node raised); Ray's own failures become InfrastructureError naming the node, and mark it lost."""

    def __init__(self, ray: Any, actor: Any, node_id: str, describe: str):
        self.ray, self.actor, self.node_id, self.describe = ray, actor, node_id, describe
        self.lost: str | None = None  # why the node is taken for lost (None: it answers)
        self.engine = ""              # the node's Docker engine, as its agent names it
        self.host = describe          # the node's host name and address

    def raw(self, method: str, *args: Any) -> Any:
        """The value of the agent's `method` (no ("ok", value) unwrapping)."""
        if self.lost is not None:
            raise InfrastructureError(self.lost)
        try:
            return self.ray.get(getattr(self.actor, method).remote(*args))
        except BaseException as exc:
            if isinstance(exc, self.ray.exceptions.RayTaskError):  # the agent's own code failed: a harness bug
                raise InfrastructureError(f"the jarvis agent on Ray node {self.describe} failed in {method}: "
                                          f"{exc.cause!r}") from None
            if not lost_node(self.ray, exc):
                raise
            first = (str(exc).splitlines() or [""])[0][:300]
            self.lost = (f"the Ray node {self.describe} was lost ({exc.__class__.__name__}: {first}); the devices "
                         "there are gone with it (`jarvis cleanup --ray` removes their containers once it is back)")
            raise InfrastructureError(self.lost) from None

    def ask(self, method: str, *args: Any) -> Any:
        """The value of a method that answers ("ok", value) or ("raised", exception)."""
        kind, value = self.raw(method, *args)
        if kind == "raised":
            raise value
        return value


class RemotePart:
    """A device (or the drive client) on a node: every public attribute and method of the object there."""

    def __init__(self, link: NodeLink, env_id: str, role: str, shape: dict[str, str]):
        self._link, self._env_id, self._role, self._shape = link, env_id, role, shape
        self._methods: dict[str, Callable[..., Any]] = {}

    def __getattr__(self, name: str) -> Any:
        kind = self._shape.get(name) if not name.startswith("_") else None
        if kind is None:
            raise AttributeError(f"{self._role} device on node {self._link.describe} has no {name!r}")
        if kind == "attribute":
            return self._link.ask("attribute", self._env_id, self._role, name)
        method = self._methods.get(name)
        if method is None:
            def method(*args: Any, **kwargs: Any) -> Any:
                return self._link.ask("call", self._env_id, self._role, name, args, kwargs)
            method.__name__ = name
            self._methods[name] = method
        return method

    def __repr__(self) -> str:
        return f"<{self._role} on Ray node {self._link.describe}>"


@dataclass
class RemoteEnvironment:
    """A task's environment booted on a Ray node (see the module's docstring)."""

    link: NodeLink
    env_id: str
    devices: dict[str, RemotePart]
    transfer: RemotePart
    image_ids: dict[str, str]
    backends: dict[str, str]
    device_os: dict[str, str]
    provenance: dict[str, dict[str, Any]]
    stand_ins: tuple[str, ...]
    engine: str
    worker: str
    boot_started: float
    urls: dict[str, str]
    run_id: str
    egress: bool
    node: str                      # the Ray node's id
    node_host: str = ""            # its host name and address, for messages
    ledger_signal: str | None = None
    on_close: Callable[[], None] | None = None  # gives back the node room the environment held
    _closed: bool = field(default=False, repr=False)

    @classmethod
    def of(cls, link: NodeLink, answer: dict[str, Any], node_host: str,
           on_close: Callable[[], None] | None) -> "RemoteEnvironment":
        env_id, shapes = answer["id"], answer["shapes"]
        return cls(link=link, env_id=env_id,
                   devices={p: RemotePart(link, env_id, p, s) for p, s in shapes.items() if p != DRIVE},
                   transfer=RemotePart(link, env_id, DRIVE, shapes[DRIVE]), image_ids=answer["image_ids"],
                   backends=answer["backends"], device_os=answer["device_os"], provenance=answer["provenance"],
                   stand_ins=tuple(answer["stand_ins"]), engine=answer["engine"], worker=answer["worker"],
                   boot_started=answer["boot_started"], urls=answer["urls"], run_id=answer["run_id"],
                   egress=answer["egress"], node=link.node_id, node_host=node_host,
                   ledger_signal="node" if answer["ledger"] else None, on_close=on_close)

    @property
    def node_label(self) -> str:
        """The node as results record it: its host name (and address) and id."""
        return f"{self.node} ({self.node_host})"

    def mark_drive(self) -> int | None:
        return self.link.ask("mark_drive", self.env_id)

    def drive_ledger(self) -> tuple[str, Callable[[str], bytes | None]] | None:
        text = self.link.ask("drive_events", self.env_id)
        if text is None:
            return None
        return text, lambda sha: self.link.ask("drive_object", self.env_id, sha)

    def describe(self) -> str:
        """How to reach the kept environment (for --keep-devices): on its node."""
        text = self.link.raw("release", self.env_id, True)
        self._closed = True
        self._give_room()
        return (f"on Ray node {self.node_host} ({self.node[:12]}); its docker commands there with DOCKER_HOST="
                f"{self.engine} (`jarvis cleanup` reaches it from here with --ray):\n{text}")

    def close(self) -> None:
        """Remove the environment on its node and give back the room it held (idempotent; never raises: a lost
        node's devices are said to be left for `jarvis cleanup --ray`)."""
        if self._closed:
            return
        self._closed = True
        try:
            self.link.raw("release", self.env_id, False)
        except Exception as exc:
            print(f"[jarvis] could not remove the task's devices on Ray node {self.node_host}: {exc}",
                  file=sys.stderr, flush=True)
        self._give_room()

    def _give_room(self) -> None:
        if self.on_close is not None:
            try:
                self.on_close()
            except Exception:
                pass
            self.on_close = None
