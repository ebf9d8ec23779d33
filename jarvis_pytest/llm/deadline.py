"""The deadline of the current agent decision, set by the step loop for the thread that runs `agent.act`.

Model clients read it (`remaining()`) so that no request, retry or back-off outlives the step: each attempt's
timeout is cut to the time left, and no retry starts after the deadline. Agents need not pass it along.
"""

from __future__ import annotations

import contextlib
import threading
import time
from typing import Iterator

_LOCAL = threading.local()


@contextlib.contextmanager
def deadline_at(when: float | None) -> Iterator[None]:
    """Within the block, this thread's model calls end by `when` (a `time.monotonic()` value; None: no deadline)."""
    before = getattr(_LOCAL, "when", None)
    _LOCAL.when = when
    try:
        yield
    finally:
        _LOCAL.when = before


def remaining() -> float | None:
    """Seconds left before this thread's deadline (≤ 0 once passed), or None when it has none."""
    when = getattr(_LOCAL, "when", None)
    return None if when is None else when - time.monotonic()
