"""`jarvis bench throughput`: how many tasks one machine carries when the wait is for a model.

The same real atomic tasks (Ubuntu's `mousepad-write_note` instances: real devices, set-up, evaluation) run with
the planner–grounder agent (`holo2`) against the project's loopback OpenAI-compatible server, which answers each
model call after a fixed latency with a scripted plan that really solves the task (click the editor, type the
note, save, done). Once per worker count it reports tasks/hour, the speed-up against one worker, the share of
worker time spent waiting for devices (cold starts not hidden by pre-warming), the harness's overhead per step
with model time taken out (observation + execution + the agent's own work, p50/p90), and the peak memory of the
run (device containers from their cgroups, plus the pytest processes).
"""

from __future__ import annotations

import json
import os
import random
import re
import subprocess
import sys
import tempfile
import threading
import time
import uuid
import zlib
from pathlib import Path
from typing import Any

from jarvis_pytest.agents.planner import render_step
from jarvis_pytest.bench.devices import percentile
from jarvis_pytest.llm.fake_server import FakeChatServer, Reply, RecordedRequest
from jarvis_pytest.paths import REPO_ROOT
from jarvis_pytest.results.run_state import resource_id

TASK = "mousepad-write_note"
TEMPLATE = "ubuntu-mousepad-write_note"
CGROUP_MEMORY = Path("/sys/fs/cgroup/memory/docker")  # cgroup v1, cgroupfs driver (Debian's docker.io)


def planner_reply(req: RecordedRequest, latency: float) -> Reply:
    """The scripted plan: the step to take follows from how many steps the prompt's history already lists."""
    prompt = req.text("system")
    history = prompt.rsplit("Current history:", 1)[-1]
    done = len(re.findall(r"^Step \d+ on ubuntu: ", history, flags=re.M))
    note = re.search(r'type the text "(.*)" and save', prompt)
    text = note.group(1) if note else ""
    steps = [render_step("ubuntu", "Click into the editor", {"action": "left_click"}, "the text area of the editor"),
             render_step("ubuntu", "Type the note", {"action": "type", "text": text}),
             render_step("ubuntu", "Save", {"action": "key", "keys": ["ctrl", "s"]}),
             render_step("ubuntu", "Saved", {"action": "terminate", "status": "success"})]
    return Reply(text=steps[min(done, len(steps) - 1)], delay=latency)


class RunMemory:
    """The memory of one run now: its containers on this machine's engine (cgroup usage) and its pytest processes
    (RSS: the process `root`, the run's controller, and every process under it: the xdist workers).

    Sampled every second, it costs the machine it measures little: Docker is asked for the run's containers only
    when a new container shows in the cgroup hierarchy. (Until 2026-11-29 a process was told apart by its command
    line, which matched neither the controller nor an xdist worker: the peak memory counted the containers only.)"""

    def __init__(self, run_id: str, docker: Any):
        self.run_id, self.docker = run_id, docker
        self.root: int | None = None       # the run's controller, once started
        self.seen: set[str] = set()        # container ids seen in the cgroup hierarchy
        self.containers: set[str] = set()  # of which the run's
        self.head = 0.0                    # MB of the run's pytest processes alone, at the last sample

    def _processes(self) -> list[str]:
        """The pids of `root` and every process under it."""
        if self.root is None:
            return []
        children: dict[str, list[str]] = {}
        for pid in os.listdir("/proc"):
            if not pid.isdigit():
                continue
            try:
                stat = Path(f"/proc/{pid}/stat").read_text(errors="replace")
                children.setdefault(stat.rsplit(")", 1)[1].split()[1], []).append(pid)
            except (OSError, IndexError):
                pass
        found, todo = [], [str(self.root)]
        while todo:
            pid = todo.pop()
            found.append(pid)
            todo += children.get(pid, [])
        return found

    def mb(self) -> float:
        total = 0
        try:
            ids = {name for name in os.listdir(CGROUP_MEMORY) if len(name) == 64}
        except OSError:
            ids = None
        if ids is None or ids - self.seen:
            self.containers = {c["Id"] for c in self.docker.api.containers(filters={"label": f"org.jarvis.run="
                                                                                            f"{self.run_id}"})}
            self.seen |= ids or set()
        for cid in self.containers if ids is None else ids & self.containers:
            try:
                total += int((CGROUP_MEMORY / cid / "memory.usage_in_bytes").read_text())
            except (OSError, ValueError):
                pass
        head = 0
        for pid in self._processes():
            try:
                for line in Path(f"/proc/{pid}/status").read_text(errors="replace").splitlines():
                    if line.startswith("VmRSS:"):
                        head += int(line.split()[1]) * 1024
            except (OSError, ValueError):
                pass
        self.head = head / 2**20
        return (total + head) / 2**20


