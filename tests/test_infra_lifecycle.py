"""Task environments on real containers: loopback-only ports, labels and limits, readiness failures with logs,
the pre-warm pool, and cleanup after a killed run."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import uuid
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import docker
import pytest
from conftest import standin_backend, within_rules

from jarvis_pytest.devices.backend import Backend, register_backend
from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.environments import lifecycle as lifecycle_module
from jarvis_pytest.infra.cleanup import cleanup, orphan_sweep
from jarvis_pytest.infra.containers import (LABEL_HOST, LABEL_PID, LABEL_PLATFORM, LABEL_ROLE, LABEL_RUN,
                                            LABEL_WORKER, BootPriority)
from jarvis_pytest.infra.containers import labels as ctr_labels
from jarvis_pytest.environments.lifecycle import Lifecycle, Limits
from jarvis_pytest.infra.networks import attached
from jarvis_pytest.environments.pool import Pool, available_memory_mb

pytestmark = pytest.mark.containers


def leftovers(run_id: str) -> list[str]:
    d = docker.from_env()
    label = {"label": f"{LABEL_RUN}={run_id}"}
    return sorted([c.name for c in d.containers.list(all=True, filters=label)]
                  + [n.name for n in d.networks.list(filters=label)] + [v.name for v in d.volumes.list(filters=label)])


def bindings(container) -> list[dict]:
    container.reload()
    return [b for bs in container.attrs["NetworkSettings"]["Ports"].values() if bs for b in bs]


def never_ready(url: str, timeout: float) -> None:
    """A backend's `wait_ready` whose control server never answers."""
    time.sleep(timeout)
    raise InfrastructureError(f"control server at {url} does not answer")


def test_ports_labels_limits_and_network(standin_platforms, device_images):
    run_id = f"test-{uuid.uuid4().hex[:8]}"
    env = Lifecycle(run_id, "gw3", Limits(memory="300m", cpus=0.5)).boot(standin_platforms)
    try:
        assert sorted(env.containers) == sorted([*standin_platforms, "transfer"])
        for role, c in env.containers.items():
            bs = bindings(c)
            assert bs and all(b["HostIp"] == "127.0.0.1" for b in bs), bs  # never 0.0.0.0 or ::
            assert c.labels[LABEL_RUN] == run_id and c.labels[LABEL_WORKER] == "gw3"
            assert c.labels[LABEL_ROLE] == ("transfer" if role == "transfer" else "device")
            assert c.labels[LABEL_PLATFORM] == ("" if role == "transfer" else role)
            assert c.labels[LABEL_PID] == str(os.getpid()) and c.labels[LABEL_HOST]
            assert set(c.attrs["NetworkSettings"]["Networks"]) == {env.network.name}  # the task's network only
            assert env.image_ids[role] == c.attrs["Image"]
            assert env.urls[role].startswith("http://127.0.0.1:")
            if role != "transfer":
                assert c.attrs["HostConfig"]["Memory"] == 300 * 2**20
                assert c.attrs["HostConfig"]["NanoCpus"] == 500_000_000
        assert env.network.attrs["Labels"][LABEL_RUN] == run_id
        transfer = env.containers["transfer"]
        assert "transfer" in transfer.attrs["NetworkSettings"]["Networks"][env.network.name]["Aliases"]
        assert env.run_id == run_id and "jarvis cleanup --run" in env.describe()
    finally:
        env.close()
    env.close()  # idempotent
    assert leftovers(run_id) == []


def test_names_are_unique_per_lifecycle_of_one_run_and_worker(standin_platforms, lifecycle):
    twins = [Lifecycle(lifecycle.run_id, "gw0") for _ in range(2)]
    with ThreadPoolExecutor(2) as ex:
        envs = list(ex.map(lambda lc: lc.boot(standin_platforms[:1]), twins))
    names = [c.name for e in envs for c in e.containers.values()] + [e.network.name for e in envs]
    assert len(set(names)) == len(names) == 6
    for e in envs:
        e.close()
    assert leftovers(lifecycle.run_id) == []


