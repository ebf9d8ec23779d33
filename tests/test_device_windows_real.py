"""The real Windows backend (`--windows-backend kvm`), which cannot boot here (no Windows image, no KVM that runs
one): its settings, the container specifications of preparation and of a task (the VM runner's restore of the
golden's memory snapshot), what preparation checks and refuses and in which order, its first-boot (OEM) scripts and
bundle, when it says it cannot run, what its results record, and the live gate (`make test-windows-real`), skipped
here with the reason.

Where dockur's entry would run, a real container plays it: its rules are transcribed from dockur/windows v6.05
(the pinned `dockurr/windows:6.05`, commit efe47da) with the file they come from; Docker, tini, bash and the
signals are real. Where the runner would save Windows' memory, it saves a small Linux guest's under TCG through the
same code (`tests/test_vm_runner.py` proves its restore). The OS and program probes and the logon script run on the
Wine device (the same control server and `cmd`; Wine's `cmd` is not Windows', and `net`/`nslookup` are stubs
there)."""

from __future__ import annotations

import dataclasses
import io
import json
import os
import re
import struct
import subprocess
import sys
import time
import zipfile
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

import pytest

from jarvis_pytest.devices.backend import backend_for
from jarvis_pytest.devices.vm import windows as vm_windows
from jarvis_pytest.devices.windows import real
from jarvis_pytest.errors import DEVICE_FAULT_ATTEMPTS, ConfigError, InfrastructureError

REPO = Path(__file__).resolve().parents[1]
TEST_LABEL = {"org.jarvis.test": "1"}
LIVE_ENV = "JARVIS_WINDOWS_LIVE"  # set by `make test-windows-real`


def golden_of(tmp_path: Path, **state: str | bytes) -> real.WindowsVMSettings:
    """Settings whose disks folder is under tmp_path, its golden holding `state` (file name → content)."""
    s = real.settings({}, disks=str(tmp_path / "disks"))
    s.golden.mkdir(parents=True)
    for name, content in state.items():
        path = s.golden / name
        path.write_bytes(content) if isinstance(content, bytes) else path.write_text(content)
    return s


# What a dockur v6.05 installation of VERSION=10 leaves in /storage (src/install.sh finishInstall, src/power.sh
# markWindowsBooted, qemu src/boot.sh and src/network.sh).
INSTALLED = {"data.qcow2": b"QFI\xfb" + b"\x01" * 64, "windows.base": "win10x64.iso\n", "windows.boot": "",
             "windows.ver": "6.05\n", "windows.rom": b"\x55" * 16, "windows.vars": b"\xaa" * 16,
             "windows.mac": "02:7A:EC:01:02:03\n"}
QEMU = "QEMU emulator version 7.2.22 (Debian 1:7.2+dfsg-7+deb12u18+b3)"


def save_memory(s: real.WindowsVMSettings) -> dict:
    """What the runner leaves in `<golden>/snapshot/` after saving the memory of the golden's Windows (small
    stand-ins for the disk overlay and the state stream; the record a restore checks), and what READY records of it
    (`real.save_snapshot`'s answer)."""
    from jarvis_pytest.devices.vm import golden as vm_golden

    profile = real.task_profile(s)
    snap = s.golden / vm_golden.SNAPSHOT
    snap.mkdir()
    (snap / vm_golden.DISK).write_bytes(b"QFI\xfb" + b"\x02" * 64)
    (snap / "windows.vars").write_bytes(b"\xaa" * 16)
    desc = json.dumps({"devices": [{"name": "timer"}]}).encode()
    (snap / vm_golden.STATE).write_bytes(vm_golden.MAGIC + b"\x07" + b"\x00" * 64 + b"\x00"
                                         + bytes([vm_golden.VMDESC]) + struct.pack(">I", len(desc)) + desc)
    files = {rel: vm_golden.file_stamp(s.golden / rel) for rel in vm_golden.recorded_files(s.golden, profile)}
    state = snap / vm_golden.STATE
    record = vm_golden.Record(profile=profile, qemu=QEMU, source={"dockur_release": "6.05"},
                              state_bytes=state.stat().st_size, state_sha256=vm_golden.sha256_of(state), files=files,
                              created=time.time(), timings={"boot_to_ready": 40.0, "save": 3.0})
    vm_golden.write_record(s.golden, record)
    return {"profile": profile.name, "qemu": QEMU, "state_bytes": record.state_bytes,
            "state_sha256": record.state_sha256, "saved": record.created, "timings": record.timings,
            "memory_mb": profile.memory_mb, "cores": real.cores(s)}


def prepared(tmp_path: Path, s: real.WindowsVMSettings | None = None, **state: str | bytes | None) -> \
        real.WindowsVMSettings:
    """A golden as preparation leaves it: dockur's finished installation (`INSTALLED`, with `state`'s changes),
    its memory snapshot, READY last."""
    s = s or real.settings({}, disks=str(tmp_path / "disks"))
    s.golden.mkdir(parents=True)
    for name, content in {**INSTALLED, **state}.items():
        if content is not None:
            path = s.golden / name
            path.write_bytes(content) if isinstance(content, bytes) else path.write_text(content)
    ready = real.finalise(s, FACTS)
    ready["snapshot"] = save_memory(s)
    real.mark_ready(s, ready)
    return s


# -- settings -----------------------------------------------------------------------------------------------------
def test_settings_default_to_a_pinned_dockur_and_a_windows_10_with_every_kvm_program():
    s = real.settings({})
    assert s.problem() is None
    assert s.image == "dockurr/windows:6.05" == real.IMAGE  # a tag, not the moving `latest`
    assert s.version == "10" and s.windows_id == "win10x64"  # Windows 10 22H2: WordPad and the classic Paint
    assert {"wordpad", "mspaint", "msedge", "powershell", "regedit", "notepad"} <= set(real.kvm_programs())


def test_settings_come_from_options_over_the_environment_and_name_their_origin():
    env = {"JARVIS_WINDOWS_VERSION": "ltsc10", "JARVIS_WINDOWS_RAM": "6G", "JARVIS_WINDOWS_CPUS": "3",
           "JARVIS_WINDOWS_DISKS": "/tmp/wdisks"}
    s = real.settings(env, cpus="4")
    assert (s.version, s.windows_id, s.ram, s.cpus) == ("ltsc10", "win10x64-enterprise-ltsc-eval", "6G", "4")
    assert s.golden == Path("/tmp/wdisks/golden") and s.ready_mark == Path("/tmp/wdisks/golden/READY")
    assert s.origin == {"version": "JARVIS_WINDOWS_VERSION", "ram": "JARVIS_WINDOWS_RAM", "cpus": "windows.cpus",
                        "disks": "JARVIS_WINDOWS_DISKS"}
    with pytest.raises(ConfigError, match="unknown Windows VM setting.*colour"):
        real.settings({}, colour="blue")


