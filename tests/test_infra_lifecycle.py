"""Task environments on real containers: the transfer drive across devices, loopback-only ports, readiness
failures with logs, the pre-warm pool, and cleanup after a killed run."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import uuid

import docker
import httpx
import pytest

from jarvis_pytest.devices.backend import Backend, register_backend
from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.infra.cleanup import cleanup
from jarvis_pytest.infra.lifecycle import LABEL_RUN, Lifecycle, Limits
from jarvis_pytest.infra.pool import Pool

pytestmark = pytest.mark.containers


def leftovers(run_id: str) -> list[str]:
    d = docker.from_env()
    label = {"label": f"{LABEL_RUN}={run_id}"}
    return ([c.name for c in d.containers.list(all=True, filters=label)]
            + [n.name for n in d.networks.list(filters=label)] + [v.name for v in d.volumes.list(filters=label)])


def test_transfer_drive_between_devices_and_host(ubuntu_env, device_images):
    device = ubuntu_env.devices["ubuntu"]
    put = device.run("printf 'made on ubuntu' > /tmp/a.txt && curl -s -o /dev/null -w '%{http_code}' -T /tmp/a.txt "
                     "-H 'PW: agentPassword' http://transfer:5244/shared/a.txt")
    assert put.stdout == "201", put
    assert ubuntu_env.transfer.walk() == ["/shared/a.txt"]  # the empty /data folder holds no file
    assert ubuntu_env.transfer.list("/") == (["data", "shared"], [])
    assert ubuntu_env.transfer.download("/shared/a.txt") == b"made on ubuntu"
    # a second device on the task's network downloads it through the drive's HTTP interface
    other = docker.from_env().containers.run(device_images["ubuntu"], ["bash", "-c", "sleep 60"], detach=True,
                                             network=ubuntu_env.network.name, labels={"org.jarvis.test": "1"})
    try:
        got = other.exec_run(["curl", "-s", "-H", "PW: agentPassword", "http://transfer:5244/shared/a.txt"])
        assert got.output == b"made on ubuntu"
        ubuntu_env.transfer.upload("/from_host/b.txt", b"made on the host")
        got = other.exec_run(["curl", "-s", "-u", "agent:agentPassword", "http://transfer:5244/from_host/b.txt"])
        assert got.output == b"made on the host"
    finally:
        other.remove(force=True)
    ubuntu_env.transfer.delete("/from_host/b.txt")
    assert ubuntu_env.transfer.walk() == ["/shared/a.txt"]


def test_drive_needs_the_password(ubuntu_env):
    url = ubuntu_env.urls["transfer"]
    assert httpx.put(f"{url}/x.txt", content=b"x", headers={"PW": "wrong"}).status_code == 403
    assert httpx.put(f"{url}/x.txt", content=b"x").status_code in (401, 403)
    for _ in range(12):  # no ban after many failed logins (agents mistype)
        httpx.get(f"{url}/?ls", headers={"PW": "wrong"})
    assert httpx.get(f"{url}/?ls", headers={"PW": "agentPassword"}).status_code == 200


def test_ports_are_published_on_loopback_only(ubuntu_env):
    for c in ubuntu_env.containers.values():
        c.reload()
        bindings = [b for bs in c.attrs["NetworkSettings"]["Ports"].values() if bs for b in bs]
        assert bindings and all(b["HostIp"] == "127.0.0.1" for b in bindings), bindings
        assert c.labels[LABEL_RUN] and c.labels["org.jarvis.worker"] == "test"


def test_a_device_that_never_gets_ready_fails_with_its_logs(lifecycle):
    def never(url: str, timeout: float) -> None:
        time.sleep(timeout)
        raise InfrastructureError(f"device at {url} not ready after {timeout} s")

    register_backend(Backend(platform="never", image="transfer", port=5244, connect=lambda url: None,
                             wait_ready=never, container_options={
                                 "command": ["bash", "-c", "echo 'device says: cannot start'; sleep 60"]}))
    lc = Lifecycle(lifecycle.run_id, "test", Limits(ready_timeout=2))
    t0 = time.monotonic()
    with pytest.raises(InfrastructureError) as err:
        lc.boot(("never",))
    assert time.monotonic() - t0 < 30
    assert "not ready" in str(err.value) and "--- logs of" in str(err.value)
    assert "device says: cannot start" in str(err.value)
    assert leftovers(lifecycle.run_id) == []  # a failed boot removes what it made


def test_pool_prewarm_and_close(lifecycle):
    pool = Pool(lifecycle)
    t0 = time.monotonic()
    cold = lifecycle.boot(("ubuntu",))
    cold_s = time.monotonic() - t0
    cold.close()
    pool.prewarm(("ubuntu",))
    time.sleep(cold_s + 1)
    t0 = time.monotonic()
    env = pool.acquire(("ubuntu",))
    warm_s = time.monotonic() - t0
    print(f"cold boot {cold_s:.2f} s, acquire after pre-warm {warm_s * 1000:.1f} ms")
    assert env.devices["ubuntu"].health().desktop
    env.close()
    pool.prewarm(("ubuntu",))  # never acquired: close must remove it
    pool.close()
    assert leftovers(lifecycle.run_id) == []


BOOT_AND_HANG = """
import sys, time
from jarvis_pytest.infra.lifecycle import Lifecycle
Lifecycle(sys.argv[1], "gw9").boot(("ubuntu",))
print("booted", flush=True)
time.sleep(600)
"""


def test_cleanup_after_the_run_is_killed(device_images):
    run_id = f"test-kill-{uuid.uuid4().hex[:6]}"
    proc = subprocess.Popen([sys.executable, "-c", BOOT_AND_HANG, run_id], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "booted"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(10)
        assert len(leftovers(run_id)) == 3  # ubuntu, transfer, network: a kill leaves them
        out = subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "cleanup", "--run", run_id],
                             capture_output=True, text=True, check=True).stdout
        assert "2 containers, 1 networks" in out
        assert leftovers(run_id) == []
    finally:
        proc.kill()
        cleanup(run_id)