def test_a_kept_network_is_reused_only_once_no_container_is_on_it(standin_platforms, lifecycle):
    lc = Lifecycle(lifecycle.run_id, "gw2", keep_networks=1)
    first = lc.boot(standin_platforms[:1])
    second = lc.boot(standin_platforms[:1])  # while the first still runs: a network of its own
    assert second.network.name != first.network.name
    first_drive = first.containers["transfer"]
    first.close()
    assert leftovers(lc.run_id) == sorted([*(c.name for c in second.containers.values()), second.network.name,
                                           first.network.name, first_drive.name])  # kept, with its rule and drive
    assert within_rules(first.network.name) == 1
    second.close()  # one is kept already: this one goes, its drive, then its rule, then its bridge
    assert leftovers(lc.run_id) == sorted([first.network.name, first_drive.name])
    assert within_rules(second.network.name) == 0
    third = lc.boot(standin_platforms[:1])
    assert third.network.name == first.network.name and lc.networks.created == 2
    assert third.containers["transfer"].id == first_drive.id  # renewed, not made again
    assert attached(third.network) == sorted(c.name for c in third.containers.values())
    third.close()
    stray = docker.from_env().containers.run(  # something still on the kept network: it must not be reused
        "jarvis/transfer", ["sleep", "600"], name=f"{lc.run_id}-stray", network=third.network.name, detach=True,
        labels={LABEL_RUN: lc.run_id})
    fourth = lc.boot(standin_platforms[:1])  # the kept drive is removed, the stray and its network left alone
    assert fourth.network.name not in (first.network.name, second.network.name) and lc.networks.created == 3
    assert first_drive.name not in leftovers(lc.run_id)
    fourth.close()
    lc.close()  # removes the network it kept (the fourth's) and its drive; the stray's is not the lifecycle's
    assert leftovers(lc.run_id) == sorted([stray.name, third.network.name])
    assert within_rules(fourth.network.name) == 0


def drive_files(container) -> list[str]:
    """Everything under the drive's root inside its container, with the mode and owner of /data."""
    out = container.exec_run(["sh", "-c", "cd /srv/drive && find . | sort; stat -c '%a %U' data"]).output
    return out.decode().splitlines()


def compiled_templates(container) -> list[str]:
    """The drive's cache of compiled page templates: each entry's name and modification time (`drive.py`)."""
    out = container.exec_run(["find", "/var/cache/jarvis-drive/templates", "-type", "f", "-printf", "%f %T@\\n"])
    return sorted(out.output.decode().split("\n")[:-1]) if out.exit_code == 0 else []


def drive_generation(container) -> int:
    """How many servers the drive's PID 1 has started (`drive.py`)."""
    return int(container.exec_run(["cat", "/run/jarvis-drive"]).output.split()[0])