@pytest.mark.parametrize("env, field, words", [
    ({"JARVIS_WINDOWS_VERSION": "11"}, "JARVIS_WINDOWS_VERSION", "WordPad"),
    ({"JARVIS_WINDOWS_IMAGE": "dockurr/windows"}, "JARVIS_WINDOWS_IMAGE", "not pinned"),
    ({"JARVIS_WINDOWS_IMAGE": "dockurr/windows:latest"}, "JARVIS_WINDOWS_IMAGE", "not pinned"),
    ({"JARVIS_WINDOWS_IMAGE": "dockurr/windows:5.14"}, "JARVIS_WINDOWS_IMAGE", "not dockur/windows 6.05"),
    ({"JARVIS_WINDOWS_RAM": "lots"}, "JARVIS_WINDOWS_RAM", "not an amount of memory"),
    ({"JARVIS_WINDOWS_CPUS": "0"}, "JARVIS_WINDOWS_CPUS", "not a number of cores"),
    ({"JARVIS_WINDOWS_DISK_SIZE": "big"}, "JARVIS_WINDOWS_DISK_SIZE", "not a disk size"),
])
def test_a_bad_setting_is_one_error_naming_it_and_the_fix(monkeypatch, tmp_path, env, field, words):
    s = real.settings(env)
    error = s.problem()
    assert isinstance(error, ConfigError) and error.field == field and words in str(error) and error.fix
    with pytest.raises(ConfigError):
        s.check()
    # the backend says so instead of booting (auto then takes the Wine stand-in); preparing stops before anything
    for name, value in env.items():
        monkeypatch.setenv(name, value)
    monkeypatch.setattr(real.os.path, "exists", lambda p: True)
    assert field in (real.unavailable() or "")
    monkeypatch.setenv(real.DOWNLOAD_ENV, "1")
    with pytest.raises(ConfigError, match=field):
        real.prepare()


def test_the_6_05_release_is_accepted_from_a_mirror_or_by_digest_and_no_other():
    for image in ("ghcr.io/dockur/windows:6.05", "registry:5000/windows:6.05", "dockurr/windows@sha256:" + "0" * 64):
        assert real.settings({}, image=image).problem() is None, image
    # a digest's release is known once it installed (windows.ver): the runner then refuses another (test_vm_runner)
    for image in ("dockurr/windows:5.14", "dockurr/windows:6.06", "registry:5000/windows"):  # a port is not a tag
        assert real.settings({}, image=image).problem() is not None, image
    assert real.DOCKUR_TAG == "6.05" == vm_windows.DOCKUR_RELEASE  # the release installed is the machine restored


@pytest.mark.parametrize("ram, mb", [(None, 4096), ("6G", 6144), ("6144M", 6144), ("8gb", 8192), ("6 G", 6144),
                                      ("4", 4096), ("129", 129 * 1024), ("6144", 6144), ("2.5G", 2560),
                                      ("4194304K", 4096), ("lots", 4096)])
def test_the_vms_ram_is_read_as_dockur_reads_ram_size(ram, mb):
    """qemus/qemu v7.48 src/memory.sh:20-49: spaces dropped, a bare number below 130 is GiB, any other bare number
    MiB, an IEC suffix with an optional B. The runner restores with it; the pool keeps it (and QEMU's) free."""
    s = real.settings({}) if ram is None else real.settings({}, ram=ram)
    assert real.ram_mb(s) == mb
    kvm = backend_for("windows", "kvm", {} if ram is None or ram == "lots" else {"ram": ram})
    if ram != "lots":
        assert kvm.memory == f"{mb + 512}m" and kvm.booted_memory_mb == mb + 160


def test_the_vms_settings_come_from_the_settings_not_the_environment(monkeypatch):
    monkeypatch.setenv("JARVIS_WINDOWS_RAM", "8G")
    monkeypatch.setenv("JARVIS_WINDOWS_CPUS", "64")
    s = real.settings({}, ram="6G", cpus="3")
    assert real.ram_mb(s) == 6144 and real.ram_mb(real.settings()) == 8192
    assert real.cores(s) == min(3, os.cpu_count()) and real.cores(real.settings()) == os.cpu_count()  # init.sh:94-97


# -- the containers -----------------------------------------------------------------------------------------------
def test_dockur_installs_windows_10_at_the_librarys_screen(tmp_path):
    s = real.settings({}, disks=str(tmp_path))
    env = real.environment(s)
    assert (env["WIDTH"], env["HEIGHT"]) == ("1920", "1080")  # the library's and grounders' screen, not 1280x720
    assert env["VERSION"] == "10" and env["DISK_FMT"] == "qcow2" and env["USERNAME"] == "user"
    assert env["USER_PORTS"] == "5000"  # forwarded into the VM where dockur falls back to user-mode networking
    prep = real.preparation_options(s, tmp_path / "oem")
    assert prep["environment"] == env and prep["image"] == s.image == "dockurr/windows:6.05"
    assert "/dev/kvm" in prep["devices"] and "NET_ADMIN" in prep["cap_add"]


def test_preparation_runs_dockur_on_the_golden_and_stops_it_with_sigterm(tmp_path):
    s = real.settings({}, disks=str(tmp_path))
    prep = real.preparation_options(s, tmp_path / "oem")
    assert prep["volumes"][str(s.golden)] == {"bind": "/storage", "mode": "rw"}  # all of dockur's state is kept
    assert prep["volumes"][str(tmp_path / "oem")] == {"bind": "/oem", "mode": "ro"}
    assert prep["stop_signal"] == "SIGTERM" and prep["tty"] is False  # dockur traps SIGINT only with a tty
    assert "entrypoint" not in prep  # dockur's own entry installs
    assert set(prep["ports"]) == {"5000/tcp", "8006/tcp"} and all(h == "127.0.0.1" for h, _ in prep["ports"].values())


class _Boot:
    """Records what a backend's boot would hand the engine (`infra.containers.boot_container`)."""

    def __init__(self):
        self.calls: list = []

    def __call__(self, backend, request):
        from jarvis_pytest.infra.containers import BootedDevice

        self.calls.append((backend, request))
        return BootedDevice(container=None, url="http://127.0.0.1:1", backend=backend)


def boot_request():
    from jarvis_pytest.infra.containers import BootRequest

    return BootRequest(docker=None, name="t", network=None, labels={}, memory=None, cpus=None, ready_timeout=1)


