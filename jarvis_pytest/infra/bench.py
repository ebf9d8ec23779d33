"""`jarvis bench devices`: cold start, reset from the pre-warm pool, screenshot, action and accessibility-tree
latency (p50/p90 over repeated runs) and memory of an idle device, each printed beside its target."""

from __future__ import annotations

import json
import statistics
import time
import uuid

from jarvis_pytest.devices.actions import MoveTo
from jarvis_pytest.infra.cleanup import cleanup
from jarvis_pytest.infra.lifecycle import Lifecycle
from jarvis_pytest.infra.pool import Pool

TARGETS_MS = {"cold_start": 3000, "screenshot": 50, "action": 20}


def _pct(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, round(q * (len(s) - 1)))]


def _stats(values_ms: list[float]) -> dict[str, float]:
    return {"p50": round(statistics.median(values_ms), 1), "p90": round(_pct(values_ms, 0.9), 1), "n": len(values_ms)}


def _timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return (time.perf_counter() - t0) * 1000


def measure(platform: str = "ubuntu", repeat: int = 5, samples: int = 30) -> dict:
    """Boot `repeat` environments cold and `repeat` from a pre-warmed pool; sample latencies on one device."""
    run_id = f"bench-{uuid.uuid4().hex[:6]}"
    lifecycle = Lifecycle(run_id, "bench")
    key = (platform,)
    try:
        cold = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            env = lifecycle.boot(key)
            cold.append((time.perf_counter() - t0) * 1000)
            env.close()
        pool = Pool(lifecycle)
        reset = []
        for _ in range(repeat):
            pool.prewarm(key)
            time.sleep(3)  # the task the pool overlaps with
            t0 = time.perf_counter()
            env = pool.acquire(key)
            reset.append((time.perf_counter() - t0) * 1000)
            env.close()
        pool.close()
        env = lifecycle.boot(key)
        try:
            device = env.devices[platform]
            shots = [_timed(device.screenshot) for _ in range(samples)]
            actions = [_timed(lambda i=i: device.act(MoveTo(x=100 + i, y=200))) for i in range(samples)]
            a11y = [_timed(device.a11y_tree) for _ in range(max(3, samples // 5))]
            time.sleep(1)
            stats = env.containers[platform].stats(stream=False)
            memory_mb = stats["memory_stats"].get("usage", 0) / 2**20
        finally:
            env.close()
    finally:
        cleanup(run_id)
    return {"platform": platform, "cold_start_ms": _stats(cold), "reset_ms": _stats(reset),
            "screenshot_ms": _stats(shots), "action_ms": _stats(actions), "a11y_ms": _stats(a11y),
            "idle_memory_mb": round(memory_mb), "targets_ms": TARGETS_MS}


def render(result: dict) -> str:
    rows = [("cold start (create → ready)", "cold_start_ms", TARGETS_MS["cold_start"]),
            ("reset (from the pre-warm pool)", "reset_ms", None),
            ("screenshot 1920×1080", "screenshot_ms", TARGETS_MS["screenshot"]),
            ("one action (MOVE_TO)", "action_ms", TARGETS_MS["action"]),
            ("accessibility tree", "a11y_ms", None)]
    lines = [f"{'figure':<32}{'p50 ms':>10}{'p90 ms':>10}{'n':>5}  target"]
    for label, key, target in rows:
        s = result[key]
        verdict = "" if target is None else f"p50 ≤ {target} ms: {'met' if s['p50'] <= target else 'MISSED'}"
        lines.append(f"{label:<32}{s['p50']:>10.1f}{s['p90']:>10.1f}{s['n']:>5}  {verdict}")
    lines.append(f"{'memory of an idle device':<32}{result['idle_memory_mb']:>10} MB")
    return "\n".join(lines)


def main(args) -> int:
    result = measure(args.platform, args.repeat, args.samples)
    print(json.dumps(result, indent=2) if args.json else render(result))
    return 0