def test_a_kept_drive_is_renewed_wiped_and_checked_empty(standin_platforms, lifecycle, capfd, monkeypatch):
    import dataclasses

    lc = Lifecycle(lifecycle.run_id, "gw3", keep_networks=1)
    fresh = lc.boot(standin_platforms[:1])
    drive = fresh.containers["transfer"]
    assert drive_files(drive) == [".", "./data", "755 root"] and drive_generation(drive) == 1
    # what a task may leave: files and folders in /data and at the root, a hidden file, a login session, the
    # state of an unfinished upload (copyparty's history folder)
    for path in ("/data/report.xlsx", "/data/sub/deep.txt", "/top.txt", "/.hidden"):
        fresh.transfer.upload(path, b"left by the last task")
    fresh.transfer.mkdir("/data/empty-folder")
    assert drive.exec_run(["sh", "-c", "mkdir -p /root/.config/copyparty && touch /root/.config/copyparty/x.db "
                           "/var/lib/copyparty/up2k.snap"]).exit_code == 0
    url = fresh.urls["transfer"]
    compiled = compiled_templates(drive)
    # copyparty's page templates, compiled into the image (`drive.py warm`): the first server loaded them and
    # wrote none (none is newer than the file Docker made as it created the container)
    written = drive.exec_run(["find", "/var/cache/jarvis-drive/templates", "-type", "f", "-newer", "/.dockerenv"])
    assert len(compiled) >= 10 and written.exit_code == 0 and written.output == b"", (compiled, written.output)
    fresh.close()
    renewed = lc.boot(standin_platforms[:1])
    assert renewed.containers["transfer"].id == drive.id and renewed.urls["transfer"] == url
    assert renewed.transfer.walk("/") == [] and renewed.transfer.list("/") == (["data"], [])
    assert drive_files(drive) == [".", "./data", "755 root"] and drive_generation(drive) == 2
    assert drive.exec_run(["ls", "/root/.config/copyparty/x.db"]).exit_code != 0
    assert drive.exec_run(["ls", "/var/lib/copyparty/up2k.snap"]).exit_code != 0
    # a device of the new task reaches it by its name on the network
    device = renewed.containers[standin_platforms[0]]
    probe = device.exec_run(["curl", "-s", "-o", "/dev/null", "-w", "%{http_code}", "-H", "PW: agentPassword",
                             "http://transfer:5244/data/?ls"])
    assert probe.output == b"200"
    # the renewed server loaded the compiled templates (none written again) and renders pages from them
    assert compiled_templates(drive) == compiled
    page = device.exec_run(["curl", "-s", "-A", "Mozilla/5.0", "http://transfer:5244/"]).output.decode()
    assert 'name="cppwd"' in page, page[:300]  # the login page, from the cached code of a template
    renewed.transfer.upload("/data/mine.txt", b"x")
    renewed.close()

    # the checks can fail. A signal the drive does not renew on: no next generation, so the kept drive (with the
    # file) is replaced by a new one, and that is said
    renew_signal = lc.server.renew_signal
    lc.server = dataclasses.replace(lc.server, renew_signal="SIGCONT")
    monkeypatch.setattr(lifecycle_module, "RENEW_TIMEOUT", 1.0)
    capfd.readouterr()
    replaced = lc.boot(standin_platforms[:1])
    assert replaced.containers["transfer"].id != drive.id and replaced.transfer.walk("/") == []
    assert f"kept drive {drive.name}: renewal failed: no new server within 1 s of SIGCONT (still generation 2)" \
        in capfd.readouterr().err
    replaced.transfer.upload("/data/mine.txt", b"x")
    replaced.close()
    # and were the generation check fooled, the emptiness check is not: the old server's file fails the boot, which
    # leaves nothing
    counts = iter(range(100))
    monkeypatch.setattr(lifecycle_module, "served_generation", lambda container: next(counts))
    with pytest.raises(InfrastructureError, match=r"is not empty: .*mine.txt"):
        lc.boot(standin_platforms[:1])
    assert leftovers(lc.run_id) == []
    monkeypatch.undo()

    # a drive whose server ended by itself is not started again (it exits as copyparty did) and is replaced
    lc.server = dataclasses.replace(lc.server, renew_signal=renew_signal)
    third = lc.boot(standin_platforms[:1])
    crashed = third.containers["transfer"]
    crashed.exec_run(["sh", "-c", "read -r g p </run/jarvis-drive; kill -KILL $p"])
    assert crashed.wait(timeout=10)["StatusCode"] == 137
    third.close()
    capfd.readouterr()
    fourth = lc.boot(standin_platforms[:1])
    assert fourth.containers["transfer"].id != crashed.id and fourth.transfer.walk("/") == []
    assert f"kept drive {crashed.name}: its server ended by itself (exit code 137)" in capfd.readouterr().err
    fourth.close()
    lc.close()
    assert leftovers(lc.run_id) == []