def test_a_task_vm_is_the_runners_restore_of_the_golden_snapshot(monkeypatch, tmp_path):
    """No dockur at task time: the kvm backend boots a VM runner container that restores the golden's memory
    snapshot into an overlay of the golden disk, on dockur 6.05's machine with the settings' RAM and cores."""
    import jarvis_pytest.infra.containers as ctr
    from jarvis_pytest.devices.vm.profile import Profile

    s = prepared(tmp_path)
    monkeypatch.setattr(real.os.path, "exists", lambda p: True)  # as on a machine with /dev/kvm
    kvm = backend_for("windows", "kvm", {"disks": str(s.disks), "ram": "4G", "cpus": "2"})
    assert kvm.unavailable() is None
    boot = _Boot()
    monkeypatch.setattr(ctr, "boot_container", boot)
    kvm.boot(boot_request())
    (backend, _), = boot.calls
    opts = backend.container_options
    assert backend.image_ref == "jarvis/vm-runner:latest" and backend.port == 5000  # our image, not dockur's
    assert opts["command"] == ["restore"] and "entrypoint" not in opts  # the runner's entry: no dockur at task time
    assert opts["volumes"] == {str(s.golden.resolve()): {"bind": "/golden", "mode": "ro"}}  # never written by a task
    assert opts["devices"] == ["/dev/kvm:/dev/kvm:rwm"] and "cap_add" not in opts  # slirp: no NET_ADMIN, no tap
    spec = json.loads(opts["environment"]["JARVIS_VM"])
    profile = Profile.from_dict(spec["profile"])
    assert profile == real.task_profile(s) and profile.name == "windows-10-dockur-6.05"
    assert profile.memory_mb == 4096 and profile.smp.startswith(f"{real.cores(s)},")
    assert spec["ready_timeout"] == real.READY_TIMEOUT == kvm.ready_timeout
    # what it restores: the saved state whose record names this profile (the same check the runner makes)
    from jarvis_pytest.devices.vm import golden as vm_golden

    assert vm_golden.check(s.golden, profile).state_sha256 == real.ready_record(s)["snapshot"]["state_sha256"]


def test_a_golden_the_runner_cannot_restore_is_refused_before_any_container(monkeypatch, tmp_path):
    import jarvis_pytest.infra.containers as ctr

    monkeypatch.setattr(real.os.path, "exists", lambda p: True)
    boot = _Boot()
    monkeypatch.setattr(ctr, "boot_container", boot)

    def refused(s: real.WindowsVMSettings, given: dict, words: str) -> None:
        kvm = backend_for("windows", "kvm", {"disks": str(s.disks), **given})
        assert words in (kvm.unavailable() or ""), kvm.unavailable()
        request = boot_request()
        with pytest.raises(ConfigError, match=re.escape(words)):
            kvm.boot(request)
        assert boot.calls == [] and request.started == []

    s = prepared(tmp_path / "a")
    refused(s, {"ram": "6G"}, "cannot be restored with these settings (windows.ram 6G")  # saved with 4096 MiB
    (s.golden / "snapshot" / "vmstate").write_bytes(b"QEVM")                            # a damaged state
    refused(s, {}, "the memory state has 4 bytes")
    s = prepared(tmp_path / "b")
    (s.golden / "windows.ver").write_text("6.04\n")  # a golden another dockur release installed
    refused(s, {}, "installed by dockur/windows '6.04'")
    s = prepared(tmp_path / "c")
    ready = json.loads(s.ready_mark.read_text())
    s.ready_mark.write_text(json.dumps({**ready, "format": 2}))  # an earlier preparation: dockur booted its tasks
    refused(s, {}, "without the memory snapshot tasks are restored from")


def test_ready_needs_the_memory_snapshot(tmp_path):
    s = golden_of(tmp_path, **INSTALLED)
    ready = real.finalise(s, FACTS)
    assert not s.ready_mark.exists()  # finalise checks dockur's golden; READY waits for the snapshot
    with pytest.raises(InfrastructureError, match="no memory snapshot"):
        real.mark_ready(s, ready)
    assert not s.ready_mark.exists()


@pytest.fixture(scope="module")
def docker(device_images):
    from jarvis_pytest.infra.engine import client

    return client()


# dockur v6.05's entry as preparation meets it, played in bash under tini (Docker's --init, the tini dockur's image
# runs as PID 1): src/power.sh enableTrap traps SIGTERM, SIGHUP, SIGABRT, SIGQUIT always and SIGINT only when
# `interactive` (stdin a tty); gracefulShutdown asks the guest to power off, and `finish` → markWindowsBooted writes
# windows.boot once Windows has stopped after booting from its disk. Before the signal it has installed.
FAKE_DOCKUR_PREPARE = """#!/bin/bash
set -Eeuo pipefail
graceful() {
  echo "Received $1 signal, sending ACPI shutdown signal..."
  kill -TERM "$qemu" 2>/dev/null || :
  wait "$qemu" || :
  touch /storage/windows.boot
  echo "Shutdown completed!"
  exit "$2"
}
if [ -t 0 ]; then trap 'graceful SIGINT 130' SIGINT; fi
trap 'graceful SIGTERM 143' SIGTERM
trap 'graceful SIGHUP 129' SIGHUP
printf 'QFI\\xfbdisk' > /storage/data.qcow2
echo win10x64.iso > /storage/windows.base
echo 6.05 > /storage/windows.ver
printf 'vars' > /storage/windows.vars
sleep infinity &
qemu=$!
echo "Windows started successfully"
wait "$qemu"
"""


def preparing_container(docker, image: str, s: real.WindowsVMSettings, tmp_path: Path, **changes):
    """A container with preparation's real options (stop signal, tty, the golden as /storage) running the
    stand-in above, once it says Windows started."""
    (tmp_path / "entry.sh").write_text(FAKE_DOCKUR_PREPARE)
    opts = {**real.preparation_options(s, tmp_path / "oem"), **changes}
    c = docker.containers.run(image, entrypoint=["/bin/bash", "/fake/entry.sh"], init=True, detach=True,
                              stop_signal=opts["stop_signal"], tty=opts["tty"], stdin_open=opts["stdin_open"],
                              volumes={str(s.golden): opts["volumes"][str(s.golden)],
                                       str(tmp_path): {"bind": "/fake", "mode": "ro"}},
                              labels=TEST_LABEL, network_mode="none")
    deadline = time.monotonic() + 30
    while b"started successfully" not in c.logs() and time.monotonic() < deadline:
        time.sleep(0.1)
    return c


FACTS = {"image": {"ref": "dockurr/windows:6.05", "id": "sha256:" + "1" * 64,
                   "digest": "dockurr/windows@sha256:" + "2" * 64},
         "screen": [1920, 1080], "os": {"windows": "10", "build": "19045.3803", "release": "22H2"},
         "programs": {"wordpad": r"C:\Program Files\Windows NT\Accessories\wordpad.exe"}}


