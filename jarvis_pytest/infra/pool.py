"""Pre-warming (paper appendix): boot the next task's devices in the background while the current task runs."""

from __future__ import annotations

import atexit
import sys
import threading
from concurrent.futures import Future, ThreadPoolExecutor
from concurrent.futures import wait as wait_futures

from jarvis_pytest.infra.containers import BootPriority
from jarvis_pytest.infra.lifecycle import Lifecycle, TaskEnvironment


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
    """

    def __init__(self, lifecycle: Lifecycle, enabled: bool = True):
        self.lifecycle = lifecycle
        self.enabled = enabled
        self._ready: dict[tuple[str, ...], tuple[Future, BootPriority]] = {}
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
                priority = BootPriority(low=True)
                self._ready[key] = (self._executor.submit(self.lifecycle.boot, key, priority), priority)

    def wait_prewarmed(self, platforms: tuple[str, ...] | list[str], timeout: float | None = None) -> bool:
        """Wait until the pre-warm of `platforms` finished (booted or failed); False if none or still booting."""
        with self._lock:
            future, _ = self._ready.get(_key(platforms), (None, None))
        return future is not None and bool(wait_futures([future], timeout).done)

    def acquire(self, platforms: tuple[str, ...] | list[str]) -> TaskEnvironment:
        """A fresh, ready environment for `platforms`: the pre-warmed one, else booted now."""
        key = _key(platforms)
        with self._lock:
            future, priority = self._ready.pop(key, (None, None))
        if future is not None:
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

    def close(self) -> None:
        """Remove the environments not handed out (waiting for a boot in progress); idempotent."""
        with self._lock:
            self._closed = True
            futures, self._ready = [f for f, _ in self._ready.values()], {}
        for f in futures:
            try:
                f.result().close()
            except Exception:
                pass  # a failed boot removed what it made
        self._executor.shutdown(wait=True)
        self.lifecycle.close()
        atexit.unregister(self.close)