def test_a_kept_drive_volume_goes_only_to_a_task_whose_device_mounts_it(standin_platforms, lifecycle):
    """A drive whose storage is a volume (mounted by a device, as Windows mounts S:) is renewed for a task whose
    device mounts it again, and that device sees the wiped drive; a task whose devices mount nothing takes a kept
    drive without a volume, or gets a new one."""
    register_backend(Backend(platform="mounting", image="transfer", port=8000, connect=lambda url: url,
                             wait_ready=lambda url, t: None, drive_mount="/mnt/drive",
                             container_options={"command": ["python3", "-m", "http.server", "8000"]}))
    lc = Lifecycle(lifecycle.run_id, "gw4", keep_networks=2)
    mounting, plain = lc.boot(("mounting",)), lc.boot(standin_platforms[:1])
    volume = mounting.volumes[0].name
    mounting.containers["mounting"].exec_run(["sh", "-c", "echo from-the-device >/mnt/drive/data/left.txt"])
    assert mounting.transfer.walk("/") == ["/data/left.txt"] and not plain.volumes
    with_volume, without = mounting.containers["transfer"], plain.containers["transfer"]
    mounting.close()
    plain.close()
    assert {volume, with_volume.name, without.name} <= set(leftovers(lc.run_id))
    again = lc.boot(standin_platforms[:1])  # not the oldest kept drive: the one without a volume
    assert again.containers["transfer"].id == without.id and not again.volumes
    remount = lc.boot(("mounting",))
    assert remount.containers["transfer"].id == with_volume.id and [v.name for v in remount.volumes] == [volume]
    seen = remount.containers["mounting"].exec_run(["sh", "-c", "cd /mnt/drive && find . | sort"]).output
    assert seen.split() == [b".", b"./data"] and remount.transfer.walk("/") == []
    remount.close()
    other = lc.boot(standin_platforms[:1])  # only the drive with a volume is kept: it is removed, a new one made
    assert other.containers["transfer"].id not in (with_volume.id, without.id) and not other.volumes
    assert volume not in leftovers(lc.run_id) and with_volume.name not in leftovers(lc.run_id)
    again.close()
    other.close()
    lc.close()
    assert leftovers(lc.run_id) == []


def _held_backend(platform: str = "held") -> str:
    """A stand-in platform whose devices run in a holder's network namespace (`Backend.holder`)."""
    register_backend(standin_backend(platform, holder=True))
    return platform


def test_a_held_device_runs_in_its_holder_which_alone_is_on_the_network(device_images, lifecycle):
    from jarvis_pytest.infra.egress import device_routes

    platform = _held_backend()
    env = Lifecycle(lifecycle.run_id, "gw5").boot((platform,))
    try:
        device, holder = env.containers[platform], env.holders[platform].container
        device.reload()
        holder.reload()
        assert device.attrs["HostConfig"]["NetworkMode"] == f"container:{holder.id}"
        assert not bindings(device) and not device.attrs["NetworkSettings"]["Networks"]  # nothing of its own
        bs = bindings(holder)
        assert bs and all(b["HostIp"] == "127.0.0.1" for b in bs), bs
        assert env.urls[platform] == f"http://127.0.0.1:{bs[0]['HostPort']}" == env.holders[platform].url
        assert set(holder.attrs["NetworkSettings"]["Networks"]) == {env.network.name}
        assert holder.labels[LABEL_ROLE] == "holder" and holder.labels[LABEL_PLATFORM] == platform
        assert holder.labels[LABEL_RUN] == lifecycle.run_id and holder.labels[LABEL_PID] == str(os.getpid())
        assert holder.attrs["Config"]["Entrypoint"] == ["sleep", "infinity"] and not holder.attrs["Config"]["Cmd"]
        # the device's namespace is the holder's: its address on the task network, no default route
        routes = device_routes(device)
        assert routes and not any(r.startswith("default") for r in routes) and routes == device_routes(holder)
        # the device serves through the holder's port, and reaches the drive by its name
        import httpx
        assert httpx.get(env.urls[platform], timeout=5).status_code == 200
        probe = device.exec_run(["curl", "-s", "-o", "/dev/null", "-w", "%{http_code}", "-H", "PW: agentPassword",
                                 "http://transfer:5244/data/?ls"])
        assert probe.output == b"200"
        assert sorted(attached(env.network)) == sorted([holder.name, env.containers["transfer"].name])
    finally:
        env.close()
    assert leftovers(lifecycle.run_id) == []