@pytest.mark.containers
def test_preparation_shuts_windows_down_and_keeps_the_finished_golden(docker, device_images, tmp_path):
    s = golden_of(tmp_path)
    c = preparing_container(docker, device_images["transfer"], s, tmp_path)
    try:
        log = real.stop_vm(c, grace=20)
    finally:
        c.remove(force=True)
    assert "Received SIGTERM" in log and "Shutdown completed" in log, log
    ready = real.finalise(s, FACTS, log)
    assert ready["state"] == ["data.qcow2", "windows.base", "windows.boot", "windows.vars", "windows.ver"]
    assert ready["dockur_version"] == "6.05" and ready["windows_id"] == "win10x64"
    assert not s.ready_mark.exists()  # dockur's golden is finished; READY comes after the memory snapshot


@pytest.mark.containers
def test_a_golden_stopped_with_sigint_is_refused(docker, device_images, tmp_path):
    """What preparation did before: SIGINT, which dockur (no tty) does not trap: Windows is killed, no
    windows.boot, and READY is refused rather than written over a golden every task would reinstall."""
    s = golden_of(tmp_path)
    c = preparing_container(docker, device_images["transfer"], s, tmp_path, stop_signal="SIGINT")
    try:
        log = real.stop_vm(c, grace=20)
    finally:
        c.remove(force=True)
    assert "Received" not in log and (s.golden / "data.qcow2").exists()
    with pytest.raises(InfrastructureError, match="no windows.boot: Windows was not shut down cleanly"):
        real.finalise(s, FACTS, log)
    assert not s.ready_mark.exists()


def test_ready_is_refused_for_a_golden_of_another_version(tmp_path):
    s = golden_of(tmp_path, **{**INSTALLED, "windows.base": "win11x64.iso\n"})
    with pytest.raises(InfrastructureError, match=r"windows.base is 'win11x64.iso', not win10x64.iso"):
        real.finalise(s, FACTS)
    assert not s.ready_mark.exists()


def test_preparing_again_first_removes_the_old_ready(monkeypatch, tmp_path):
    s = prepared(tmp_path)
    assert s.ready_mark.exists()
    monkeypatch.setenv(real.DOWNLOAD_ENV, "1")
    monkeypatch.setattr(real.os.path, "exists", lambda p: True)
    import jarvis_pytest.infra.engine as engine

    def no_engine(**kw):
        raise InfrastructureError("no engine (test)")

    monkeypatch.setattr(engine, "client", no_engine)
    with pytest.raises(InfrastructureError, match="no engine"):
        real.prepare(s=s)
    assert not s.ready_mark.exists()  # a preparation that fails leaves no READY over a half-made golden


@pytest.mark.containers
def test_preparation_end_to_end_refuses_a_windows_that_did_not_finish(monkeypatch, docker, device_images, tmp_path):
    """`prepare` with a real engine, the Wine device image standing in for dockur's (it answers as the VM's control
    server does, and writes none of dockur's state): it runs, waits for the server, checks the device, stops it
    and then refuses READY, naming what is missing with the container's last lines; nothing is left running."""
    tag = "jarvis/windows-prepare-test:6.05"  # the Wine image under dockur's tag
    docker.images.get(device_images["windows"]).tag(tag)
    s = real.settings({}, disks=str(tmp_path / "disks"), image=tag)
    monkeypatch.setenv(real.DOWNLOAD_ENV, "1")
    monkeypatch.setattr(real.os.path, "exists", lambda p: True)  # as on a machine with /dev/kvm
    monkeypatch.setattr(real, "_devices", lambda: [])            # the stand-in needs no KVM
    monkeypatch.setattr(real, "kvm_programs", lambda: ["notepad", "wordpad"])  # what Wine has
    monkeypatch.setattr(real, "STOP_GRACE", 5)                   # the stand-in does not trap SIGTERM
    try:
        with pytest.raises(InfrastructureError) as err:
            real.prepare(timeout=120, s=s)
    finally:
        docker.images.remove(tag)
    text = str(err.value)
    assert "is not finished: no data.qcow2; no windows.boot" in text and "last lines of the preparing" in text, text
    assert not s.ready_mark.exists()
    assert docker.containers.list(all=True, filters={"label": "org.jarvis.role=prepare"}) == []


@pytest.mark.containers
def test_preparation_saves_the_memory_snapshot_before_ready(monkeypatch, docker, device_images, tmp_path):
    """`prepare` end to end, in its order: dockur installs (the Wine image plays it and, on SIGTERM, leaves dockur
    6.05's state, as `test_preparation_shuts_windows_down_and_keeps_the_finished_golden` shows dockur's entry
    does), `finalise` checks dockur's golden, the VM runner cold-boots it and saves its memory (`save_snapshot`:
    the real runner container and code, a small Linux guest under TCG standing in for Windows, which cannot run
    here), and READY comes last, recording the snapshot and the dockur image it was installed by."""
    import uuid

    from jarvis_pytest.devices.vm import golden as vm_golden
    from jarvis_pytest.devices.vm import testguest
    from jarvis_pytest.infra.images import image_tag

    tag = f"jarvis/windows-prepare-test-{uuid.uuid4().hex[:6]}:6.05"  # the Wine image under dockur's tag
    docker.images.get(device_images["windows"]).tag(tag)
    s = real.settings({}, disks=str(tmp_path / "disks"), image=tag)
    stand_in = dataclasses.replace(testguest.PROFILE, disk="data.qcow2")  # the guest's disk where dockur's lies
    guest = tmp_path / "guest"
    guest.mkdir()
    testguest._extract(docker, image_tag(testguest.GUEST_IMAGE), guest)
    monkeypatch.setenv(real.DOWNLOAD_ENV, "1")
    monkeypatch.setattr(real.os.path, "exists", lambda p: True)  # as on a machine with /dev/kvm
    monkeypatch.setattr(real, "_devices", lambda: [])
    monkeypatch.setattr(real, "kvm_programs", lambda: ["notepad", "wordpad"])  # what Wine has
    monkeypatch.setattr(real, "STOP_GRACE", 5)
    monkeypatch.setattr(real, "SETTLE", 0.0)
    monkeypatch.setattr(vm_windows, "HOSTS_ENTRY", f"echo {stand_in.drive_ip} transfer >> /etc/hosts && "
                                                   "grep -c ' transfer$' /etc/hosts")
    windows_profile = vm_windows.profile_from_storage

    def profile(storage, **kw):  # dockur 6.05's state is checked as for Windows; the Linux guest boots
        windows_profile(storage, **kw)
        return stand_in

    monkeypatch.setattr(vm_windows, "profile_from_storage", profile)
    order: list[str] = []

    def spy(name: str, check=lambda: None):
        original = getattr(real, name)

        def call(*args, **kwargs):
            order.append(name)
            check()
            return original(*args, **kwargs)

        monkeypatch.setattr(real, name, call)

    stop_vm = real.stop_vm

    def stop_like_dockur(container, grace=None):  # dockur 6.05 on SIGTERM: Windows shut down, windows.boot written
        order.append("stop_vm")
        log = stop_vm(container, grace)
        for name, content in INSTALLED.items():
            if name != "data.qcow2":
                path = s.golden / name
                path.write_bytes(content) if isinstance(content, bytes) else path.write_text(content)
        for name, target in (("disk.qcow2", "data.qcow2"), ("vmlinuz", "vmlinuz"), ("initrd.img", "initrd.img")):
            (s.golden / target).write_bytes((guest / name).read_bytes())
        return log

    def no_ready():
        assert not s.ready_mark.exists(), "READY before the memory snapshot"

    monkeypatch.setattr(real, "stop_vm", stop_like_dockur)
    spy("finalise", no_ready)
    spy("save_snapshot", no_ready)
    spy("mark_ready", lambda: vm_golden.check(s.golden, stand_in))  # the snapshot is whole before READY
    try:
        disk = real.prepare(timeout=120, s=s)
    finally:
        docker.images.remove(tag)
    assert order == ["stop_vm", "finalise", "save_snapshot", "mark_ready"]
    assert disk == str(s.golden / "data.qcow2")
    record = vm_golden.check(s.golden, stand_in)
    ready = real.ready_record(s)
    assert ready["snapshot"]["state_sha256"] == record.state_sha256 and ready["snapshot"]["qemu"] == record.qemu
    assert ready["image"]["ref"] == tag and ready["dockur_version"] == "6.05" and ready["os"]["windows"] == "10"
    assert record.source["dockur_release"] == "6.05" and record.source["image"]["ref"] == tag
    assert len(record.outputs) == 1 and int(record.outputs[0]) >= 1  # `transfer` in the guest's hosts file
    assert record.profile.memory_mb == 256  # the stand-in's; Windows' is the settings' RAM (test_vm_runner)
    assert real.golden_problem(s) is None  # a task may restore it
    assert real.provenance(s)["snapshot"]["state_sha256"] == record.state_sha256
    for role in ("prepare", "vm-prepare"):
        assert docker.containers.list(all=True, filters={"label": f"org.jarvis.role={role}"}) == []


