"""Pre-warming (paper appendix): boot the next task's devices in the background while the current task runs,
as long as the machine has the memory for them beside its running tasks."""

from __future__ import annotations

import atexit
import sys
import threading
from concurrent.futures import Future, ThreadPoolExecutor
from concurrent.futures import wait as wait_futures
from pathlib import Path
from typing import TYPE_CHECKING

from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.infra.containers import BootPriority

if TYPE_CHECKING:  # annotations only: the plugin's options read PREWARM_RESERVE_MB without the lifecycle's imports
    from jarvis_pytest.environments.lifecycle import Lifecycle, TaskEnvironment

# Memory a pre-warm leaves free for the running tasks (MB, --prewarm-reserve-mb): their applications grow as
# they open documents, browsers and images, and a pre-warm that took that memory would starve them.
PREWARM_RESERVE_MB = 2048


def available_memory_mb() -> float | None:
    """`MemAvailable` of this machine in MB, where every engine of a run runs (None where /proc has none)."""
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) / 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def _key(platforms: tuple[str, ...] | list[str]) -> tuple[str, ...]:
    return tuple(sorted(set(platforms)))


class Pool:
    """Hands out fresh task environments; `prewarm(platforms)` starts booting one ahead of time.

    One pool per worker process (its `Lifecycle` names the run and worker). `acquire` takes the pre-warmed
    environment of the same platform set when there is one (waiting for it to finish booting) and boots one
    synchronously otherwise; a pre-warmed boot that failed is retried once, synchronously, so its error is the
    one raised. Handed-out environments are the caller's to close. `close` (also run at interpreter exit)
    removes every environment not handed out and the networks the lifecycle kept. Thread-based: one background
    boot at a time. A pre-warm runs at a low CPU weight (`BootPriority`); a task that waits for it raises it above
    the default, the more the longer it has been booting, and it gets the default once booted.

    Bounded by memory: a pre-warm starts only while the machine's available memory, less what the environment
    will hold (`Lifecycle.booted_memory_mb`), stays above `reserve_mb`; until then it waits (checking twice a
    second, and saying so once on stderr). A task that asks for it boots it at once, as it would boot without a
    pre-warm: the bound holds back speculative boots, never the devices a task needs. Each worker checks on its
    own, so workers that check at the same moment may each start one.
    """

    def __init__(self, lifecycle: Lifecycle, enabled: bool = True, reserve_mb: float = PREWARM_RESERVE_MB):
        self.lifecycle = lifecycle
        self.enabled = enabled
        self.reserve_mb = reserve_mb
        self._ready: dict[tuple[str, ...], tuple[Future, BootPriority, threading.Event]] = {}
        self._lock = threading.Lock()
        self._closed = False
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="prewarm")
        atexit.register(self.close)

    def __enter__(self) -> Pool:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def prewarm(self, platforms: tuple[str, ...] | list[str]) -> None:
        """Start booting an environment for `platforms` unless one is already booting or booted."""
        key = _key(platforms)
        with self._lock:
            if self.enabled and not self._closed and key not in self._ready:
                priority, wanted = BootPriority(low=True), threading.Event()
                self._ready[key] = (self._executor.submit(self._boot_when_room, key, priority, wanted), priority,
                                    wanted)

    def _boot_when_room(self, key: tuple[str, ...], priority: BootPriority,
                        wanted: threading.Event) -> TaskEnvironment:
        """Boot `key` once the memory allows (or a task asks for it: `wanted`)."""
        need, said = self.lifecycle.booted_memory_mb(key), False
        while not wanted.is_set():
            if self._closed:
                raise InfrastructureError("pre-warm cancelled: the pool closed")
            free = available_memory_mb()
            if free is None or free - need >= self.reserve_mb:
                break
            if not said:
                print(f"[jarvis] pre-warm of {list(key)} waits for memory: {free:.0f} MB available, it needs about "
                      f"{need} MB and {self.reserve_mb:.0f} MB stay free for running tasks (--prewarm-reserve-mb)",
                      file=sys.stderr, flush=True)
                said = True
            wanted.wait(0.5)
        return self.lifecycle.boot(key, priority)

    def wait_prewarmed(self, platforms: tuple[str, ...] | list[str], timeout: float | None = None) -> bool:
        """Wait until the pre-warm of `platforms` finished (booted or failed); False if none or still booting."""
        with self._lock:
            future, _, _ = self._ready.get(_key(platforms), (None, None, None))
        return future is not None and bool(wait_futures([future], timeout).done)

    def acquire(self, platforms: tuple[str, ...] | list[str]) -> TaskEnvironment:
        """A fresh, ready environment for `platforms`: the pre-warmed one, else booted now."""
        key = _key(platforms)
        with self._lock:
            future, priority, wanted = self._ready.pop(key, (None, None, None))
        if future is not None:
            wanted.set()  # a pre-warm still waiting for memory boots now: the task needs it
            if not future.done():
                priority.urgent()  # the task waits for it: it comes first, before younger boots
            try:
                environment = future.result()
            except Exception as exc:
                print(f"[jarvis] pre-warmed boot of {list(key)} failed ({exc.__class__.__name__}); booting again",
                      file=sys.stderr, flush=True)
            else:
                priority.settle()  # booted: Docker's default weight, as any device has
                return environment
        priority = BootPriority()
        priority.urgent()  # the task waits for it from the start
        environment = self.lifecycle.boot(key, priority)
        priority.settle()
        return environment

    def discard(self, platforms: tuple[str, ...] | list[str]) -> None:
        """Remove the pre-warmed environment of `platforms` (once booted), if there is one: its room is wanted."""
        with self._lock:
            future, _, wanted = self._ready.pop(_key(platforms), (None, None, None))
        if future is None:
            return
        wanted.set()  # one still waiting for memory boots and goes at once (the pool is single-threaded)
        try:
            future.result().close()
        except Exception:
            pass  # a failed boot removed what it made

    def close(self) -> None:
        """Remove the environments not handed out (waiting for a boot in progress); idempotent."""
        with self._lock:
            self._closed = True
            futures, self._ready = [f for f, _, _ in self._ready.values()], {}
        for f in futures:
            try:
                f.result().close()
            except Exception:
                pass  # a failed boot removed what it made
        self._executor.shutdown(wait=True)
        self.lifecycle.close()
        atexit.unregister(self.close)