def test_a_kept_holder_serves_the_next_device_only_when_nothing_runs_in_it(device_images, lifecycle, capfd):
    import httpx

    platform = _held_backend()
    lc = Lifecycle(lifecycle.run_id, "gw6", keep_networks=1)
    first = lc.boot((platform,))
    holder, device = first.holders[platform].container, first.containers[platform]
    first.close()
    assert holder.name in leftovers(lc.run_id) and device.name not in leftovers(lc.run_id)
    second = lc.boot((platform,))
    assert second.holders[platform].container.id == holder.id and second.urls[platform] == first.urls[platform]
    assert second.containers[platform].id != device.id and lc.networks.created == 1
    assert httpx.get(second.urls[platform], timeout=5).status_code == 200  # the new device answers there
    second.close()
    # a kept holder that stopped is replaced by a new one; the network and drive are still reused
    holder.kill()
    replaced = lc.boot((platform,))
    assert replaced.network.name == first.network.name and lc.networks.created == 1
    assert replaced.holders[platform].container.id != holder.id and holder.name not in leftovers(lc.run_id)
    assert httpx.get(replaced.urls[platform], timeout=5).status_code == 200
    holder = replaced.holders[platform].container
    replaced.close()
    # something of the run still in the kept holder's namespace (a device whose removal failed): not reused
    stray = docker.from_env().containers.run("jarvis/transfer", ["sleep", "600"], name=f"{lc.run_id}-in-holder",
                                             network_mode=f"container:{holder.id}", detach=True,
                                             labels={LABEL_RUN: lc.run_id})
    capfd.readouterr()
    third = lc.boot((platform,))
    assert third.network.name != first.network.name and third.holders[platform].container.id != holder.id
    assert f"still has {stray.name} on it: not reused" in capfd.readouterr().err
    assert holder.name not in leftovers(lc.run_id)  # the kept holder and drive were removed
    third.close()
    lc.close()
    stray.remove(force=True)
    assert leftovers(lc.run_id) == [first.network.name]  # left alone while the stray was in it, as for any network
    docker.from_env().networks.get(first.network.name).remove()


def test_a_holder_whose_files_a_device_changed_is_not_kept(device_images, lifecycle):
    """A device's root can write the /etc/hosts, /etc/resolv.conf and /etc/hostname it shares with its holder; a
    holder so changed is removed when its task ends, and the next device gets a new holder with Docker's files."""
    platform = _held_backend()
    lc = Lifecycle(lifecycle.run_id, "gw7", keep_networks=1)
    for path in ("/etc/hosts", "/etc/resolv.conf", "/etc/hostname"):
        env = lc.boot((platform,))
        holder, device = env.holders[platform].container, env.containers[platform]
        assert device.exec_run(["sh", "-c", f"echo 10.9.9.9 transfer >> {path}"]).exit_code == 0
        env.close()
        assert holder.name not in leftovers(lc.run_id) and env.network.name in leftovers(lc.run_id)
        again = lc.boot((platform,))
        assert again.network.name == env.network.name and again.holders[platform].container.id != holder.id
        assert b"10.9.9.9" not in again.containers[platform].exec_run(["cat", path]).output
        again.close()  # untouched: kept, and the next round's device joins it
    lc.close()
    assert leftovers(lc.run_id) == []


def test_the_real_ubuntu_device_on_loopback(ubuntu_env):
    for c in ubuntu_env.containers.values():
        assert all(b["HostIp"] == "127.0.0.1" for b in bindings(c))
    assert ubuntu_env.devices["ubuntu"].health().desktop
    assert ubuntu_env.image_ids["ubuntu"].startswith("sha256:")


def failed_boot(lifecycle, platform: str, script: str, ready_timeout: float) -> str:
    """Boot a stand-in device of the transfer image running `script`; the error it fails with (within 20 s)."""
    register_backend(Backend(platform=platform, image="transfer", port=5000, connect=lambda url: url,
                             wait_ready=never_ready, container_options={"command": ["sh", "-c", script]}))
    lc = Lifecycle(lifecycle.run_id, "test", Limits(ready_timeout=ready_timeout))
    t0 = time.monotonic()
    with pytest.raises(InfrastructureError) as err:
        lc.boot((platform,))
    elapsed = time.monotonic() - t0
    print(f"{platform} device failed after {elapsed:.1f} s (timeout {ready_timeout} s)")
    assert elapsed < 20
    return str(err.value)


def test_a_device_that_never_gets_ready_fails_with_its_logs(lifecycle, device_images):
    msg = failed_boot(lifecycle, "never", "echo 'device says: cannot start'; sleep 600", ready_timeout=5)
    assert "not ready after 5 s" in msg and "does not answer" in msg
    assert "docker logs" in msg and "device says: cannot start" in msg
    assert leftovers(lifecycle.run_id) == []  # a failed boot removes what it made, the drive and network too