def _busy_cpu_seconds() -> float:
    """CPU time the whole machine spent busy since boot (all cores; idle and I/O wait left out), /proc/stat."""
    fields = [int(v) for v in Path("/proc/stat").read_text().splitlines()[0].split()[1:]]
    user, nice, system, _idle, _iowait, irq, softirq, steal = (fields + [0] * 8)[:8]
    return (user + nice + system + irq + softirq + steal) / os.sysconf("SC_CLK_TCK")


CONTAINERS_CPU = Path("/sys/fs/cgroup/cpuacct/docker/cpuacct.usage")  # cgroup v1, nanoseconds


def _containers_cpu_seconds() -> float | None:
    """CPU time of every container of the local engine so far (cgroup v1 `docker` hierarchy), None elsewhere."""
    try:
        return int(CONTAINERS_CPU.read_text()) / 1e9
    except (OSError, ValueError):
        return None


def speed_reference() -> dict[str, float]:
    """How fast this machine is now: the CPU seconds (best of three) of two fixed pieces of work, a pure-Python
    loop (like the harness and the control servers) and zlib compressing 4 MB (like a PNG screenshot). Printed
    beside the figures, it tells a slow day of a shared VM from a slower harness: the same code on the same kind
    of machine has cost about a quarter more CPU per task from one day to the next. (A third reference, starting
    200 processes, was tried on 2026-11-27 and dropped: it read 0.13 s in runs whose devices cost 2.55 and 2.28
    CPU-s a task, while the loop read 0.230-0.236 and 0.206 s.)"""
    data = random.Random(0).randbytes(1 << 22).translate(bytes(i % 16 for i in range(256)))  # 4 bits a byte

    def best(work) -> float:
        times = []
        for _ in range(3):
            t0 = time.process_time()
            work()
            times.append(time.process_time() - t0)
        return round(min(times), 3)

    return {"python_loop_s": best(lambda: sum(i * i for i in range(2_000_000))),
            "zlib_4mb_s": best(lambda: zlib.compress(data, 6))}


def steady_state(results: list[Any]) -> dict[str, Any]:
    """The rate a long run settles at, read in the window where every worker is past its first task and none
    has finished its last (start-up, collection, first boots and the tail left out): tasks that ended in the
    window per hour, and the share of the workers' time in it spent waiting for devices by tasks that began in
    it. None when no such window exists (a worker ran a single task)."""
    from datetime import datetime

    def ts(iso: str) -> float:
        return datetime.fromisoformat(iso).timestamp()

    done = [(ts(r.started), ts(r.finished), float(r.durations.get("boot", 0.0)), r.worker)
            for r in results if r.finished and r.started and r.worker]
    ends: dict[str, list[float]] = {}
    for _, end, _, worker in done:
        ends.setdefault(worker, []).append(end)
    t1 = max((min(v) for v in ends.values()), default=0.0)
    t2 = min((max(v) for v in ends.values()), default=0.0)
    if min((len(v) for v in ends.values()), default=0) < 2 or t2 <= t1:
        return {"tasks_per_hour": None, "cold_start_share": None, "tasks": 0, "window_s": 0.0}
    window = t2 - t1
    ended = sum(t1 < end <= t2 for _, end, _, _ in done)
    boot = sum(b for start, _, b, _ in done if t1 <= start <= t2)
    return {"tasks_per_hour": round(ended / window * 3600, 1),
            "cold_start_share": round(boot / (window * len(ends)), 3), "tasks": ended, "window_s": round(window, 1)}