def test_image_record_keeps_the_registry_digest_of_the_pinned_tag():
    @dataclass
    class Image:
        id: str
        attrs: dict

    image = Image("sha256:" + "1" * 64, {"RepoDigests": ["ghcr.io/dockur/windows@sha256:" + "3" * 64,
                                                         "dockurr/windows@sha256:" + "2" * 64]})
    assert real.image_record(image, "dockurr/windows:6.05") == FACTS["image"]
    assert real.image_record(Image("sha256:9", {}), "mine/windows:1") == {"ref": "mine/windows:1", "id": "sha256:9",
                                                                         "digest": ""}


# -- when it says it cannot run -----------------------------------------------------------------------------------
def test_backend_says_why_it_cannot_run(monkeypatch, tmp_path):
    def why() -> str | None:  # the kvm backend as a run configures it (the environment read again)
        return backend_for("windows", "kvm").unavailable()

    kvm = backend_for("windows", "kvm")
    assert not kvm.stand_in and kvm.label == "windows (kvm)"
    assert kvm.image_ref == "jarvis/vm-runner:latest"  # built here; dockur's image only installs the golden
    assert backend_for("windows", "real").name == "kvm"  # the name for it
    assert "jarvis images build --only windows-real" in kvm.how_to_run
    monkeypatch.setenv("JARVIS_WINDOWS_DISKS", str(tmp_path / "disks"))
    monkeypatch.setattr(real.os.path, "exists", lambda p: True)
    assert "no prepared Windows disk" in (why() or "")
    s = prepared(tmp_path, real.settings({}, disks=str(tmp_path / "disks")))
    assert why() is None
    monkeypatch.setenv("JARVIS_WINDOWS_VERSION", "10l")  # another Windows than the golden's
    assert "the settings ask for '10l'" in (why() or "")
    monkeypatch.setenv("JARVIS_WINDOWS_VERSION", "win10")  # another name of the same Windows
    assert why() is None
    monkeypatch.setenv("JARVIS_WINDOWS_IMAGE", "registry:5000/windows:6.05")
    assert "prepared by dockurr/windows:6.05" in (why() or "")
    monkeypatch.delenv("JARVIS_WINDOWS_IMAGE")
    (s.golden / "windows.boot").unlink()
    assert "lacks windows.boot" in (why() or "")
    s.ready_mark.write_text("prepared 2026-11-01 from dockurr/windows VERSION=11\n")  # an earlier READY: disk only
    assert "without the memory snapshot" in (why() or "")
    monkeypatch.setattr(real.os.path, "exists", lambda p: False)
    assert "no /dev/kvm" in why()
    # auto picks the first backend that can run: here the Wine stand-in
    monkeypatch.setenv("JARVIS_WINDOWS_DISKS", str(tmp_path / "nothing"))
    auto = backend_for("windows")
    assert auto.name == "wine" and auto.stand_in and auto.label == "windows (wine)"


def test_images_build_prepares_windows_with_the_settings_a_run_would_use(monkeypatch):
    """`jarvis images build --only windows-real --backend-option windows.KEY=VALUE`: the VM runner image is built
    first, then `prepare(s=...)` gets the kvm backend's settings: each option, else its variable, else the default."""
    import jarvis_pytest.infra.engine as engine
    from jarvis_pytest.infra import images

    seen: dict = {"built": []}
    monkeypatch.setattr(engine, "client", lambda **kw: None)
    monkeypatch.setattr(images, "ensure_base", lambda c, force=False: "base")
    monkeypatch.setattr(images, "build_image", lambda c, spec, base, force=False:
                        seen["built"].append(spec.name) or f"jarvis/{spec.name}:latest")
    monkeypatch.setattr(real, "prepare", lambda timeout=0, s=None: seen.setdefault("s", s) and "golden")
    monkeypatch.setenv("JARVIS_WINDOWS_CPUS", "4")
    monkeypatch.delenv("JARVIS_WINDOWS_RAM", raising=False)
    built = images.build_all(["windows-real"], options={"windows": {"ram": "6G", "disks": "/srv/win"}})
    assert seen["built"] == ["vm-runner"] and built == {"vm-runner": "jarvis/vm-runner:latest",
                                                         "windows-real": "golden"}
    s = seen["s"]
    assert (s.ram, s.cpus, s.golden) == ("6G", "4", Path("/srv/win/golden"))
    assert s.origin == {"ram": "windows.ram", "disks": "windows.disks", "cpus": "JARVIS_WINDOWS_CPUS"}
    seen.clear()
    seen["built"] = []
    with pytest.raises(ConfigError, match="windows.ram.*'lots'"):
        images.build_all(["windows-real"], options={"windows": {"ram": "lots"}})
    assert "s" not in seen  # refused before anything is prepared


