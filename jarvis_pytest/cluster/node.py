"""What runs on a Ray node: the agent (a Ray actor, one per pytest worker and node) that holds the worker's task
environments on that node, and the node-side halves of what the head does there (images, cleanup).

The agent is this plain class, made an actor by the head (`cluster/environments.py`); it builds the same pool a
local run builds (`harness/environments.make_environments`) on the node's own Docker engine, so booting,
pre-warming, network and drive reuse, egress closure and removal are the local code, run on the node. The head
reaches a device only through `call` and `attribute` (its control port stays on the node's 127.0.0.1). A call's
exception comes back as a value and is raised again on the head with its own type (`outcome`), so a device fault or
an infrastructure error means there what it means locally.
"""

from __future__ import annotations

import fcntl
import hashlib
import inspect
import os
import pickle
import queue
import secrets
import socket
import tempfile
import threading
from pathlib import Path
from typing import Any

from jarvis_pytest.errors import InfrastructureError

DRIVE = "transfer"  # the role of the environment's drive client in calls


def engine_url() -> str:
    """The node's Docker engine as results name it: `$DOCKER_HOST` of `ray start`, else "local"."""
    return os.environ.get("DOCKER_HOST") or "local"


def harness_digest() -> str:
    """A digest of the harness's own files as installed here (its .py, .json and .txt files): the head refuses a
    node whose harness differs from its own (results would mix two harnesses)."""
    package = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256()
    for path in sorted(p for p in package.rglob("*") if p.suffix in (".py", ".json", ".txt")
                       and "__pycache__" not in p.parts):
        digest.update(path.relative_to(package).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()[:16]


def shape(obj: Any) -> dict[str, str]:
    """Public name → "method" or "attribute" for an object the head proxies (read without running properties)."""
    out = {}
    for name in dir(obj):
        if name.startswith("_"):
            continue
        try:
            static = inspect.getattr_static(obj, name)
        except AttributeError:
            continue
        if isinstance(static, property):
            out[name] = "attribute"
        elif inspect.isfunction(static) or inspect.ismethoddescriptor(static) or isinstance(
                static, (staticmethod, classmethod)) or (callable(static) and not isinstance(static, type)):
            out[name] = "method"
        else:
            out[name] = "attribute"
    return out


def outcome(fn, *args, **kwargs) -> tuple[str, Any]:
    """("ok", value) or ("raised", exception) of `fn(...)`; an exception that would not survive the trip to the
    head (not picklable, or not rebuilt from its pickle) goes as an InfrastructureError naming it."""
    try:
        return "ok", fn(*args, **kwargs)
    except BaseException as exc:  # returned, not raised: Ray would wrap it in its own error with a traceback
        try:
            pickle.loads(pickle.dumps(exc))
            return "raised", exc
        except Exception:
            return "raised", InfrastructureError(f"{exc.__class__.__name__}: {exc}")


class NodeAgent:
    """One pytest worker's task environments on one node: `acquire` (booted or pre-warmed), `call` a device's or
    the drive's method, `release`. Thread-safe (a threaded actor: a pre-warm boots while a task runs)."""

    def __init__(self, decided: dict, given: dict, settings: dict):
        from jarvis_pytest.devices.backend import resolve_backends
        from jarvis_pytest.infra.engine import client

        self.backends = resolve_backends({}, given, decided=decided)
        self.settings = settings
        self.docker = client(timeout=1800)  # the node's engine ($DOCKER_HOST of `ray start`)
        self.envs: dict[str, Any] = {}
        self.object_readers: dict[str, Any] = {}  # environment → its drive's reader of kept bytes (`drive_events`)
        self.lock = threading.Lock()
        self._pool: Any = None
        self._image: dict[str, Any] | None = None

    @property
    def pool(self) -> Any:
        """The worker's pool on this node, made on first use (after the head saw to the node's images)."""
        with self.lock:
            if self._pool is None:
                from jarvis_pytest.harness.environments import make_environments

                self._pool = make_environments(self.backends, **self.settings)
            return self._pool

    def info(self) -> dict[str, Any]:
        """Where this agent runs: the node's host name, engine, process and harness version."""
        from jarvis_pytest import __version__

        return {"hostname": socket.gethostname(), "engine": engine_url(), "pid": os.getpid(), "version": __version__,
                "harness": harness_digest()}

    # -- environments ---------------------------------------------------------------------------------------
    def acquire(self, platforms: list[str]) -> tuple[str, Any]:
        """`outcome` of booting a fresh environment (pre-warmed when one is): its id, what the head records of it,
        and the shape of each device and of the drive client."""
        return outcome(self._acquire, platforms)

    def _acquire(self, platforms: list[str]) -> dict[str, Any]:
        env = self.pool.acquire(tuple(platforms))
        env_id = secrets.token_hex(6)
        with self.lock:
            self.envs[env_id] = env
        return {"id": env_id, "image_ids": dict(env.image_ids), "backends": dict(env.backends),
                "device_os": dict(env.device_os), "provenance": dict(env.provenance),
                "stand_ins": tuple(env.stand_ins), "engine": engine_url(), "worker": env.worker,
                "boot_started": env.boot_started, "urls": dict(env.urls), "run_id": env.run_id, "egress": env.egress,
                "shapes": {role: shape(part) for role, part in [*env.devices.items(), (DRIVE, env.transfer)]},
                "ledger": env.ledger_signal is not None}

    def prewarm(self, platforms: list[str]) -> None:
        try:
            self.pool.prewarm(tuple(platforms))
        except Exception:
            pass  # the task that needs it meets the same error, where it is reported

    def discard(self, platforms: list[str]) -> None:
        """Remove the pre-warmed environment of `platforms` (its room is given back on the head)."""
        if self._pool is not None:
            self._pool.discard(tuple(platforms))

    def _part(self, env_id: str, role: str) -> Any:
        env = self.envs.get(env_id)
        if env is None:
            raise InfrastructureError(f"no environment {env_id} on this node (released, or the node restarted)")
        return env.transfer if role == DRIVE else env.devices[role]

    def call(self, env_id: str, role: str, name: str, args: tuple, kwargs: dict) -> tuple[str, Any]:
        """`outcome` of the method `name` of a device (`role`: its platform) or of the drive client."""
        return outcome(lambda: getattr(self._part(env_id, role), name)(*args, **kwargs))

    def attribute(self, env_id: str, role: str, name: str) -> tuple[str, Any]:
        return outcome(lambda: getattr(self._part(env_id, role), name))

    def mark_drive(self, env_id: str) -> tuple[str, Any]:
        return outcome(lambda: self.envs[env_id].mark_drive())

    def drive_events(self, env_id: str) -> tuple[str, Any]:
        """The drive's ledger text (None when it keeps none); its reader of kept bytes is kept for `drive_object`."""
        def read():
            ledger = self.envs[env_id].drive_ledger()
            if ledger is None:
                return None
            self.object_readers[env_id] = ledger[1]
            return ledger[0]
        return outcome(read)

    def drive_object(self, env_id: str, sha: str) -> tuple[str, Any]:
        """The bytes the drive kept by SHA-256, read by the reader `drive_events` handed out (the ledger is not read
        again for each object)."""
        return outcome(lambda: self.object_readers[env_id](sha))

    def release(self, env_id: str, keep: bool = False) -> str:
        """Close the environment (or, `keep`, leave it running and say how to reach it); never raises."""
        with self.lock:
            env = self.envs.pop(env_id, None)
            self.object_readers.pop(env_id, None)
        if env is None:
            return ""
        if keep:
            return env.describe()
        env.close()
        return ""

    def close(self) -> None:
        """Close every environment still out and the pool (its pre-warmed environments and kept networks)."""
        with self.lock:
            envs, self.envs = list(self.envs.values()), {}
        for env in envs:
            env.close()
        if self._pool is not None:
            self._pool.close()

    # -- images ---------------------------------------------------------------------------------------------
    def images_to_load(self, wanted: dict[str, str]) -> tuple[str, Any]:
        """`outcome` of `_missing`."""
        return outcome(self._missing, wanted)

    def _missing(self, wanted: dict[str, str]) -> list[str]:
        """The tags of `wanted` (tag → image id on the head) whose image this node's engine lacks or has another id."""
        docker = self.docker
        out = []
        for tag, image_id in wanted.items():
            try:
                if docker.images.get(tag).id == image_id:
                    continue
            except Exception:
                pass
            out.append(tag)
        return out

    def image_begin(self, tag: str, image_id: str) -> tuple[str, Any]:
        """`outcome` of `_begin`."""
        return outcome(self._begin, tag, image_id)

    def _begin(self, tag: str, image_id: str) -> bool:
        """Start loading `tag` into this node's engine (True: send its `docker save` stream with `image_chunk`,
        then `image_end`); False when it is there already (another worker's agent loaded it meanwhile). One load
        per engine at a time: the node's agents wait for each other."""
        lock = Path(tempfile.gettempdir()) / f"jarvis-images-{hashlib.sha256(engine_url().encode()).hexdigest()[:12]}.lock"
        handle = open(lock, "a")
        fcntl.flock(handle, fcntl.LOCK_EX)
        if not self._missing({tag: image_id}):
            handle.close()
            return False
        chunks: queue.Queue = queue.Queue(maxsize=8)
        state: dict[str, Any] = {"tag": tag, "id": image_id, "lock": handle, "chunks": chunks, "error": None,
                                 "next": 0, "turn": threading.Condition()}

        def stream():
            while (chunk := chunks.get()) is not None:
                yield chunk

        def load():
            try:
                for line in self.docker.api.load_image(stream()):
                    if isinstance(line, dict) and line.get("error"):
                        state["error"] = line["error"]
            except Exception as exc:
                state["error"] = f"{exc.__class__.__name__}: {exc}"
                while chunks.get() is not None:  # drain what the head still sends
                    pass

        state["thread"] = threading.Thread(target=load, name=f"load-{tag}", daemon=True)
        state["thread"].start()
        self._image = state
        return True

    def image_chunk(self, index: int, data: bytes) -> None:
        """Chunk `index` (0, 1, ...) of the stream; calls run in threads of their own, so each waits its turn."""
        state = self._image
        with state["turn"]:
            state["turn"].wait_for(lambda: state["next"] == index)
            state["chunks"].put(data)
            state["next"] += 1
            state["turn"].notify_all()

    def image_end(self) -> tuple[str, Any]:
        """`outcome` of `_end`."""
        return outcome(self._end)

    def _end(self) -> None:
        """Finish the load begun by `image_begin`; InfrastructureError when it failed or gave another image id."""
        state, self._image = self._image, None
        state["chunks"].put(None)
        state["thread"].join()
        try:
            if state["error"]:
                raise InfrastructureError(f"loading {state['tag']} into the engine of node {socket.gethostname()} "
                                          f"({engine_url()}) failed: {state['error']}")
            if self._missing({state["tag"]: state["id"]}):
                raise InfrastructureError(f"loading {state['tag']} into {engine_url()} gave another image id")
        finally:
            state["lock"].close()


def cleanup_here(selection: dict[str, Any]) -> dict[str, Any]:
    """`infra/cleanup.cleanup` on this node's engine (a Ray task pinned to the node): counts, or the error."""
    from jarvis_pytest.infra.engines import cleanup_everywhere

    try:
        return {"engine": engine_url(), "hostname": socket.gethostname(),
                "counts": cleanup_everywhere((), **selection), "error": None}
    except Exception as exc:
        return {"engine": engine_url(), "hostname": socket.gethostname(), "counts": {}, "error": str(exc)}
