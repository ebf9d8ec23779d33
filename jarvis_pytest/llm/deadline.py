"""The wall-clock deadline of the current thread's model calls.

The step loop sets one for the thread that runs `agent.act`; the model client sets one per attempt (its
`timeout`) and for the start-up check. Deadlines nest: an inner one never ends later than the one around it.
The network layer (`jarvis_pytest.llm.transport`) reads `remaining()` before every connect, write and read, so
no request, retry or back-off outlives it, however slowly the server sends. Agents need not pass it along.
"""

from __future__ import annotations

import contextlib
import threading
import time
from typing import Iterator

_LOCAL = threading.local()


@contextlib.contextmanager
def deadline_at(when: float | None) -> Iterator[None]:
    """Within the block, this thread's model calls end by `when` (a `time.monotonic()` value), or by the deadline
    around the block if that is earlier (None: only the one around it, if any)."""
    before = getattr(_LOCAL, "when", None)
    _LOCAL.when = when if before is None else before if when is None else min(when, before)
    try:
        yield
    finally:
        _LOCAL.when = before


def remaining() -> float | None:
    """Seconds left before this thread's deadline (≤ 0 once passed), or None when it has none."""
    when = getattr(_LOCAL, "when", None)
    return None if when is None else when - time.monotonic()
