"""`jarvis bench devices`: cold start, reset from the pre-warm pool, screenshot, action and accessibility-tree
latency (p50/p90 over repeated runs) and the memory of an idle device, each printed beside its target.

Written against the `Device` protocol (`observe`, `act`), so any platform with a backend can be measured.
"""

from __future__ import annotations

import json
import math
import time
import uuid
from typing import Any, Callable

from jarvis_pytest.devices.actions import MoveTo
from jarvis_pytest.infra.cleanup import cleanup
from jarvis_pytest.environments.lifecycle import Lifecycle, Limits
from jarvis_pytest.infra.networks import KEEP_PER_WORKER
from jarvis_pytest.environments.pool import Pool

TARGETS_MS = {"cold_start_ms": 3000, "screenshot_ms": 50, "action_ms": 20}  # DESIGN.md §6; p50


def percentile(values: list[float], q: float) -> float:
    """The `q` quantile (nearest rank) of `values`."""
    s = sorted(values)
    return s[max(0, math.ceil(q * len(s)) - 1)]


def summary(values_ms: list[float]) -> dict[str, float]:
    return {"p50": round(percentile(values_ms, 0.5), 1), "p90": round(percentile(values_ms, 0.9), 1),
            "n": len(values_ms)}


def timed_ms(fn: Callable[[], Any]) -> float:
    t0 = time.perf_counter()
    fn()
    return (time.perf_counter() - t0) * 1000


def idle_memory_mb(container: Any) -> float:
    """Memory in use by a container without its reclaimable page cache (what `docker stats` shows)."""
    mem = container.stats(stream=False)["memory_stats"]
    stats = mem.get("stats", {})
    cache = stats.get("inactive_file", stats.get("total_inactive_file", 0))
    return (mem.get("usage", 0) - cache) / 2**20


def measure(platform: str = "ubuntu", repeat: int = 5, samples: int = 30, idle_seconds: float = 5.0) -> dict:
    """Boot `repeat` environments cold and `repeat` from a pre-warmed pool; time observations and actions. The
    lifecycle keeps task networks for later tasks as a run's workers do, so a cold start takes a kept network."""
    run_id = f"bench-{uuid.uuid4().hex[:6]}"
    lifecycle = Lifecycle(run_id, "bench", Limits(), keep_networks=KEEP_PER_WORKER)
    key = (platform,)
    try:
        cold, teardown = [], []
        for _ in range(repeat):
            t0 = time.perf_counter()
            env = lifecycle.boot(key)
            cold.append((time.perf_counter() - t0) * 1000)
            teardown.append(timed_ms(env.close))
        reset = []
        with Pool(lifecycle) as pool:
            for _ in range(repeat):
                pool.prewarm(key)
                pool.wait_prewarmed(key)  # the task the pool overlaps with lasts longer than a boot
                t0 = time.perf_counter()
                env = pool.acquire(key)
                reset.append((time.perf_counter() - t0) * 1000)
                env.close()
        env = lifecycle.boot(key)
        try:
            device = env.devices[platform]
            first = device.observe()
            shots = [timed_ms(device.observe) for _ in range(samples)]
            actions = [timed_ms(lambda i=i: device.act(MoveTo(x=100 + i, y=200))) for i in range(samples)]
            a11y = [timed_ms(lambda: device.observe(a11y=True)) for _ in range(max(3, samples // 5))]
            time.sleep(idle_seconds)
            memory = {role: round(idle_memory_mb(c)) for role, c in env.containers.items()}
        finally:
            env.close()
    finally:
        lifecycle.close()
        cleanup(run_id)
    return {"platform": platform, "screen": [first.width, first.height], "cold_start_ms": summary(cold),
            "reset_ms": summary(reset), "teardown_ms": summary(teardown), "screenshot_ms": summary(shots),
            "action_ms": summary(actions), "observe_a11y_ms": summary(a11y), "idle_memory_mb": memory,
            "targets_p50_ms": TARGETS_MS}


ROWS = [("cold start (create → ready)", "cold_start_ms"), ("reset (pre-warmed, from the pool)", "reset_ms"),
        ("teardown (close: devices removed)", "teardown_ms"),
        ("screenshot", "screenshot_ms"), ("one action (MOVE_TO)", "action_ms"),
        ("screenshot + accessibility tree", "observe_a11y_ms")]


def render(result: dict) -> str:
    w, h = result["screen"]
    lines = [f"{result['platform']} device, screen {w}×{h}",
             f"{'figure':<36}{'p50 ms':>9}{'p90 ms':>9}{'n':>4}  target (p50)"]
    for label, key in ROWS:
        s, target = result[key], TARGETS_MS.get(key)
        verdict = "" if target is None else f"≤ {target} ms: {'met' if s['p50'] <= target else 'MISSED'}"
        lines.append(f"{label:<36}{s['p50']:>9.1f}{s['p90']:>9.1f}{s['n']:>4}  {verdict}")
    for role, mb in sorted(result["idle_memory_mb"].items()):
        lines.append(f"{'idle memory: ' + role:<36}{mb:>9} MB")
    return "\n".join(lines)


def main(args) -> int:
    result = measure(args.platform, args.repeat, args.samples)
    print(json.dumps(result, indent=2) if args.json else render(result))
    return 0