@pytest.mark.parametrize("delay", ["0", "1.5"], ids=["exits-at-once", "exits-while-polled"])
def test_a_device_that_exits_fails_at_once_with_its_logs(lifecycle, device_images, delay):
    msg = failed_boot(lifecycle, "crashing", f"sleep {delay}; echo 'Xvfb: fatal: no screen' >&2; exit 3",
                      ready_timeout=60)
    assert "exited with code 3" in msg and "Xvfb: fatal: no screen" in msg
    assert leftovers(lifecycle.run_id) == []


def test_an_unknown_platform_creates_nothing(lifecycle):
    with pytest.raises(InfrastructureError, match="no device backend for platform 'amiga'"):
        lifecycle.boot(("amiga",))
    assert leftovers(lifecycle.run_id) == []


def test_pool_prewarm_is_faster_than_a_cold_boot_and_close_removes_all(lifecycle):
    pool = Pool(lifecycle)
    t0 = time.monotonic()
    cold = pool.acquire(("ubuntu",))  # nothing pre-warmed: boots now
    cold_s = time.monotonic() - t0
    assert cold.devices["ubuntu"].health().desktop
    pool.prewarm(("ubuntu",))  # while the "task" on `cold` runs
    assert pool.wait_prewarmed(("ubuntu",), timeout=120)
    cold.close()
    t0 = time.monotonic()
    warm = pool.acquire(("ubuntu",))
    warm_s = time.monotonic() - t0
    print(f"\ncold boot {cold_s:.2f} s; acquire after pre-warm {warm_s * 1000:.1f} ms")
    assert warm.devices["ubuntu"].health().desktop and warm.transfer.list("/") == (["data"], [])
    assert warm.network.name != cold.network.name
    warm.close()
    pool.prewarm(("ubuntu",))  # never acquired: close must remove it, even while it is still booting
    pool.close()
    assert leftovers(lifecycle.run_id) == []
    pool.prewarm(("ubuntu",))  # a closed pool boots nothing more
    assert not pool.wait_prewarmed(("ubuntu",), timeout=0) and leftovers(lifecycle.run_id) == []


def test_a_prewarm_waits_while_memory_is_short_but_a_task_gets_its_devices_at_once(lifecycle, standin_platforms,
                                                                                   capfd):
    platforms = standin_platforms[:1]
    free = available_memory_mb()  # this machine's MemAvailable: the bound reads the real figure
    assert free and free > 0
    assert lifecycle.booted_memory_mb(platforms) == (lifecycle.backend(platforms[0]).booted_memory_mb
                                                     + lifecycle.server.booted_memory_mb) > 0
    short = free + 10**6  # a reserve this machine cannot keep beside any boot
    with Pool(lifecycle, reserve_mb=short) as pool:
        pool.prewarm(platforms)
        time.sleep(2)
        assert not pool.wait_prewarmed(platforms, timeout=0) and leftovers(lifecycle.run_id) == []  # nothing made
        assert capfd.readouterr().err.count("waits for memory") == 1  # said once, not at every check
        pool.reserve_mb = 0  # memory is free again: the waiting pre-warm boots on its own
        assert pool.wait_prewarmed(platforms, timeout=60)
        ahead = pool.acquire(platforms)
        assert set(ahead.containers) == {platforms[0], "transfer"}
        ahead.close()
        pool.reserve_mb = short
        pool.prewarm(platforms)
        time.sleep(1)
        assert not pool.wait_prewarmed(platforms, timeout=0) and leftovers(lifecycle.run_id) == []
        t0 = time.monotonic()
        asked = pool.acquire(platforms)  # a task asks for it: it boots now, memory or not, as without a pre-warm
        assert set(asked.containers) == {platforms[0], "transfer"} and time.monotonic() - t0 < 60
        asked.close()
        pool.prewarm(platforms)  # waiting when the pool closes: cancelled, nothing left
        time.sleep(0.5)
        t0 = time.monotonic()
    assert time.monotonic() - t0 < 5 and leftovers(lifecycle.run_id) == []