def task_library(folder: Path) -> Path:
    """A library of the benchmark's one template (the repository's file, types in force): the run collects its
    N instances only, where `--instances N` over the whole library would make every xdist worker create N × 124
    pytest items to deselect all but N (seconds of CPU per worker that no real run pays)."""
    from jarvis_pytest.tasks.library import load_library

    source = load_library(REPO_ROOT / "tasks").sources[TEMPLATE]
    (folder / "ubuntu").mkdir(parents=True, exist_ok=True)
    (folder / "ubuntu" / source.name).write_bytes(source.read_bytes())
    (folder / "types.json").write_bytes((REPO_ROOT / "tasks" / "types.json").read_bytes())
    return folder


def _children_cpu_seconds() -> float:
    """CPU time (user + system) of this process's waited-for children so far: a benchmark run's pytest processes
    (the controller and its xdist workers), never the devices (containers) nor a Ray node's processes."""
    import resource

    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run_once(workers: int, latency_ms: int, tasks: int, out_root: Path, ray: str | None = None) -> dict[str, Any]:
    """One benchmark run with `workers` xdist workers (with `ray`, its devices on that Ray cluster's nodes); the
    figures of the run."""
    from jarvis_pytest.infra.engine import client
    from jarvis_pytest.report.rollup import load_results

    latency = latency_ms / 1000
    run_dir = out_root / f"throughput-w{workers}{'-ray' if ray else ''}-{uuid.uuid4().hex[:6]}"
    fake = FakeChatServer(models=("planner", "grounder"), record=False)  # holding every request slowed long runs
    fake.respond_with(lambda req: planner_reply(req, latency), model="planner")
    fake.respond_with(lambda req: Reply(text='{"x": 500, "y": 500}', delay=latency), model="grounder")
    docker = client()
    peak = peak_head = 0.0
    stop = threading.Event()

    memory = RunMemory(resource_id(run_dir), docker)

    def sample() -> None:
        nonlocal peak, peak_head
        while not stop.wait(1.0):
            peak = max(peak, memory.mb())
            peak_head = max(peak_head, memory.head)

    with fake, tempfile.TemporaryDirectory(prefix="jarvis-throughput-") as scratch:
        # -p no:hypothesispytest: the project's own tests use Hypothesis, so the development venv has it, and its
        # plugin loads in every pytest process: an 8-worker start-up cost 9.4-10.4 CPU-s with it, 7.8-8.0 without
        # (a run of the benchmark has no use for it, and a plain install of the harness does not have it)
        cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:hypothesispytest", "-q",
               str(REPO_ROOT / "tasks" / "test_atomic.py"),
               "-n", str(workers), "--agent", "holo2", "--planner-base-url", fake.url, "--planner-model", "planner",
               "--grounder-base-url", fake.url, "--grounder-model", "grounder", "-k", TASK,
               "--instances", str(tasks), "--results-dir", str(run_dir), "--step-timeout", str(60 + 4 * latency),
               "--library", str(task_library(Path(scratch))), *(["--ray", ray] if ray else [])]
        sampler = threading.Thread(target=sample, daemon=True)
        sampler.start()
        t0, cpu0, dev0, head0 = time.monotonic(), _busy_cpu_seconds(), _containers_cpu_seconds(), _children_cpu_seconds()
        runner = subprocess.Popen(cmd, cwd=REPO_ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        memory.root = runner.pid
        stdout, _ = runner.communicate()
        proc = subprocess.CompletedProcess(cmd, runner.returncode, stdout, "")
        wall, cpu, dev1 = time.monotonic() - t0, _busy_cpu_seconds() - cpu0, _containers_cpu_seconds()
        head = _children_cpu_seconds() - head0
        stop.set()
    results = load_results(run_dir)[0]
    passed = sum(r.status == "passed" for r in results)
    boot = sum(r.durations.get("boot", 0.0) for r in results)
    overhead = []
    for r in results:
        traj = run_dir / "tasks" / re.sub(r"[^A-Za-z0-9._-]+", "_", r.task_id).strip("_") / "traj.jsonl"
        for line in traj.read_text().splitlines() if traj.exists() else []:
            s = json.loads(line)
            model = float((s.get("extra") or {}).get("model_ms", 0.0))
            overhead.append(s["observe_ms"] + s["exec_ms"] + max(0.0, s["agent_ms"] - model))
    return {"workers": workers, "where": "ray" if ray else "local", "tasks": len(results), "passed": passed,
            "wall_s": round(wall, 1),
            "tasks_per_hour": round(len(results) / wall * 3600, 1) if wall else 0.0,
            "cold_start_share": round(boot / (wall * workers), 3) if wall else 0.0,
            "overhead_ms": {"p50": round(percentile(overhead, 0.5), 1) if overhead else None,
                            "p90": round(percentile(overhead, 0.9), 1) if overhead else None, "steps": len(overhead)},
            "peak_memory_mb": round(peak),  # the run's containers on this machine's engine and its pytest processes
            "peak_head_mb": round(peak_head),  # its pytest processes alone
            "steady": steady_state(results),
            # the machine's busy CPU time per task (devices, harness, the loopback model, start-up) and the
            # tasks/hour at which this machine's cores would be saturated
            "cpu_s_per_task": round(cpu / len(results), 2) if results else None,
            "device_cpu_s_per_task": round((dev1 - dev0) / len(results), 2) if results and dev0 is not None
            and dev1 is not None else None,  # of which the devices and drives (their containers on this engine)
            # the head's own share: the pytest processes (controller, workers: the agent loop, the results, with
            # --ray the Ray driver's side of every device call), from their rusage
            "head_cpu_s_per_task": round(head / len(results), 3) if results else None,
            "cpu_bound_tasks_per_hour": round((os.cpu_count() or 1) * 3600 / (cpu / len(results))) if results and cpu
            else None,
            "exit": proc.returncode, "results": str(run_dir),
            "output_tail": proc.stdout[-600:] if proc.returncode else ""}


# Default tasks per run: 16 for every worker, in every run. Each worker of every run then does the same work, so
# the fixed costs of a worker's timeline (its start, its first boot, which nothing hides, and its last task, which
# has no next task to pre-warm) weigh alike at every worker count, and the speed-up compares like with like. (Until
# 2026-11-27 the default was 12 per worker and at least 24: the 1-worker run then spread its fixed costs over
# twice as many tasks a worker as the 8-worker run.) 16 keeps the whole default bench under 15 minutes here.
PER_WORKER = 16


def tasks_for(workers: int, tasks: int | None) -> int:
    """Tasks in the run with `workers` workers: `tasks` when given, else 16 per worker (each worker runs long
    enough that its steady state can be read past its first task)."""
    return tasks if tasks else PER_WORKER * workers


def measure(worker_counts: list[int], latency_ms: int, tasks: int | None, out_root: Path,
            ray: str | None = None) -> dict[str, Any]:
    """One run per worker count; with `ray`, two per worker count, side by side: devices on this machine's engine,
    then on the Ray cluster's nodes (`ray_overhead_ms`: the Ray run's per-step overhead above the local one's)."""
    before = speed_reference()
    runs = []
    for w in worker_counts:
        runs.append(run_once(w, latency_ms, tasks_for(w, tasks), out_root))
        if ray:
            runs.append(run_once(w, latency_ms, tasks_for(w, tasks), out_root, ray=ray))
            local, remote = runs[-2]["overhead_ms"], runs[-1]["overhead_ms"]
            runs[-1]["ray_overhead_ms"] = {q: round(remote[q] - local[q], 1) if remote[q] is not None and
                                           local[q] is not None else None for q in ("p50", "p90")}
    after = speed_reference()
    speed = {name: [before[name], after[name]] for name in before}
    for where in ("local", "ray"):  # speed-ups against the first run of the same kind
        same = [r for r in runs if r["where"] == where]
        base = same[0]["tasks_per_hour"] if same else 0.0
        steady_base = same[0]["steady"]["tasks_per_hour"] if same else None
        for r in same:
            r["speedup"] = round(r["tasks_per_hour"] / base, 2) if base else None
            rate = r["steady"]["tasks_per_hour"]
            r["steady"]["speedup"] = round(rate / steady_base, 2) if rate and steady_base else None
    # `tasks`: as asked (None: the default per worker count; each run says its own in runs[].tasks)
    # `speed_reference`: each reference's CPU seconds before the first run and after the last
    return {"task": TASK, "latency_ms": latency_ms, "tasks": tasks, "cores": os.cpu_count(),
            "speed_reference": speed, "runs": runs, "ray": ray}


def render(result: dict[str, Any]) -> str:
    count = f"{result['tasks']} × {result['task']} per run" if result["tasks"] else \
        f"{PER_WORKER} × {result['task']} per worker in every run"
    lines = [f"{count}, model latency {result['latency_ms']} ms per call, "
             f"{result['cores']} cores; whole run, then steady state (every worker past its first task, none done)",
             "this machine's speed before / after (CPU s, lower is faster): "
             + ", ".join(f"{name} {a} / {b}" for name, (a, b) in result["speed_reference"].items()),
             f"{'workers':>7} {'tasks/h':>9} {'speed-up':>9} {'cold-start':>11} {'steady/h':>9} {'speed-up':>9} "
             f"{'cold-start':>11} {'overhead p50':>13} {'p90':>7} {'peak MB':>8} {'CPU s/task':>11} {'devices':>8} "
             f"{'head':>6} {'CPU-bound at':>13} {'passed':>7}"]
    for r in result["runs"]:
        o, st = r["overhead_ms"], r["steady"]
        steady = (f"{st['tasks_per_hour']:>9.1f} {st.get('speedup') or 0:>8.2f}× {100 * st['cold_start_share']:>10.1f}%"
                  if st["tasks_per_hour"] else f"{'-':>9} {'-':>9} {'-':>11}")
        lines.append(f"{r['workers']:>7}{'+ray' if r.get('where') == 'ray' else '    '} {r['tasks_per_hour']:>9.1f} {r['speedup'] or 0:>8.2f}× "
                     f"{100 * r['cold_start_share']:>10.1f}% {steady} "
                     f"{o['p50'] or 0:>11.1f} ms {o['p90'] or 0:>4.0f} ms "
                     f"{r['peak_memory_mb']:>8} {r['cpu_s_per_task'] or 0:>11.1f} "
                     f"{r['device_cpu_s_per_task'] if r['device_cpu_s_per_task'] is not None else '-':>8} "
                     f"{r.get('head_cpu_s_per_task') or 0:>6.2f} "
                     f"{r['cpu_bound_tasks_per_hour'] or 0:>9} /h {r['passed']:>3}/{r['tasks']}")
    for r in result["runs"]:
        if r.get("ray_overhead_ms"):
            extra = r["ray_overhead_ms"]
            lines.append(f"through Ray ({result.get('ray')}), {r['workers']} worker(s): per-step overhead "
                         f"{extra['p50']:+.1f} ms at p50, {extra['p90']:+.1f} ms at p90 above the local run; the "
                         f"head spent {r.get('head_cpu_s_per_task') or 0:.2f} CPU-s a task, its pytest processes "
                         f"held {r.get('peak_head_mb') or 0} MB at most")
    lines.append("head: CPU-s a task of the pytest processes alone (controller and workers; devices and Ray nodes "
                 "apart); with +ray the devices ran on the nodes (CPU s/task counts this whole machine)")
    return "\n".join(lines)


def main(args) -> int:
    workers = [int(w) for w in str(args.workers).split(",") if w.strip()]
    if not workers or min(workers) < 1:
        print("jarvis bench throughput: --workers takes counts of 1 or more, e.g. 1,2,4,8", file=sys.stderr)
        return 2
    ray = None
    if getattr(args, "ray", None):
        from jarvis_pytest.cluster.connect import check_address

        ray = check_address(args.ray)
    result = measure(workers, args.latency_ms, args.tasks, Path(args.results or REPO_ROOT / "reports"), ray=ray)
    print(json.dumps(result, indent=2) if args.json else render(result))
    return 0 if all(r["exit"] == 0 for r in result["runs"]) else 1
