"""`jarvis bench throughput` runs real tasks and prints what the issue asks for: per worker count tasks/hour,
speed-up, cold-start share, harness overhead per step and peak memory (plus CPU per task), with every task solved
by the scripted plan. Numbers are printed, never asserted against targets (targets are for the bench)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from jarvis_pytest.infra.throughput import CONTAINERS_CPU

pytestmark = pytest.mark.containers
REPO = Path(__file__).resolve().parents[1]


def test_throughput_bench_runs_real_tasks_and_reports_every_figure(device_images, tmp_path):
    proc = subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "bench", "throughput", "--workers", "1,2",
                           "--tasks", "2", "--latency-ms", "200", "--results", str(tmp_path), "--json"],
                          cwd=REPO, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    print(proc.stdout)
    result = json.loads(proc.stdout)
    assert [r["workers"] for r in result["runs"]] == [1, 2] and result["latency_ms"] == 200
    for run in result["runs"]:
        assert run["exit"] == 0 and run["tasks"] == run["passed"] == 2, run
        assert run["tasks_per_hour"] > 0 and 0 <= run["cold_start_share"] <= 1
        assert run["overhead_ms"]["steps"] >= 2 * 2 and run["overhead_ms"]["p50"] > 0  # a step: observe + act
        assert run["peak_memory_mb"] > 100 and run["cpu_s_per_task"] > 0 and run["cpu_bound_tasks_per_hour"] > 0
        if CONTAINERS_CPU.exists():  # cgroup v1 with Docker's cgroupfs driver, as here
            assert 0 < run["device_cpu_s_per_task"] < run["cpu_s_per_task"], run
        assert len(list(Path(run["results"]).glob("tasks/*/result.json"))) == 2
    assert result["runs"][0]["speedup"] == 1.0 and result["runs"][1]["speedup"] > 0