def cpu_shares(container) -> tuple[int, int]:
    """A container's CPU weight as Docker has it (0: its default) and as the kernel applies it (its cgroup)."""
    container.reload()
    cgroup = Path(f"/sys/fs/cgroup/cpu/docker/{container.id}/cpu.shares")
    return container.attrs["HostConfig"]["CpuShares"], int(cgroup.read_text())


def test_a_prewarm_runs_at_a_low_cpu_weight_until_a_task_asks_for_it(lifecycle, standin_platforms):
    platforms = standin_platforms[:1]
    with Pool(lifecycle) as pool:
        now = pool.acquire(platforms)  # nothing pre-warmed: booted for a waiting task, then at Docker's default
        assert {role: cpu_shares(c) for role, c in now.containers.items()} == {platforms[0]: (1024, 1024),
                                                                               "transfer": (1024, 1024)}
        pool.prewarm(platforms)  # speculative while the task on `now` runs: takes what running devices leave
        assert pool.wait_prewarmed(platforms, timeout=60)
        ahead = pool._ready[platforms][0].result()
        low = (BootPriority.LOW, BootPriority.LOW)
        assert {role: cpu_shares(c) for role, c in ahead.containers.items()} == {platforms[0]: low, "transfer": low}
        now.close()
        taken = pool.acquire(platforms)  # a task waits for it: the default weight from now on
        assert taken is ahead
        assert {role: cpu_shares(c) for role, c in taken.containers.items()} == {platforms[0]: (1024, 1024),
                                                                                 "transfer": (1024, 1024)}
        taken.close()


def test_a_boot_a_task_waits_for_runs_above_the_default_weight_until_it_is_done(lifecycle, device_images):
    made = []

    def container(shares):
        made.append(docker.from_env().containers.create(device_images["transfer"], ["sleep", "600"],
                                                        cpu_shares=shares,
                                                        labels=ctr_labels(lifecycle.run_id, "gw0", "device")))
        return made[-1]

    priority = BootPriority(low=True)
    try:
        early = container(priority.shares())
        priority.made(early, BootPriority.LOW)
        shares = priority.shares()
        late = container(shares)  # created before the boot became urgent, registered after
        priority.urgent()
        weight = priority.shares()
        priority.made(late, shares)
        after = container(weight)  # made while a task waits: at the urgent weight from the start
        priority.made(after, weight)
        assert weight >= 2 * BootPriority.DEFAULT
        for c in made:
            c.start()
            assert cpu_shares(c) == (weight, weight)
        priority.settle()  # booted: the default, as any device
        assert [cpu_shares(c) for c in made] == [(1024, 1024)] * 3
        assert BootPriority().shares() is None and priority.shares() is None
    finally:
        for c in made:
            c.remove(force=True)


def test_of_the_boots_tasks_wait_for_the_older_gets_more_of_the_cpu():
    """FIFO without a queue: the weight doubles with each second a boot has run, so the boot begun first (the one
    furthest along) is done first, and an urgent boot always outweighs a running task's device (the default)."""
    boot = BootPriority(low=True)
    weights = [boot.urgent_weight(now=boot.started + age) for age in (0.0, 0.5, 1.0, 3.0, 6.0, 60.0)]
    assert weights[0] == 2 * BootPriority.DEFAULT
    assert weights == sorted(weights) and len(set(weights)) == len(weights)
    assert weights[2] == 2 * weights[0] and weights[-1] == BootPriority.HIGHEST
    assert boot.urgent_weight(now=boot.started - 5) == weights[0]  # a clock read before the start: no lower


def test_a_failed_prewarm_is_retried_once_on_acquire(lifecycle, standin_platforms):
    attempts = []

    def flaky(url: str, timeout: float) -> None:
        attempts.append(url)
        if len(attempts) == 1:
            raise ValueError("first boot breaks")

    register_backend(Backend(platform="flaky", image="transfer", port=8000, connect=lambda url: url,
                             wait_ready=flaky, container_options={"command": ["sleep", "600"]}))
    with Pool(lifecycle) as pool:
        pool.prewarm(("flaky",))
        assert pool.wait_prewarmed(("flaky",), timeout=60)
        env = pool.acquire(("flaky",))
        assert len(attempts) == 2 and env.urls["flaky"] == attempts[1]
        env.close()
    assert leftovers(lifecycle.run_id) == []


