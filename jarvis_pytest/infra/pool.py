"""Pre-warming (paper appendix): boot the next task's devices in the background while the current task runs."""

from __future__ import annotations

import atexit
import threading
from concurrent.futures import Future, ThreadPoolExecutor

from jarvis_pytest.infra.lifecycle import Lifecycle, TaskEnvironment


class Pool:
    """Hands out fresh task environments; `prewarm(platforms)` starts booting one ahead of time.

    One pool per worker process. `acquire` takes the pre-warmed environment of the same platform set when there
    is one (waiting for it to finish booting), and boots one itself otherwise; a pre-warmed boot that failed is
    retried once, synchronously. `close` removes every environment not handed out.
    """

    def __init__(self, lifecycle: Lifecycle, enabled: bool = True):
        self.lifecycle = lifecycle
        self.enabled = enabled
        self._ready: dict[tuple[str, ...], Future] = {}
        self._lock = threading.Lock()
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="prewarm")
        atexit.register(self.close)

    def prewarm(self, platforms: tuple[str, ...]) -> None:
        key = tuple(sorted(platforms))
        if not self.enabled:
            return
        with self._lock:
            if key not in self._ready:
                self._ready[key] = self._executor.submit(self.lifecycle.boot, key)

    def acquire(self, platforms: tuple[str, ...]) -> TaskEnvironment:
        key = tuple(sorted(platforms))
        with self._lock:
            future = self._ready.pop(key, None)
        if future is not None:
            try:
                return future.result()
            except Exception:
                pass  # a failed pre-warm: boot once more, and let that error speak
        return self.lifecycle.boot(key)

    def close(self) -> None:
        with self._lock:
            futures, self._ready = list(self._ready.values()), {}
        for f in futures:
            try:
                f.result().close()
            except Exception:
                pass
        self._executor.shutdown(wait=True)
