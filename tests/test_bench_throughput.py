"""`jarvis bench throughput` runs real tasks and prints what the issue asks for: per worker count tasks/hour,
speed-up, cold-start share, harness overhead per step and peak memory (plus CPU per task), with every task solved
by the scripted plan. Numbers are printed, never asserted against targets (targets are for the bench)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from jarvis_pytest.bench.throughput import CONTAINERS_CPU

pytestmark = pytest.mark.containers
REPO = Path(__file__).resolve().parents[1]


def test_throughput_bench_runs_real_tasks_and_reports_every_figure(device_images, tmp_path):
    proc = subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "bench", "throughput", "--workers", "1,2",
                           "--tasks", "3", "--latency-ms", "200", "--results", str(tmp_path), "--json"],
                          cwd=REPO, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    print(proc.stdout)
    result = json.loads(proc.stdout)
    assert [r["workers"] for r in result["runs"]] == [1, 2] and result["latency_ms"] == 200
    speed = result["speed_reference"]  # CPU seconds of fixed work before the first run and after the last
    assert set(speed) == {"python_loop_s", "zlib_4mb_s"} and all(len(v) == 2 and min(v) > 0 for v in speed.values())
    for run in result["runs"]:
        assert run["exit"] == 0 and run["tasks"] == run["passed"] == 3, run
        assert run["tasks_per_hour"] > 0 and 0 <= run["cold_start_share"] <= 1
        assert run["overhead_ms"]["steps"] >= 2 * 2 and run["overhead_ms"]["p50"] > 0  # a step: observe + act
        assert run["peak_memory_mb"] > 100 and run["cpu_s_per_task"] > 0 and run["cpu_bound_tasks_per_hour"] > 0
        assert 50 * (run["workers"] + 1) < run["peak_head_mb"] < run["peak_memory_mb"]  # controller and workers
        assert 0 < run["head_cpu_s_per_task"] < run["cpu_s_per_task"] and run["where"] == "local"
        if CONTAINERS_CPU.exists():  # cgroup v1 with Docker's cgroupfs driver, as here
            assert 0 < run["device_cpu_s_per_task"] < run["cpu_s_per_task"], run
        results = [json.loads(p.read_text()) for p in Path(run["results"]).glob("tasks/*/result.json")]
        workers = {r["worker"] for r in results}
        assert len(results) == 3 and workers <= {f"gw{n}" for n in range(run["workers"])}, workers
        if run["workers"] == 1:  # the steady state: one worker is past its first task after it
            assert run["steady"]["tasks"] == 2 and run["steady"]["tasks_per_hour"] > 0, run["steady"]
            assert 0 <= run["steady"]["cold_start_share"] <= 1
    assert result["runs"][0]["speedup"] == 1.0 and result["runs"][1]["speedup"] > 0


def test_steady_state_is_read_where_every_worker_is_busy():
    from jarvis_pytest.bench.throughput import steady_state
    from jarvis_pytest.results.model import TaskResult

    def task(worker: str, start: int, end: int, boot: float) -> TaskResult:
        return TaskResult(task_id=f"{worker}-{end}", category="atomic", platforms=["ubuntu"], instruction="",
                          status="passed", worker=worker, durations={"boot": boot},
                          started=f"2026-11-24T10:00:{start:02d}.000+00:00",
                          finished=f"2026-11-24T10:00:{end:02d}.000+00:00")

    # gw0's first task ends at 4 s, gw1's at 10 s: the window opens at 10 s; gw1 ends its last at 40 s, gw0 at
    # 50 s: it closes at 40 s. In (10, 40] tasks end at 20, 30 (gw0) and 25, 40 (gw1); begun in it: 1.5 s of boot.
    results = [task("gw0", 0, 4, 4.0), task("gw0", 4, 20, 0.5), task("gw0", 20, 30, 1.5), task("gw0", 30, 50, 0.0),
               task("gw1", 0, 10, 9.0), task("gw1", 10, 25, 0.0), task("gw1", 25, 40, 0.0)]
    assert steady_state(results) == {"tasks_per_hour": 4 / 30 * 3600, "cold_start_share": round(1.5 / 60, 3),
                                     "tasks": 4, "window_s": 30.0}
    assert steady_state(results[:4] + results[4:5])["tasks_per_hour"] is None  # gw1 ran one task


def test_every_run_gives_each_worker_the_same_number_of_tasks_by_default():
    from jarvis_pytest.bench.throughput import PER_WORKER, render, tasks_for

    # by default each worker of every run does the same work (the 1-worker run is not given more tasks a worker
    # than the others, which would spread its fixed costs thinner); --tasks N is N in every run
    assert [tasks_for(w, None) for w in (1, 2, 4, 8)] == [PER_WORKER, 2 * PER_WORKER, 4 * PER_WORKER, 8 * PER_WORKER]
    assert [tasks_for(w, 5) for w in (1, 8)] == [5, 5]
    run = {"workers": 1, "tasks": PER_WORKER, "passed": PER_WORKER, "tasks_per_hour": 321.1, "speedup": 1.0,
           "cold_start_share": 0.013, "overhead_ms": {"p50": 25.2, "p90": 56.8, "steps": 64}, "peak_memory_mb": 401,
           "cpu_s_per_task": 3.04, "device_cpu_s_per_task": 2.3, "cpu_bound_tasks_per_hour": 2368,
           "steady": {"tasks_per_hour": 333.2, "speedup": 1.0, "cold_start_share": 0.002}}
    result = {"task": "mousepad-write_note", "latency_ms": 2000, "tasks": None, "cores": 2, "runs": [run],
              "speed_reference": {"python_loop_s": [0.223, 0.224], "zlib_4mb_s": [0.214, 0.222]}}
    assert render(result).startswith(f"{PER_WORKER} × mousepad-write_note per worker in every run, model latency")
    assert render({**result, "tasks": 5}).startswith("5 × mousepad-write_note per run, model latency")
