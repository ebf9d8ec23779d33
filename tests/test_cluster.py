"""Task environments on a Ray cluster (`--ray`, `jarvis_pytest/cluster/`).

The container tests run a real cluster on this machine: a head and two nodes started with `ray start`
(`cluster/local.py`), each node on its own Docker engine (extra engines 3 and 4, started here; the first run on a
machine copies the images to them through Ray), declaring 3 device slots each so that four workers need both. A
sample of Ubuntu, Wine and composed tasks runs on it with `-n 4` and again on this machine's engine: the same
summary. A node whose raylet is killed mid-task ends that task as an infrastructure error, the run goes on on the
other node, `--resume` runs it again there, and `jarvis cleanup` removes its devices once the node is back."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from jarvis_pytest.results.run_state import resource_id

REPO = Path(__file__).resolve().parents[1]
PORT = 26479          # not Ray's default nor `jarvis cluster start`'s: a cluster of the user's is left alone
ENGINES = (3, 4)      # extra engines of the nodes (2 is test_engines.py's)
SLOTS = 3
SAMPLE = ["-k", "(mousepad-write_note or thunar-rename_file or windows-cmd-copy_tree or windows-cmd-list_files) "
          "and seed0 or md-0105 or mi-0055", "--instances", "1"]
LOSS_SAMPLE = ["-k", "(mousepad-write_note or thunar-rename_file or terminal-count_matches or terminal-zip_folder "
               "or windows-cmd-copy_tree or windows-cmd-list_files) and seed0", "--instances", "1"]


def bench(*args: str, env: dict[str, str] | None = None, timeout: float = 1200) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", str(REPO / "tasks"), *args],
                          cwd=REPO, capture_output=True, text=True, timeout=timeout, env={**os.environ, **(env or {})})


def results(run: Path) -> dict[str, dict]:
    return {r["task_id"]: r for r in (json.loads(p.read_text()) for p in run.glob("tasks/*/result.json"))}


def leftovers(engine: str | None, run: Path) -> list[str]:
    from jarvis_pytest.infra.engine import client

    api = client(host=engine).api
    label = {"label": f"org.jarvis.run={resource_id(run)}"}
    return ([c["Names"][0] for c in api.containers(all=True, filters=label)]
            + [n["Name"] for n in api.networks(filters=label)])


# -- without a cluster ---------------------------------------------------------------------------------------------
def test_addresses_and_the_project_setting(tmp_path):
    from jarvis_pytest.cluster.connect import check_address, configured
    from jarvis_pytest.errors import ConfigError

    assert check_address(" 127.0.0.1:6379 ") == "127.0.0.1:6379"
    for bad in ("127.0.0.1", "ray://127.0.0.1:10001", "127.0.0.1:0", "host:99999"):
        with pytest.raises(ConfigError, match="--ray.*is not the address of a Ray cluster"):
            check_address(bad)
    assert configured(None, tmp_path) is None
    (tmp_path / "pyproject.toml").write_text('[tool.jarvis]\nray = "10.0.0.5:6379"\n')
    assert configured(None, tmp_path) == "10.0.0.5:6379" and configured("127.0.0.1:1234", tmp_path) == "127.0.0.1:1234"
    (tmp_path / "pyproject.toml").write_text('[tool.jarvis]\nray = 6379\n')
    with pytest.raises(ConfigError, match="tool.jarvis.ray"):
        configured(None, tmp_path)


def test_without_ray_nothing_imports_it():
    """The plugin, the task engine and the command line load without Ray, and a run without --ray never imports it
    (Ray is an optional extra)."""
    code = ("import sys, pytest; import jarvis_pytest.cli, jarvis_pytest.plugin.session, jarvis_pytest.harness.runner,"
            " jarvis_pytest.cluster.connect, jarvis_pytest.cluster.environments, jarvis_pytest.bench.throughput; "
            "rc = pytest.main(['-q', '-p', 'no:cacheprovider', '--collect-only', 'tasks', '--agent', 'noop', "
            "'-k', 'mousepad-write_note']); print('RAY', 'ray' in sys.modules)")
    proc = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert proc.stdout.strip().endswith("RAY False"), proc.stdout[-2000:] + proc.stderr[-2000:]


def test_bad_cluster_options_are_one_clear_error(tmp_path):
    both = bench("--agent", "noop", "--results-dir", str(tmp_path / "a"), "--ray", "127.0.0.1:6379",
                 "--docker-host", "unix:///var/run/docker.sock", "-k", "mousepad-write_note", timeout=300)
    assert both.returncode == 4 and "--ray and --docker-host" in both.stderr and "Traceback" not in both.stderr, \
        both.stderr
    nobody = bench("--agent", "noop", "--results-dir", str(tmp_path / "b"), "--ray", "127.0.0.1:1",
                   "-k", "mousepad-write_note", timeout=300)
    assert nobody.returncode == 4 and "--ray 127.0.0.1:1: no Ray head answers there" in nobody.stderr \
        and "Traceback" not in nobody.stderr, nobody.stderr


def test_what_crosses_to_the_head_keeps_its_type():
    """A device's error comes back raised with its own type (a device fault reruns the task, an infrastructure
    error is counted apart); one that cannot be pickled becomes an InfrastructureError naming it."""
    from jarvis_pytest.cluster.node import outcome, shape
    from jarvis_pytest.errors import DeviceFault, InfrastructureError

    class NeedsTwo(Exception):
        def __init__(self, a, b):
            super().__init__(f"{a} {b}")

    def fail(exc):
        raise exc

    assert outcome(lambda: 42) == ("ok", 42)
    kind, exc = outcome(fail, DeviceFault("wine could not start cmd"))
    assert kind == "raised" and type(exc) is DeviceFault and str(exc) == "wine could not start cmd"
    kind, exc = outcome(fail, NeedsTwo("a", "b"))
    assert kind == "raised" and type(exc) is InfrastructureError and "NeedsTwo: a b" in str(exc)

    class Device:
        platform = "ubuntu"
        names_windows = True

        @property
        def size(self):
            raise AssertionError("a property is not run to learn the shape")

        def observe(self):
            return None

    assert shape(Device()) == {"platform": "attribute", "names_windows": "attribute", "size": "attribute",
                               "observe": "method"}


def test_the_room_a_task_asks_of_a_node():
    """One device slot per device, the memory its devices and drive hold once booted, `kvm` for KVM guests."""
    from types import SimpleNamespace

    from jarvis_pytest.cluster.environments import ClusterEnvironments, needs_kvm
    from jarvis_pytest.devices.backend import Backends, backends_of

    assert needs_kvm(backends_of("android")["emulator"]) and needs_kvm(backends_of("windows")["kvm"])
    assert not needs_kvm(backends_of("windows")["wine"]) and not needs_kvm(backends_of("ubuntu")["docker"])
    chosen = {"ubuntu": backends_of("ubuntu")["docker"], "windows": backends_of("windows")["wine"],
              "android": backends_of("android")["emulator"]}
    pool = SimpleNamespace(backends=Backends(chosen), settings={"transfer": None})
    room = ClusterEnvironments.room(pool, ("ubuntu", "windows"))
    memory = chosen["ubuntu"].booted_memory_mb + chosen["windows"].booted_memory_mb
    assert room["jarvis_device_slots"] == 2 and "kvm" not in room and room["memory"] > memory * 2**20
    assert ClusterEnvironments.room(pool, ("android", "ubuntu"))["kvm"] == 1


# -- on a real cluster ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def cluster(device_images):
    """A head and two nodes of this machine (`ray start`), each on its own extra engine, stopped after the module
    (the engines too, where this module started them: their images stay in their data roots)."""
    from jarvis_pytest.cluster import local
    from jarvis_pytest.infra.engine import _ping, extra_engine_url, stop_extra_engine

    running = [i for i in ENGINES if _ping(extra_engine_url(i))]
    started = time.monotonic()
    made = local.start(nodes=len(ENGINES), slots=SLOTS, port=PORT, first_engine=ENGINES[0])
    print(f"cluster up in {time.monotonic() - started:.1f} s", file=sys.stderr)
    try:
        yield made
    finally:
        local.stop(made)
        for i in ENGINES:
            if i not in running:
                stop_extra_engine(i)


@pytest.mark.containers
def test_a_cluster_of_two_nodes_runs_a_sample_as_here_and_outlives_a_lost_node(cluster, tmp_path):
    """One test (xdist would give two tests of the module to two workers, each starting the cluster): the sample,
    then the node loss on the same cluster."""
    status = subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "cluster", "status", "--ray", cluster.address],
                            cwd=REPO, capture_output=True, text=True, timeout=120)
    assert status.returncode == 0 and f"{cluster.address}: 2 node(s) offering devices" in status.stdout, \
        status.stdout + status.stderr
    assert all(f"{node[:12]} " in status.stdout for node in cluster.nodes) and f"{SLOTS} device slots" in status.stdout
    started = time.monotonic()
    sample_runs_on_two_nodes_as_it_runs_here(cluster, tmp_path)
    print(f"sample on the cluster and here: {time.monotonic() - started:.1f} s", file=sys.stderr)
    started = time.monotonic()
    a_lost_node_is_an_infrastructure_error_the_run_survives(cluster, tmp_path)
    print(f"node loss, resume, cleanup: {time.monotonic() - started:.1f} s", file=sys.stderr)


def sample_runs_on_two_nodes_as_it_runs_here(cluster, tmp_path):
    ray_run, here_run = tmp_path / "ray", tmp_path / "here"
    proc = bench("--agent", "oracle", "-n", "4", "--results-dir", str(ray_run), "--ray", cluster.address, *SAMPLE)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-3000:]
    found = results(ray_run)
    assert len(found) == 6 and all(r["status"] == "passed" for r in found.values()), \
        {t: r["error"] for t, r in found.items()}
    nodes = {r["node"].split()[0] for r in found.values()}
    assert nodes == set(cluster.nodes), (nodes, cluster.nodes)  # four workers with three slots a node: both nodes
    assert all(r["engine"] == cluster.nodes[r["node"].split()[0]] for r in found.values())
    assert {r["platforms"][0] for r in found.values()} >= {"ubuntu", "windows"}
    meta = json.loads((ray_run / "run.json").read_text())
    assert meta["ray"]["address"] == cluster.address and {n["node"] for n in meta["ray"]["nodes"]} == set(cluster.nodes)
    assert all(leftovers(engine, ray_run) == [] for engine in cluster.nodes.values())

    proc = bench("--agent", "oracle", "-n", "4", "--results-dir", str(here_run), *SAMPLE)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-3000:]

    def counts(run: Path) -> dict:
        summary = json.loads((run / "summary.json").read_text())
        return {k: v for k, v in summary.items() if k not in ("timing",)}

    assert counts(ray_run) == counts(here_run)
    assert {t: r["status"] for t, r in results(here_run).items()} == {t: r["status"] for t, r in found.items()}


def a_lost_node_is_an_infrastructure_error_the_run_survives(cluster, tmp_path):
    """The raylet of the node running a task's devices is killed while the agent thinks (a slow agent: 8 s a
    step): that task errors (never fails), the other tasks finish on the other node, nothing of the run stays
    there; `--resume` runs the lost task again on the node left; once the node is back (a new raylet on its
    engine), `jarvis cleanup --run` removes what the lost task left on its engine."""
    from jarvis_pytest.cluster import local
    from jarvis_pytest.infra.engine import client

    run = tmp_path / "run"
    victim, survivor = sorted(cluster.nodes)
    victim_engine, survivor_engine = cluster.nodes[victim], cluster.nodes[survivor]
    args = ["--agent", "slow_agent:SlowAgent", "--agent-option", "seconds=8", "-n", "2", "--results-dir", str(run),
            "--ray", cluster.address, *LOSS_SAMPLE]
    env = {**os.environ, "PYTHONPATH": str(REPO / "tests" / "data" / "agents")}
    proc = subprocess.Popen([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", str(REPO / "tasks"), *args],
                            cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    docker = client(host=victim_engine)
    deadline = time.monotonic() + 300
    while not docker.containers.list(filters={"label": ["org.jarvis.role=device", f"org.jarvis.run={resource_id(run)}"]}):
        assert time.monotonic() < deadline and proc.poll() is None, "no task's devices came to the node to lose"
        time.sleep(0.3)
    time.sleep(2)  # the task's agent is thinking
    local.kill_node(victim)
    out = proc.communicate(timeout=900)[0]
    found = results(run)
    lost = {t for t, r in found.items() if r["status"] == "error"}
    assert len(found) == 6 and lost, out[-4000:]
    assert all(found[t]["node"].startswith(victim) and "was lost" in found[t]["error"] for t in lost), \
        {t: (found[t]["node"], found[t]["error"]) for t in lost}
    assert all(r["status"] == "failed" for t, r in found.items() if t not in lost)  # the agent did nothing
    assert any(r["node"].startswith(survivor) for t, r in found.items() if t not in lost)
    assert proc.returncode != 0  # errors are not a clean run
    assert leftovers(survivor_engine, run) == []

    again = bench(*args, "--resume", str(run), env={"PYTHONPATH": env["PYTHONPATH"]})
    assert "no Ray head answers" not in again.stderr
    rerun = results(run)
    assert all(rerun[t]["status"] == "failed" and rerun[t]["node"].startswith(survivor) for t in lost), \
        {t: (rerun[t]["status"], rerun[t]["node"], rerun[t]["error"]) for t in lost}
    assert leftovers(survivor_engine, run) == []

    assert leftovers(victim_engine, run)  # the lost node's devices: its engine outlived its raylet
    local.add_node(cluster, victim_engine, SLOTS)  # the node is back (a new raylet, a new node id)
    done = subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "cleanup", "--run", str(run)], cwd=REPO,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0 and "Ray cluster" in done.stdout, done.stdout + done.stderr
    assert leftovers(victim_engine, run) == []