def test_images_build_takes_options_only_for_the_image_that_uses_them():
    proc = subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "images", "build", "--backend-option",
                           "windows.ram=6G"], cwd=REPO, capture_output=True, text=True, timeout=120)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 2 and "Traceback" not in out and "--only windows-real" in out, out


def test_preparing_downloads_nothing_unless_asked(monkeypatch, tmp_path):
    """`jarvis images build --only windows-real` pulls an image and downloads Windows: without the opt-in it stops
    before any of that, saying how to allow it (no Docker call, no packet)."""
    monkeypatch.delenv(real.DOWNLOAD_ENV, raising=False)
    monkeypatch.setattr(real.os.path, "exists", lambda p: True)  # as on a machine with /dev/kvm
    import jarvis_pytest.infra.engine as engine

    monkeypatch.setattr(engine, "client", lambda **kw: pytest.fail("no Docker call without the opt-in"))
    with pytest.raises(InfrastructureError, match=f"{real.DOWNLOAD_ENV}=1"):
        real.prepare(s=real.settings({}, disks=str(tmp_path)))


def test_the_kvm_backend_gives_its_results_the_golden_provenance(monkeypatch, tmp_path):
    s = prepared(tmp_path)
    kvm = backend_for("windows", "kvm", {"disks": str(s.disks)})
    said = kvm.provenance()
    assert said == real.provenance(s)
    assert said["image"]["digest"] == "dockurr/windows@sha256:" + "2" * 64 and said["dockur_version"] == "6.05"
    assert said["os"] == FACTS["os"] and said["snapshot"]["profile"] == "windows-10-dockur-6.05"
    assert said["snapshot"]["state_sha256"] == real.ready_record(s)["snapshot"]["state_sha256"]


PROVENANCE_PLUGIN = """
import dataclasses

from jarvis_pytest.devices.backend import register_backend
from jarvis_pytest.devices.windows.backend import WINE

# The Wine device under the kvm backend's name, saying what a kvm golden says of itself (`real.provenance`)
register_backend(dataclasses.replace(WINE, name="kvm", stand_in=False, provenance=lambda: {
    "image": {"ref": "dockurr/windows:6.05", "digest": "dockurr/windows@sha256:" + "2" * 64},
    "dockur_version": "6.05", "snapshot": {"state_sha256": "ab" * 32}}))
"""


@pytest.mark.containers
def test_every_result_of_a_kvm_task_records_its_golden(device_images, tmp_path):
    """Through a real run: a backend's provenance (for kvm: the dockur image's digest and the memory snapshot)
    reaches each task's result.json as `device_provenance`, beside the container's image id."""
    (tmp_path / "kvm_standin.py").write_text(PROVENANCE_PLUGIN)
    lib = tmp_path / "lib" / "windows"
    lib.mkdir(parents=True)
    (lib / "cmd_list_files.json").write_bytes((REPO / "tasks" / "windows" / "cmd_list_files.json").read_bytes())
    run = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist", "-p",
                           "kvm_standin", str(REPO / "tasks" / "test_atomic.py"), "--library", str(lib.parent),
                           "--instances", "1", "--agent", "noop", "--results-dir", str(run),
                           "--windows-backend", "kvm"], cwd=REPO, capture_output=True, text=True, timeout=600,
                          env={**os.environ, "PYTHONPATH": f"{tmp_path}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"})
    out = proc.stdout + proc.stderr
    (result,) = [json.loads(p.read_text()) for p in run.glob("tasks/*/result.json")]
    assert result["backends"] == {"windows": "windows (kvm)"} and result["status"] == "failed", out[-3000:]
    assert result["device_provenance"] == {"windows": {
        "image": {"ref": "dockurr/windows:6.05", "digest": "dockurr/windows@sha256:" + "2" * 64},
        "dockur_version": "6.05", "snapshot": {"state_sha256": "ab" * 32}}}
    assert result["image_ids"]["windows"].startswith("sha256:")


# -- what the device says about itself ----------------------------------------------------------------------------
WINDOWS_10_OS = """
Microsoft Windows [Version 10.0.19045.3803]

HKEY_LOCAL_MACHINE\\SOFTWARE\\Microsoft\\Windows NT\\CurrentVersion
    SystemRoot    REG_SZ    C:\\Windows
    CurrentBuild    REG_SZ    19045
    CurrentBuildNumber    REG_SZ    19045
    DisplayVersion    REG_SZ    22H2
    EditionID    REG_SZ    Professional
    ProductName    REG_SZ    Windows 10 Pro
    ReleaseId    REG_SZ    2009
    UBR    REG_DWORD    0xedb

HKEY_LOCAL_MACHINE\\SOFTWARE\\Microsoft\\Windows NT\\CurrentVersion\\AeDebug
"""


def test_the_os_is_read_from_what_the_device_says():
    assert real.parse_os(WINDOWS_10_OS) == {"version": "10.0.19045.3803", "product": "Windows 10 Pro",
                                            "edition": "Professional", "release": "22H2", "build": "19045.3803",
                                            "windows": "10"}
    eleven = WINDOWS_10_OS.replace("19045", "26100").replace("22H2", "24H2")  # its ProductName says Windows 10
    assert real.parse_os(eleven)["windows"] == "11"


@pytest.fixture(scope="module")
def wine(docker, device_images):
    """A Wine device (the same control server and `cmd` as the real backend's)."""
    from jarvis_pytest.bench.probe import boot

    with boot(device_images["windows"], platform="windows", client=docker) as booted:
        yield booted.device


@pytest.mark.containers
def test_the_os_and_programs_probes_run_on_a_windows_device(wine):
    system = real.device_os(wine)
    assert system["version"].startswith("10.0.") and system["windows"] == "10" and system["product"], system
    found = real.programs_found(wine, ["notepad", "wordpad", "mspaint"])
    assert found["notepad"] and found["wordpad"].lower().endswith("wordpad.exe") and found["mspaint"] is None


def test_the_programs_probe_runs_again_where_the_device_could_not_start_it():
    """One make test: Wine's cmd answered 9009 "Can't recognize 'C:\\jarvis\\python\\python.exe ...'" for a program
    that exists (the device's `fault`); the probe tries again, and says so where the fault stays."""
    from jarvis_pytest.devices.base import CommandResult

    class Flaky:
        def __init__(self, faults):
            self.faults, self.runs = faults, 0

        def run(self, command, timeout=60.0, user=None):
            self.runs += 1
            if self.runs <= self.faults:
                return CommandResult(9009, "", "Can't recognize ...", fault="python.exe exists but did not start")
            return CommandResult(0, '{"notepad": "C:\\\\windows\\\\notepad.exe"}\r\n', "")

    device = Flaky(2)
    assert real.programs_found(device, ["notepad"]) == {"notepad": "C:\\windows\\notepad.exe"} and device.runs == 3
    with pytest.raises(InfrastructureError, match="exit 9009"):
        real.programs_found(Flaky(DEVICE_FAULT_ATTEMPTS), ["notepad"])


