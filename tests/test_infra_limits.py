"""Devices are bounded, on real containers: what a task's agent can do as the device's user with sudo — fork
without end, allocate without end, spin every core — stops at its container's limits, inside its container,
while the host and the other containers keep working; removing the device ends it."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.infra.containers import (HOLDER_PIDS_LIMIT, PIDS_ENV, PIDS_LIMIT, cpus_of, device_cpus,
                                            pids_limit)

REPO = Path(__file__).resolve().parents[1]

USER = "user"  # the agent's user on the Ubuntu device (passwordless sudo)


def as_user_with_sudo(container, *command: str, detach: bool = False):
    """Run `command` in `container` as root through the agent's user's sudo (what an agent's script can do)."""
    return container.exec_run(["sudo", "-n", *command], user=USER, detach=detach)


def stats(container) -> dict:
    return container.stats(stream=False, one_shot=True)


def host_processes() -> int:
    return sum(1 for name in os.listdir("/proc") if name.isdigit())


def cpu_seconds(container) -> float:
    return stats(container)["cpu_stats"]["cpu_usage"]["total_usage"] / 1e9


@pytest.fixture
def ubuntu(lifecycle):
    env = lifecycle.boot(("ubuntu",))
    yield env
    env.close()


SMALL_MEMORY, SMALL_CPUS = "1g", 0.25


@pytest.fixture
def small_ubuntu(device_images):
    """An Ubuntu device with --device-memory 1g and --device-cpus 0.25: a hog reaches its limit sooner and takes
    less of the machine, and a quarter core is less than a busy loop gets even on a loaded machine."""
    import uuid

    from jarvis_pytest.infra.cleanup import cleanup
    from jarvis_pytest.environments.lifecycle import Lifecycle, Limits

    run_id = f"test-{uuid.uuid4().hex[:8]}"
    env = Lifecycle(run_id, "test", Limits(memory=SMALL_MEMORY, cpus=SMALL_CPUS)).boot(("ubuntu",))
    yield env
    env.close()
    cleanup(run_id)


# forks up to `n` children that sleep, counts those the kernel allowed, kills them and prints the count
FORKER = """
import os, signal, sys, time
pids = []
for _ in range(int(sys.argv[1])):
    try:
        pid = os.fork()
    except OSError:
        break
    if pid == 0:
        time.sleep(300)
        os._exit(0)
    pids.append(pid)
print(len(pids), flush=True)
for pid in pids:
    os.kill(pid, signal.SIGKILL)
for pid in pids:
    os.waitpid(pid, 0)
"""


@pytest.mark.containers
def test_every_container_is_created_bounded(ubuntu):
    """The device, its port holder and the drive each carry a process limit; the device and the drive a memory
    limit with no swap beyond it; the device the default CPU limit (`device_cpus`: all cores but one, on more
    than two)."""
    config = {role: c.attrs["HostConfig"] for role, c in ubuntu.containers.items()}
    holder = ubuntu.holders["ubuntu"].container
    holder.reload()
    device, drive = config["ubuntu"], config["transfer"]
    assert device["PidsLimit"] == PIDS_LIMIT and drive["PidsLimit"] == PIDS_LIMIT
    assert holder.attrs["HostConfig"]["PidsLimit"] == HOLDER_PIDS_LIMIT
    assert device["Memory"] == 4 * 2**30 and device["MemorySwap"] == device["Memory"]
    assert drive["Memory"] == 512 * 2**20 and drive["MemorySwap"] == drive["Memory"]
    assert device["NanoCpus"] == int(device_cpus(ubuntu.containers["ubuntu"].client) * 1e9)


@pytest.mark.containers
def test_forking_as_root_stops_at_the_process_limit(ubuntu):
    """Bounded, so it can show what happens without the limit too: asked for 300 more processes than the limit,
    the device gets fewer than the limit, and works again once they are gone."""
    device = ubuntu.containers["ubuntu"]
    res = as_user_with_sudo(device, "python3", "-c", FORKER, str(PIDS_LIMIT + 300))
    forked = int(res.output.decode().split()[0])
    assert forked < PIDS_LIMIT, res.output.decode()[-500:]
    assert ubuntu.devices["ubuntu"].run("echo still here").stdout.strip() == "still here"


@pytest.mark.containers
def test_a_fork_bomb_is_bounded_and_removed_with_its_device(ubuntu):
    """`:(){ :|:& };:` as root in the device: its processes stay at the container's limit, the host can still
    start processes and the drive (another container) still runs commands and serves; removing the device ends
    the bomb and gives the host its processes back."""
    device, drive = ubuntu.containers["ubuntu"], ubuntu.containers["transfer"]
    before = host_processes()
    as_user_with_sudo(device, "bash", "-c", ":(){ :|:& };:", detach=True)
    peak_device, peak_host, deadline = 0, 0, time.monotonic() + 60
    while time.monotonic() < deadline:  # until the bomb reaches the limit
        peak_device = max(peak_device, stats(device)["pids_stats"]["current"])
        peak_host = max(peak_host, host_processes())
        if peak_device >= PIDS_LIMIT - 8:
            break
    for _ in range(5):  # and while it pushes against it
        peak_device = max(peak_device, stats(device)["pids_stats"]["current"])
        peak_host = max(peak_host, host_processes())
        assert subprocess.run(["true"], timeout=10).returncode == 0  # the host can fork
        assert drive.exec_run(["true"]).exit_code == 0             # another container can
        ubuntu.transfer.wait_ready(10)                               # and serves
        time.sleep(1)
    print(f"fork bomb: device peak {peak_device} processes (limit {PIDS_LIMIT}); host {before} before, "
          f"peak {peak_host}")
    assert PIDS_LIMIT - 8 <= peak_device <= PIDS_LIMIT
    assert peak_host <= before + PIDS_LIMIT + 200  # other processes of the machine come and go meanwhile
    t0 = time.monotonic()
    ubuntu.close()
    print(f"fork bomb: device removed in {time.monotonic() - t0:.1f} s; host {host_processes()} processes after")
    assert host_processes() <= before + 200


@pytest.mark.containers
def test_a_memory_hog_is_killed_inside_its_container(small_ubuntu):
    """Root in the device allocates (and touches) 256 MB at a time, up to 1 GB past the device's limit (bounded,
    so it can show what happens without the limit too): the kernel kills it in its container, the device and
    its control server keep working."""
    ubuntu = small_ubuntu
    device = ubuntu.containers["ubuntu"]
    limit = device.attrs["HostConfig"]["Memory"]
    assert limit == 2**30 and device.attrs["HostConfig"]["MemorySwap"] == limit
    hog = ("import sys\nchunks = []\n"
           "while len(chunks) * 2**28 < int(sys.argv[1]):\n    chunks.append(bytearray(b'x') * 2**28)\n"
           "print('survived', flush=True)\n")
    available = _available_mb()
    res = as_user_with_sudo(device, "python3", "-c", hog, str(limit + 2**30))
    assert res.exit_code == 137 and b"survived" not in res.output, (res.exit_code, res.output[-300:])
    device.reload()
    assert device.status == "running"
    assert ubuntu.devices["ubuntu"].run("echo still here").stdout.strip() == "still here"
    print(f"memory hog: killed at the device's limit of {limit / 2**20:.0f} MB; host had {available:.0f} MB "
          f"available before, {_available_mb():.0f} MB after")


@pytest.mark.containers
def test_a_device_that_spins_every_core_gets_no_more_than_its_limit(small_ubuntu):
    """Root in the device runs two busy loops per core for a few seconds: the kernel holds the device to its CPU
    limit (the default is checked above; a quarter core here, which a busy loop exceeds even on a loaded
    machine)."""
    device = small_ubuntu.containers["ubuntu"]
    loops = 2 * (os.cpu_count() or 1)
    spin = f"for i in $(seq {loops}); do timeout 12 sh -c 'while :; do :; done' & done; wait"
    as_user_with_sudo(device, "sh", "-c", spin, detach=True)
    time.sleep(3)  # the loops run
    c0, t0 = cpu_seconds(device), time.monotonic()
    time.sleep(5)
    rate = (cpu_seconds(device) - c0) / (time.monotonic() - t0)
    throttled = stats(device)["cpu_stats"]["throttling_data"]["throttled_periods"]
    print(f"CPU hog: the device used {rate:.2f} cores (limit {SMALL_CPUS:g} of {os.cpu_count()}); throttled in "
          f"{throttled} periods")
    assert rate <= SMALL_CPUS * 1.2 and throttled > 0


def _available_mb() -> float:
    from jarvis_pytest.environments.pool import available_memory_mb

    return available_memory_mb() or 0.0


def test_the_process_limit_is_overridable_and_checked_at_start_up(tmp_path):
    assert pids_limit({}) == PIDS_LIMIT and pids_limit({PIDS_ENV: "4096"}) == 4096
    assert pids_limit({PIDS_ENV: "none"}) is None
    for bad in ("0", "-5", "lots", "1e3"):
        with pytest.raises(ConfigError, match=PIDS_ENV):
            pids_limit({PIDS_ENV: bad})
    proc = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist", "tasks",
                           "--agent", "noop", "-k", "thunar-rename_file and seed0", "--results-dir",
                           str(tmp_path / "run")], cwd=REPO,
                          capture_output=True, text=True, timeout=120, env={**os.environ, PIDS_ENV: "lots"})
    out = proc.stdout + proc.stderr
    assert proc.returncode == 4 and PIDS_ENV in out and "Traceback" not in out, out[-2000:]
    assert not (tmp_path / "run" / "tasks").exists()


@pytest.mark.parametrize("cores, limit", [(1, 1.0), (2, 2.0), (3, 2.0), (4, 3.0), (64, 63.0)])
def test_the_default_cpu_limit_leaves_a_core_where_there_are_more_than_two(cores, limit):
    assert cpus_of(cores) == limit