EXIT_WITHOUT_CLOSING = """
import sys
sys.path.insert(0, sys.argv[2])
from conftest import STANDIN_PLATFORMS, register_standin_backends
register_standin_backends()
from jarvis_pytest.environments.lifecycle import Lifecycle
from jarvis_pytest.environments.pool import Pool
pool = Pool(Lifecycle(sys.argv[1], "gw7"))
pool.prewarm(STANDIN_PLATFORMS)
assert pool.wait_prewarmed(STANDIN_PLATFORMS, timeout=60)
print("pre-warmed", flush=True)
"""  # and exits without closing the pool: its atexit hook must remove the environment


def test_the_pool_cleans_up_at_interpreter_exit(standin_platforms):
    run_id = f"test-exit-{uuid.uuid4().hex[:6]}"
    tests_dir = os.path.dirname(__file__)
    try:
        out = subprocess.run([sys.executable, "-c", EXIT_WITHOUT_CLOSING, run_id, tests_dir], capture_output=True,
                             text=True, timeout=120)
        assert out.stdout.strip() == "pre-warmed", out.stderr[-2000:]
        assert leftovers(run_id) == []
    finally:
        cleanup(run_id)


def test_one_orphan_sweep_of_an_engine_at_a_time():
    """Sessions starting together sweep orphans one after another; a sweep that cannot get its turn says why."""
    with orphan_sweep(), ThreadPoolExecutor(1) as other:  # a thread of its own is another holder, as a process is
        with pytest.raises(InfrastructureError, match=r"another orphan sweep of this engine held its lock"):
            other.submit(lambda: orphan_sweep(timeout=0.3).__enter__()).result()
        with orphan_sweep():  # the holder itself may sweep (cleanup() inside a held sweep)
            pass
    with orphan_sweep(timeout=5):  # released: the next sweep gets its turn
        pass


BOOT_AND_HANG = """
import sys, time
from jarvis_pytest.environments.lifecycle import Lifecycle
Lifecycle(sys.argv[1], "gw9").boot(("ubuntu",))
print("booted", flush=True)
time.sleep(600)
"""


def test_cleanup_after_the_run_is_killed(standin_platforms, device_images):
    run_id = f"test-kill-{uuid.uuid4().hex[:6]}"
    proc = subprocess.Popen([sys.executable, "-c", BOOT_AND_HANG, run_id], stdout=subprocess.PIPE, text=True)
    live = None
    try:
        assert proc.stdout.readline().strip() == "booted"
        with orphan_sweep():  # a pytest session another test starts now would otherwise sweep these orphans first
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait(10)
            assert len(leftovers(run_id)) == 4  # ubuntu, its holder, transfer, network: a kill -9 leaves them
            killed_net = [n.name for n in docker.from_env().networks.list(filters={"label": f"{LABEL_RUN}={run_id}"})]
            assert [within_rules(n) for n in killed_net] == [1]  # the network's own accept rule stays with it
            # another worker of the same run is still alive: cleaning orphans must spare its environment
            live = Lifecycle(run_id, "gw1").boot(standin_platforms[:1])
            assert cleanup(run_id, orphans_only=True) == {"containers": 3, "networks": 1, "volumes": 0}
        assert leftovers(run_id) == sorted([*(c.name for c in live.containers.values()), live.network.name])
        assert [within_rules(n) for n in [*killed_net, live.network.name]] == [0, 1]  # the rule went first
        assert live.transfer.list("/") == (["data"], [])
        # `jarvis cleanup --run` removes everything of the run, live or not
        out = subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "cleanup", "--run", run_id],
                             capture_output=True, text=True)
        assert out.returncode == 0, out.stderr
        assert "2 containers, 1 networks, 0 volumes removed" in out.stdout
        assert leftovers(run_id) == []
        assert [within_rules(n) for n in [*killed_net, live.network.name]] == [0, 0]  # rules go with networks
    finally:
        proc.kill()
        if live is not None:
            live.close()
        cleanup(run_id)