@pytest.mark.containers
def test_a_windows_without_the_librarys_screen_or_programs_is_not_kept(wine, tmp_path):
    @dataclass(frozen=True)
    class Settings720(real.WindowsVMSettings):
        @property
        def screen(self) -> tuple[int, int]:
            return (1280, 720)

    s = real.settings({}, disks=str(tmp_path))
    facts = real.check_device(wine, s, ["notepad", "wordpad"])  # Wine has both, at 1920x1080
    assert facts["screen"] == [1920, 1080] and facts["os"]["windows"] == "10" and facts["programs"]["wordpad"]
    with pytest.raises(InfrastructureError, match=r"the screen is 1920x1080, the library assumes 1280x720"):
        real.check_device(wine, Settings720(disks=tmp_path), ["notepad"])
    with pytest.raises(InfrastructureError, match=r"no msedge, mspaint on this Windows"):
        real.check_device(wine, s)  # every program the kvm templates launch: Wine has no Edge, no Paint


# -- the first-boot (OEM) scripts ---------------------------------------------------------------------------------
def test_first_boot_scripts_install_python_and_the_server_and_start_them_at_logon():
    install = (real.OEM_DIR / "install.bat").read_bytes()
    start = (real.OEM_DIR / "start.bat").read_bytes()
    for script in (install, start):
        assert b"\r\n" in script and b"\n" not in script.replace(b"\r\n", b"")  # cmd wants CRLF
    text = install.decode()
    assert "python-embed.zip" in text and "server.zip" in text and r"C:\jarvis" in text
    assert r"CurrentVersion\Run" in text and "start.bat" in text and "python313._pth" in text
    # a failed look-up of `transfer` while the golden was prepared is not remembered past its snapshot
    assert r"WebClient\Parameters" in text and "ServerNotFoundCacheLifeTimeInSec /t REG_DWORD /d 0" in text
    rule = next(line for line in text.splitlines() if "firewall add rule" in line)
    assert r'program="%J%\python\python.exe"' in rule and "profile=any" in rule and "localport" not in rule
    run = start.decode()
    assert "net use S: http://transfer:5244/" in run and "agentPassword" in run
    assert r"python.exe -m jarvis_pytest.devices.windows.server --port 5000" in run


NET_STUB = r"""import sys
open(r"C:\stubs\net.log", "a").write(sys.argv[2] + "\n")
sys.exit(0 if sys.argv[2] == "{works}" else 2)
"""
NSLOOKUP_ANSWER = "Server:  UnKnown\nAddress:  172.30.0.1\n\nName:    transfer\nAddress:  {addr}\n"
NSLOOKUP_NONE = "Server:  UnKnown\nAddress:  172.30.0.1\n\n*** UnKnown can't find transfer.: Non-existent domain\n"


def start_bat_on_wine(wine, works: str, dns: str, args: str = ""):
    """start.bat in the Wine device's `cmd` (as the VM runs it at logon, or as `start.bat map ADDRESS` after a
    restore), with `net` and `nslookup` played by copies of the embeddable Python (each runs a file named by its
    first argument: `use`, `transfer.`; `net use` succeeds only for the URL `works`) and the server's start shown
    instead of done. Returns /run's answer and the second argument of each `net use`."""
    setup = (r"mkdir C:\stubs 2>nul & del C:\stubs\net.log 2>nul & del C:\jarvis\start.log 2>nul & "
             r"for %f in (python313.dll python313.zip python313._pth) do copy /y C:\jarvis\python\%f C:\stubs\ >nul")
    assert wine.run(setup + r" & copy /y C:\jarvis\python\python.exe C:\stubs\net.exe >nul & "
                    r"copy /y C:\jarvis\python\python.exe C:\stubs\nslookup.exe >nul").returncode == 0
    wine.upload(r"C:\Users\user\use", NET_STUB.replace("{works}", works).encode())
    wine.upload(r"C:\Users\user\transfer", "\n".join(f"print({line!r})" for line in
                                                     dns.format(addr="10.9.8.7").splitlines()).encode())
    script = (real.OEM_DIR / "start.bat").read_bytes().replace(b'start "jarvis" /min', b"echo START")
    wine.upload(r"C:\stubs\start.bat", script)
    out = wine.run(rf"set PATH=C:\stubs;%PATH%&& C:\stubs\start.bat {args}".rstrip(), timeout=120)
    return out, wine.download(r"C:\stubs\net.log").decode().split()


@pytest.mark.containers
@pytest.mark.parametrize("works, dns, tries, mapped", [
    ("http://transfer:5244/", NSLOOKUP_ANSWER, ["http://transfer:5244/"], "S: is http://transfer:5244/"),
    ("http://10.9.8.7:5244/", NSLOOKUP_ANSWER, ["http://transfer:5244/", "http://10.9.8.7:5244/"],
     "S: is http://10.9.8.7:5244/"),
    ("never", NSLOOKUP_ANSWER, ["http://transfer:5244/", "http://10.9.8.7:5244/"] * 5, "S: could not be mapped"),
    ("never", NSLOOKUP_NONE, ["http://transfer:5244/"] * 5, "S: could not be mapped"),
], ids=["by-name", "by-address", "neither", "no-dns-answer"])
def test_logon_maps_s_by_name_then_by_address_with_retries_then_starts_the_server(wine, works, dns, tries, mapped):
    out, net = start_bat_on_wine(wine, works, dns)
    assert "START C:\\jarvis\\python\\python.exe -m jarvis_pytest.devices.windows.server" in out.stdout, out
    assert net == ["/delete", *tries]  # a stale S: goes first
    log = wine.download(r"C:\jarvis\start.log").decode()
    assert mapped in log and log.rstrip().endswith("starting the control server"), log


@pytest.mark.containers
@pytest.mark.parametrize("works, dns, tries, code", [
    ("http://transfer:5244/", NSLOOKUP_NONE, ["http://transfer:5244/"], 0),
    ("http://20.20.20.100:5244/", NSLOOKUP_NONE, ["http://transfer:5244/", "http://20.20.20.100:5244/"], 0),
    ("http://20.20.20.100:5244/", NSLOOKUP_ANSWER,
     ["http://transfer:5244/", "http://10.9.8.7:5244/", "http://20.20.20.100:5244/"], 0),
    ("never", NSLOOKUP_NONE, ["http://transfer:5244/", "http://20.20.20.100:5244/"] * 5, 1),
], ids=["by-name", "by-the-given-address", "after-dns", "neither"])
def test_after_a_restore_s_is_mapped_with_the_drives_address_as_the_last_resort(wine, works, dns, tries, code):
    """What the VM runner runs through the control server once a task's VM is restored (`vm_windows.MAP_DRIVE`):
    S: mapped by name, by DNS's address, then by the drive's forwarded address, 5 rounds; the exit code says
    whether it is mapped (the runner fails the boot otherwise, with start.bat's log); the server is not started
    again."""
    assert vm_windows.MAP_DRIVE == r"C:\jarvis\start.bat map 20.20.20.100"
    out, net = start_bat_on_wine(wine, works, dns, "map 20.20.20.100")
    assert out.returncode == code and "START" not in out.stdout, out
    assert net == ["/delete", *tries]
    if code == 0:
        assert f"S: is {works}" in out.stdout, out
    else:
        assert "S: could not be mapped" in out.stderr and "round 5" in out.stderr, out
    log = wine.download(r"C:\jarvis\start.log").decode()
    assert "map S: after a restore" in log and "starting the control server" not in log, log


def test_oem_bundle_carries_the_official_python_with_its_licence_and_the_server(tmp_path):
    folder = real.oem_bundle(tmp_path / "oem")
    assert sorted(p.name for p in folder.iterdir()) == ["install.bat", "python-embed.zip", "server.zip", "start.bat"]
    py = zipfile.ZipFile(folder / "python-embed.zip")
    names = set(py.namelist())
    assert {"python.exe", "LICENSE.txt", "python313.zip", "_ctypes.pyd", "_socket.pyd"} <= names
    assert py.read("python.exe")[:2] == b"MZ"  # a Windows executable
    server = zipfile.ZipFile(io.BytesIO((folder / "server.zip").read_bytes()))
    names = server.namelist()
    assert {"jarvis_pytest/devices/windows/server/__main__.py", "jarvis_pytest/devices/control_http.py",
            "jarvis_pytest/devices/pyautogui_compat.py", "jarvis_pytest/devices/windows/__init__.py",
            "jarvis_pytest/devices/png.py", "jarvis_pytest/devices/windows/server/screen.py",
            "jarvis_pytest/devices/windows/server/system.py"} <= set(names)  # system.resolve: the programs probe
    # the package imports nothing beyond the standard library on the device: no pydantic, no httpx
    for name in names:
        text = server.read(name).decode()
        assert "import pydantic" not in text and "from pydantic" not in text and "import httpx" not in text, name


def test_a_template_for_the_real_backend_is_skipped_here_with_its_reason(tmp_path):
    """An application only a real Windows has (Paint): on this machine (Wine) the instance is skipped, with the
    reason and the command that would run it, counted apart — never failed, nothing booted."""
    tpl = {
        "id": "windows-paint-save_png", "platform": "windows", "app": "Paint", "backends": ["kvm"],
        "instruction": "Save {{image}} as PNG.",
        "inputs": {"image": {"type": "image_file", "choices": ["C:\\Users\\user\\Pictures\\a.bmp"]}},
        "config": [{"type": "upload_file", "path": "{{image}}", "content": "x"}],
        "evaluate": [{"func": "file_exists", "args": {"path": "{{image}}"}}],
    }
    lib = tmp_path / "lib"
    (lib / "windows").mkdir(parents=True)
    (lib / "windows" / "paint.json").write_text(json.dumps(tpl))
    run = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist", "-rs",
                           str(REPO / "tasks" / "test_atomic.py"), "--library", str(lib), "--instances", "1",
                           "--agent", "noop", "--results-dir", str(run)],
                          cwd=REPO, capture_output=True, text=True, timeout=300,
                          env={**os.environ, "JARVIS_WINDOWS_DISKS": str(tmp_path / "no-golden")})
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0 and "1 skipped" in out, out[-3000:]
    assert "needs the windows backend kvm" in out and "jarvis images build --only windows-real" in out
    summary = json.loads((run / "summary.json").read_text())
    assert summary["skipped"]["atomic"] == 1 and summary["atomic"]["overall"]["n"] == 0
    assert "Skipped: cannot run here" in (run / "summary.md").read_text()


# -- the live gate: `make test-windows-real` ----------------------------------------------------------------------
def kvm_sample() -> list[str]:
    """The Windows QC sample on kvm: the first template (by id) of every application the kvm backend may run."""
    from jarvis_pytest.tasks.library import load_library

    first: dict[str, str] = {}
    for tpl in load_library(REPO / "tasks").by_platform("windows"):
        if not tpl.backends or "kvm" in tpl.backends:
            first.setdefault(tpl.app, tpl.id)
    return sorted(first.values())


def test_live_quality_gate():
    """`make test-windows-real`: the Windows QC sample (one template per application, seed 0, its negatives and
    oracle) on the kvm backend, then one report to paste: the golden's image, digest and Windows, and per task what
    passed, what failed and why. Skipped with the reason where there is no prepared KVM Windows (as on the machine
    this was written on), and unless asked (`JARVIS_WINDOWS_LIVE=1`: every task boots a VM)."""
    why = backend_for("windows", "kvm").unavailable()
    if why:
        pytest.skip(f"no KVM Windows here ({why}); to run it: {real.HOW_TO_RUN}; then make test-windows-real")
    if os.environ.get(LIVE_ENV) != "1":
        pytest.skip(f"the live Windows gate boots a VM per task: run it with make test-windows-real ({LIVE_ENV}=1)")
    ids = kvm_sample()
    results = REPO / "reports" / f"windows-real-{datetime.now().strftime('%Y%m%d-%H%M%S')}"
    proc = subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "qc", "--platform", "windows", "--instances",
                           "1", "-n", "1", "-k", " or ".join(ids), "--results-dir", str(results), "--",
                           "--windows-backend", "kvm"], cwd=REPO, timeout=8 * 3600)
    table = results / "qc.md"
    ready = real.ready_record() or {}
    report = "\n".join([
        "## jarvis-pytest: first run of the kvm Windows backend",
        f"image: {ready.get('image')}; dockur {ready.get('dockur_version')}; VERSION={ready.get('version')}",
        f"Windows: {ready.get('os')}; screen {ready.get('screen')}; prepared {ready.get('prepared')}",
        f"memory snapshot: {ready.get('snapshot')}",
        f"sample: {', '.join(ids)}", f"results: {results} (jarvis qc exit {proc.returncode})", "",
        table.read_text() if table.exists() else "no qc.md: jarvis qc ran no task; its output is above"])
    print("\n" + report)
    assert proc.returncode == 0, report
