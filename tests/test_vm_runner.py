"""The VM runner (`jarvis_pytest/devices/vm/`): per-task VMs restored from a memory snapshot.

Unit tests: the QEMU command lines, the machine profile's checks, the golden's rules (a restore refuses a golden
whose profile, QEMU, files or state differ from what was saved; a state stream must be complete), the Windows
profile read from dockur/windows v6.05 (on qemus/qemu v7.48), a task container's options.

The TCG proof (containers): a small Linux guest (Debian's kernel, `fixtures/images/vm-guest/`) is prepared once
per machine through the same code a Windows golden would be, two tasks are restored from it in parallel by the
harness's own `Lifecycle`, and the test shows what a snapshot must give: state from before it (on disk and only in
memory), a corrected clock, reseeded randomness, a task's changes kept from the next task, the drive reachable on
the task network and nothing else, nothing left behind. It prints the restore figures (`-s` shows them).
"""

from __future__ import annotations

import json
import os
import shutil
import struct
import time
import uuid
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from jarvis_pytest.devices.vm import golden
from jarvis_pytest.devices.vm import windows as win
from jarvis_pytest.devices.vm.backend import restore_figures, task_options, vm_backend
from jarvis_pytest.devices.vm.prepare import failure_of, prepare_snapshot
from jarvis_pytest.devices.vm.profile import RUNNER_PORT, Profile
from jarvis_pytest.devices.vm.runner import EXIT_CONFIG, events, relay_command
from jarvis_pytest.devices.vm.testguest import PROFILE
from jarvis_pytest.errors import ConfigError, InfrastructureError

QEMU = "QEMU emulator version 7.2.22 (Debian 1:7.2+dfsg-7+deb12u18+b3)"


def option(args: list[str], flag: str) -> list[str]:
    """Every value given to `flag` in a command line, in order."""
    return [args[i + 1] for i, a in enumerate(args[:-1]) if a == flag]


# -- the command line -------------------------------------------------------------------------------------------
def test_the_command_line_is_the_profile_and_nothing_else():
    args = PROFILE.command(root="/golden", disk="/task/disk.qcow2", qmp="/run/vm/qmp.sock",
                           console="/run/vm/console.log", vmgenid="0c3d2e8f-0000-4000-8000-000000000001")
    assert args[0] == "qemu-system-x86_64" and "-nodefaults" in args and "-no-user-config" in args
    assert option(args, "-machine") == ["q35"] and option(args, "-accel") == ["tcg"]
    assert option(args, "-cpu") == ["qemu64"] and option(args, "-smp") == ["1"] and option(args, "-m") == ["256M"]
    assert option(args, "-kernel") == ["/golden/vmlinuz"] and option(args, "-initrd") == ["/golden/initrd.img"]
    assert "init=/sbin/jarvis-init" in option(args, "-append")[0]
    # the VM writes only its own overlay; the golden's files are read
    assert option(args, "-drive") == ["file=/task/disk.qcow2,if=none,id=disk0,format=qcow2,cache=writeback,"
                                      "aio=threads,discard=unmap,detect-zeroes=unmap"]
    assert option(args, "-device") == ["virtio-blk-pci,drive=disk0,bootindex=1",
                                       "virtio-net-pci,netdev=net0,mac=52:54:00:12:34:56,romfile=",
                                       "vmgenid,id=vmgenid0,guid=0c3d2e8f-0000-4000-8000-000000000001"]
    assert option(args, "-qmp") == ["unix:/run/vm/qmp.sock,server=on,wait=off"]
    assert "-incoming" not in args and "-S" not in args and args[-1] == "-no-reboot"
    restore = PROFILE.command(root="/golden", disk="/task/disk.qcow2", qmp="q", console="c", incoming=True)
    assert restore[-3:] == ["-incoming", "defer", "-S"]  # loaded, then resumed by the runner (`cont`)
    same = [a for a in restore[:-3] if not a.startswith(("vmgenid", "unix:", "file,id=console"))]
    assert same == [a for a in args if not a.startswith(("vmgenid", "unix:", "file,id=console"))]


def test_the_guest_network_reaches_the_control_forward_and_the_drive_only():
    netdev = option(PROFILE.command(root="/g", disk="d", qmp="q", console="c"), "-netdev")
    assert netdev == [PROFILE.netdev()]
    parts = netdev[0].split(",")
    assert parts[0] == "user" and "restrict=on" in parts  # slirp routes nothing of the guest's out ...
    # ... but the forwards: the runner's own (container loopback) and the one drive address
    assert [p for p in parts if p.startswith("hostfwd=")] == [f"hostfwd=tcp:127.0.0.1:{RUNNER_PORT}-10.0.2.15:5000"]
    assert [p for p in parts if p.startswith("guestfwd=")] == [
        "guestfwd=tcp:10.0.2.100:5244-cmd:socat - TCP:transfer:5244"]
    # the container's control port is a relay to the runner's loopback forward, started once the guest is ready
    assert relay_command(PROFILE) == ["socat", "TCP-LISTEN:5000,fork,reuseaddr", f"TCP:127.0.0.1:{RUNNER_PORT}"]


def test_uefi_firmware_gives_read_only_code_and_the_vms_own_variables():
    p = Profile(name="uefi", firmware="code.fd", firmware_vars="vars.fd")
    args = p.command(root="/golden", disk="/task/disk.qcow2", firmware_vars="/task/vars.fd", qmp="q", console="c")
    assert option(args, "-drive")[:2] == ["file=/golden/code.fd,if=pflash,unit=0,format=raw,readonly=on",
                                          "file=/task/vars.fd,if=pflash,unit=1,format=raw"]
    assert "-kernel" not in args


# -- the profile's checks ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("change, field", [
    ({"colour": "red"}, "colour"),
    ({"memory_mb": "256"}, "memory_mb"),
    ({"vmgenid": 1}, "vmgenid"),
    ({"devices": "virtio-blk-pci"}, "devices"),
    ({"accel": "hvf"}, "accel"),
    ({"disk": "../disk.qcow2"}, "disk"),
    ({"devices": ["virtio-net-pci,netdev=net0"]}, "devices"),           # nothing uses the disk
    ({"guest_ip": "192.168.1.5"}, "guest_ip"),
    ({"drive_ip": "10.0.2.15"}, "drive_ip"),
    ({"clock_command": "date -s @{when}"}, "clock_command"),
    ({"initrd": "initrd.img", "kernel": ""}, "kernel"),
])
def test_a_bad_profile_is_one_error_naming_its_field(change, field):
    data = {**PROFILE.to_dict(), **change}
    with pytest.raises(ConfigError) as err:
        Profile.from_dict(data, where="profile.json")
    assert err.value.field == field and "profile.json" in str(err.value)


def test_a_profile_without_a_name_is_refused_and_a_good_one_survives_json():
    with pytest.raises(ConfigError, match="name"):
        Profile.from_dict({"memory_mb": 256})
    assert Profile.from_dict(json.loads(PROFILE.to_json())) == PROFILE


# -- the golden's rules -----------------------------------------------------------------------------------------
def stream(devices: int = 3) -> bytes:
    """A migration stream as QEMU 7.2 ends one: header, sections, the end mark, the device description."""
    desc = json.dumps({"page_size": 4096, "devices": [{"name": f"d{i}"} for i in range(devices)]}).encode()
    return golden.MAGIC + b"\x07" + os.urandom(4096) + b"\x00" + bytes([golden.VMDESC]) + struct.pack(
        ">I", len(desc)) + desc


def make_golden(folder: Path, profile: Profile = PROFILE) -> Path:
    """A prepared golden as the runner leaves one, with small stand-ins for the disk and the state."""
    snap = folder / golden.SNAPSHOT
    snap.mkdir(parents=True)
    for name in profile.files():
        (folder / name).write_bytes(os.urandom(512))
    (snap / golden.DISK).write_bytes(b"QFI\xfb" + os.urandom(512))
    (snap / golden.STATE).write_bytes(stream())
    files = {rel: golden.file_stamp(folder / rel) for rel in golden.recorded_files(folder, profile)}
    size = (snap / golden.STATE).stat().st_size
    golden.write_record(folder, golden.Record(profile=profile, qemu=QEMU, source={"test": True}, state_bytes=size,
                                              state_sha256=golden.sha256_of(snap / golden.STATE), files=files,
                                              created=time.time()))
    return folder


def test_a_golden_restores_only_with_its_profile_and_qemu(tmp_path):
    g = make_golden(tmp_path / "g")
    assert golden.check(g, PROFILE, QEMU).qemu == QEMU
    import dataclasses

    with pytest.raises(ConfigError) as err:
        golden.check(g, dataclasses.replace(PROFILE, memory_mb=512))
    assert err.value.field == "profile.memory_mb" and "saved 256, asked 512" in str(err.value)
    with pytest.raises(ConfigError) as err:
        golden.check(g, dataclasses.replace(PROFILE, devices=tuple(reversed(PROFILE.devices))))
    assert err.value.field == "profile.devices"  # the same devices in another order are another machine
    # how the guest's clock is set and where its drive address leads are not the machine: they may change
    golden.check(g, dataclasses.replace(PROFILE, clock_command="date -s @{epoch:.0f}", drive_target="drive:80",
                                        after_restore=("mount -a",)))
    with pytest.raises(ConfigError) as err:
        golden.check(g, PROFILE, "QEMU emulator version 8.2.2")
    assert err.value.field == "qemu" and "vm-runner" in str(err.value)


def test_a_golden_without_ready_or_with_changed_files_is_refused(tmp_path):
    g = make_golden(tmp_path / "g")
    (g / "vmlinuz").write_bytes(os.urandom(512))  # same size, written again: the guest's memory no longer matches
    with pytest.raises(ConfigError) as err:
        golden.check(g, PROFILE)
    assert err.value.field == "files.vmlinuz" and "changed since" in str(err.value)
    g = make_golden(tmp_path / "g2")
    (g / golden.SNAPSHOT / golden.DISK).unlink()
    with pytest.raises(ConfigError, match="missing"):
        golden.check(g, PROFILE)
    g = make_golden(tmp_path / "g3")
    golden.ready_path(g).unlink()
    with pytest.raises(ConfigError, match="prepare never finished") as err:
        golden.check(g, PROFILE)
    assert "prepare_snapshot" in str(err.value)
    golden.ready_path(g).write_text("{not json")
    with pytest.raises(ConfigError, match="cannot read"):
        golden.check(g, PROFILE)


def test_an_incomplete_state_is_refused(tmp_path):
    g = make_golden(tmp_path / "g")
    state = g / golden.SNAPSHOT / golden.STATE
    golden.check_stream(state)
    data = state.read_bytes()
    for cut in (1, 100, len(data) // 2):
        state.write_bytes(data[:-cut])
        with pytest.raises(ConfigError, match="incomplete"):
            golden.check_stream(state)
    state.write_bytes(data[:-1] + b"x")  # the same size, the end of its description damaged
    with pytest.raises(ConfigError, match="incomplete"):
        golden.check_stream(state)
    # a restore checks the recorded size: a state cut short after READY was written is refused
    g = make_golden(tmp_path / "g2")
    state = g / golden.SNAPSHOT / golden.STATE
    stamp = golden.file_stamp(state)
    with state.open("r+b") as f:
        f.truncate(stamp[0] - 10)
    os.utime(state, ns=(stamp[1], stamp[1]))
    with pytest.raises(ConfigError, match="incomplete") as err:
        golden.check(g, PROFILE)
    assert err.value.field == "state_bytes"
    state.write_bytes(b"not a stream" + b"\0" * 100)
    with pytest.raises(ConfigError, match="not a QEMU migration stream"):
        golden.check_stream(state)


def test_prepare_refuses_a_golden_without_the_profiles_files_before_any_container(tmp_path):
    (tmp_path / "vmlinuz").write_bytes(b"k")
    with pytest.raises(ConfigError) as err:
        prepare_snapshot(tmp_path, PROFILE, docker=object())
    assert err.value.field == "profile.disk" and str(tmp_path / "disk.qcow2") in str(err.value)
    with pytest.raises(ConfigError, match="does not exist"):
        prepare_snapshot(tmp_path / "nowhere", PROFILE, docker=object())


def test_a_vm_backend_refuses_an_unprepared_golden_before_any_container(tmp_path):
    from jarvis_pytest.infra.containers import BootRequest

    backend = vm_backend("vm-test-unprepared", tmp_path, PROFILE)
    assert "prepare never finished" in backend.unavailable()
    request = BootRequest(docker=None, name="x", network=None, labels={}, memory=None, cpus=None, ready_timeout=1)
    with pytest.raises(ConfigError, match="prepare never finished"):
        backend.boot(request)
    assert request.started == []


# -- a task container's options ---------------------------------------------------------------------------------
def test_a_task_container_mounts_the_golden_read_only_and_restores(tmp_path):
    options = task_options(tmp_path, PROFILE)
    assert options["command"] == ["restore"]
    assert options["volumes"] == {str(tmp_path.resolve()): {"bind": "/golden", "mode": "ro"}}
    assert Profile.from_dict(json.loads(options["environment"]["JARVIS_VM"])["profile"]) == PROFILE
    assert "devices" not in options  # TCG: no /dev/kvm
    backend = vm_backend("vm-test-options", tmp_path, PROFILE)
    assert backend.image_ref == "jarvis/vm-runner:latest" and backend.port == 5000 and backend.memory == "768m"
    assert backend.container_options == options and backend.label == "vm-test-options (vm)"


def test_the_runner_reports_bad_input_as_a_config_error_naming_the_host_path():
    class Container:
        name = "jarvis-vm-x"

    logs = "\n".join(["boot noise", json.dumps({"vm": "error", "kind": "config", "message":
                                                "/golden/snapshot/READY: field 'qemu': saved by A (fix: prepare)"})])
    assert events(logs) == [json.loads(logs.splitlines()[1])]
    err = failure_of(Container(), EXIT_CONFIG, logs, Path("/cache/g"))
    assert isinstance(err, ConfigError) and str(err).startswith("/cache/g/snapshot/READY: field 'qemu'")
    err = failure_of(Container(), 3, logs.replace('"config"', '"vm"'), Path("/cache/g"))
    assert isinstance(err, InfrastructureError) and "exited with code 3" in str(err)


# -- the Windows profile (dockur/windows v6.05 on qemus/qemu v7.48) ---------------------------------------------
def dockur_storage(folder: Path, **changes: str | None) -> Path:
    """What dockur v6.05 leaves in /storage after installing Windows 10 and a clean shutdown (install.sh:403-404
    windows.ver from the image's /etc/version, 416-417 windows.base; power.sh:401 windows.boot; qemus/qemu boot.sh:128,
    173, 202 windows.rom and windows.vars; network.sh:2131 windows.mac, upper case)."""
    files = {"data.qcow2": "disk", "windows.rom": "code", "windows.vars": "vars", "windows.boot": "",
             "windows.mac": "02:7A:EC:01:02:03\n", "windows.ver": "6.05\n", "windows.base": "win10x64.iso\n"}
    files.update(changes)
    folder.mkdir()
    for name, content in files.items():
        if content is not None:
            (folder / name).write_text(content)
    return folder


INTEL = "processor\t: 0\nvendor_id\t: GenuineIntel\nflags\t\t: fpu vme vmx tsc\n"
AMD = "processor\t: 0\nvendor_id\t: AuthenticAMD\nflags\t\t: fpu vme svm tsc_scale\n"


def test_the_windows_profile_is_dockur_6_05s_machine_made_migratable(tmp_path):
    p = win.profile_from_storage(dockur_storage(tmp_path / "storage"), ram_mb=4096, cores=2, cpuinfo=INTEL)
    args = p.command(root="/golden", disk="/task/disk.qcow2", firmware_vars="/task/windows.vars", qmp="q",
                     console="c")
    assert p.name == "windows-10-dockur-6.05"  # the release is recorded with the snapshot (READY's profile)
    # qemus/qemu v7.48 config.sh:87-88: type=q35,smm=off (boot.sh:393),graphics=off,vmport=off,dump-guest-core=off,
    # hpet=off; accel=kvm (proc.sh:70)
    assert option(args, "-machine") == ["q35,smm=off,graphics=off,vmport=off,dump-guest-core=off,hpet=off"]
    assert option(args, "-accel") == ["kvm"] and option(args, "-m") == ["4096M"]  # config.sh:40, RAM_SIZE 4G
    assert option(args, "-smp") == ["2,sockets=1,dies=1,cores=2,threads=1"]  # config.sh:14
    cpu = option(args, "-cpu")[0].split(",")
    # proc.sh:67-81: host,kvm=on,l3-cache=on,+hypervisor (VM=Y, proc.sh:237),... -vmx (VMX=N for Windows, 246-259)
    assert cpu[:6] == ["host", "kvm=on", "l3-cache=on", "+hypervisor", "migratable=on", "-vmx"]
    assert "hv-time" in cpu and "arch_capabilities=off" not in cpu  # AMD hosts only (proc.sh:93-95)
    assert not {"migratable=no", "hv_passthrough", "hv-passthrough", "+invtsc"} & set(cpu)  # those block a save
    amd = win.profile_from_storage(tmp_path / "storage", cpuinfo=AMD).cpu.split(",")
    assert amd[:7] == cpu[:6] + ["arch_capabilities=off"] and "+invtsc" not in amd
    assert option(args, "-rtc") == ["base=localtime"] and option(args, "-vga") == ["virtio"]  # boot.sh:114, display:7
    assert option(args, "-global") == ["ICH9-LPC.disable_s3=1", "ICH9-LPC.disable_s4=1",  # boot.sh:116-119
                                       "kvm-pit.lost_tick_policy=discard"]                # proc.sh:70
    assert option(args, "-drive")[:2] == ["file=/golden/windows.rom,if=pflash,unit=0,format=raw,readonly=on",
                                          "file=/task/windows.vars,if=pflash,unit=1,format=raw"]  # boot.sh:227-228
    # disk.sh:565: discard=unmap (DISK_DISCARD, disk.sh:14), detect-zeroes=on; cache and aio are the host's
    assert option(args, "-drive")[2].endswith(",discard=unmap,detect-zeroes=on")
    assert option(args, "-object") == ["iothread,id=io2",                              # disk.sh:707
                                       "rng-random,id=objrng0,filename=/dev/urandom"]  # config.sh:108
    # dockur's devices in dockur's order (slots are given in order): USB (config.sh:144-151), NIC (network.sh:2379),
    # disk at 0xa with hotplug=off, SCSI disk at boot index 3 (disk.sh:595-596, 1179-1180), RNG (config.sh:109)
    assert option(args, "-device")[:6] == [
        "qemu-xhci,id=xhci,p2=7,p3=7", "usb-tablet",
        "virtio-net-pci,id=net0,netdev=net0,romfile=,mac=02:7A:EC:01:02:03",
        "virtio-scsi-pci,id=disk0b,bus=pcie.0,addr=0xa,iothread=io2,hotplug=off",
        "scsi-hd,drive=disk0,bus=disk0b.0,channel=0,scsi-id=0,lun=0,rotation_rate=1,bootindex=3",
        "virtio-rng-pci,rng=objrng0,id=rng0,bus=pcie.0"]
    assert option(args, "-device")[6].startswith("vmgenid,") and len(option(args, "-device")) == 7
    assert option(args, "-fw_cfg") == ["name=opt/org.tianocore/UninstallMemAttrProtocol,string=y"]  # config.sh:236
    assert "net=20.20.20.0/24" in p.netdev() and "dhcpstart=20.20.20.21" in p.netdev()
    assert "guestfwd=tcp:20.20.20.100:5244-cmd:socat - TCP:transfer:5244" in p.netdev()
    clock = p.clock_command.format(epoch=1.5)
    assert "Set-Date" in clock and "[long](1.500*1000)" in clock and "(Get-Process -Id $PID).StartTime" in clock
    # after a restore S: is mapped (start.bat's `map`: the name, DNS's address, then the drive's forwarded address)
    assert p.after_restore == ("C:\\jarvis\\start.bat map 20.20.20.100",)
    assert task_options(tmp_path / "storage", p)["devices"] == ["/dev/kvm:/dev/kvm:rwm"]
    raw = win.profile_from_storage(dockur_storage(tmp_path / "raw", **{"data.qcow2": None, "data.img": "d"}),
                                   cpuinfo=INTEL)
    assert (raw.disk, raw.disk_format) == ("data.img", "raw")


def test_which_cpu_dockur_calls_amd_is_read_from_the_first_vendor_id():
    assert win.amd_host(AMD) and not win.amd_host(INTEL) and not win.amd_host("")
    assert not win.amd_host(INTEL.replace("flags", "model name\t: Intel(R) Xeon(R) (AMD64)\nflags"))
    assert win.cpu(True).split(",")[6] == "arch_capabilities=off" and "arch_capabilities=off" not in win.cpu(False)


@pytest.mark.parametrize("changes, where, words", [
    ({"windows.boot": None}, "windows.boot", "lacks"),
    ({"windows.ver": None}, "windows.ver", "lacks"),
    ({"windows.ver": "4.35\n"}, "windows.ver", "installed by dockur/windows '4.35'"),
    ({"windows.ver": "6.06\n"}, "windows.ver", "installed by dockur/windows '6.06'"),
    ({"windows.mode": "windows_secure\n"}, "windows.mode", "mode"),
    ({"windows.vars": None}, "windows.vars", "UEFI"),
    ({"windows.mac": None}, "windows.mac", "lacks"),
    ({"data.qcow2": None}, "storage", "no disk"),
])
def test_a_storage_that_is_not_dockur_6_05s_windows_10_is_one_error_naming_the_file(tmp_path, changes, where, words):
    with pytest.raises(ConfigError) as err:
        win.profile_from_storage(dockur_storage(tmp_path / "storage", **changes), cpuinfo=INTEL)
    assert err.value.path.endswith(where) and words in str(err.value) and err.value.fix


# -- the TCG proof ----------------------------------------------------------------------------------------------
PLATFORM = "vm-test"
BEFORE_SNAPSHOT = (
    "echo golden-disk > /root/before-snapshot.txt && sync",          # on the disk
    "echo golden-memory > /run/before-snapshot.txt",                 # on a tmpfs: only in memory
    "cat /proc/sys/kernel/random/boot_id",                           # this boot
    "cut -d' ' -f1,22 /proc/$(pgrep -o -f devices.vm.guest_server)/stat",  # the server process: pid, start time
)
MIN_SNAPSHOT_AGE = 5.0  # seconds between the save and a restore: an uncorrected clock would be this far behind
# Run by the runner after the clock, before the VM is ready (as a Windows guest maps S:): the drive must answer then.
AFTER_RESTORE = ("python3 -c \"import socket; socket.create_connection(('transfer', 5244), 10).close()\" && "
                 "date +%s.%N > /run/after-restore",)


def leftovers(docker, run_id: str) -> dict[str, list[str]]:
    label = {"label": f"org.jarvis.run={run_id}"}
    return {"containers": [c["Names"][0] for c in docker.api.containers(all=True, filters=label)],
            "networks": [n["Name"] for n in docker.api.networks(filters=label)],
            "volumes": [v["Name"] for v in docker.api.volumes(filters=label).get("Volumes") or []]}


def listing(folder: Path) -> dict[str, list[int]]:
    return {str(p.relative_to(folder)): golden.file_stamp(p) for p in sorted(folder.rglob("*"))
            if p.is_file() and not p.name.endswith(".lock")}


@pytest.mark.containers
def test_tasks_restore_in_parallel_from_a_memory_snapshot_under_tcg(device_images):
    from jarvis_pytest.devices.backend import register_backend
    from jarvis_pytest.devices.vm import testguest
    from jarvis_pytest.infra import egress
    from jarvis_pytest.infra.cleanup import cleanup
    from jarvis_pytest.infra.engine import client
    from jarvis_pytest.environments.lifecycle import Lifecycle

    docker = client()
    t0 = time.monotonic()
    folder, record, prepared = testguest.ensure_golden(docker, commands=BEFORE_SNAPSHOT)
    prepare_wall = time.monotonic() - t0
    boot_id, server = record.outputs[2].strip(), record.outputs[3].strip()
    before = listing(folder)
    import dataclasses

    # after_restore is not part of the machine: a golden saved without it restores with it
    register_backend(vm_backend(PLATFORM, folder, dataclasses.replace(testguest.PROFILE, after_restore=AFTER_RESTORE)))
    age = time.time() - record.created
    if age < MIN_SNAPSHOT_AGE:
        time.sleep(MIN_SNAPSHOT_AGE - age)
    run_id = f"test-{uuid.uuid4().hex[:8]}"
    lifecycle = Lifecycle(run_id, "test")
    envs: list = []
    figures: dict[str, dict] = {}

    def boot(name: str):
        t = time.monotonic()
        env = lifecycle.boot((PLATFORM,))
        envs.append(env)
        figures[name] = {"environment": time.monotonic() - t, **restore_figures(env.containers[PLATFORM])}
        return env

    def close(name: str, env) -> None:
        t = time.monotonic()
        env.close()
        figures[name]["teardown"] = time.monotonic() - t

    try:
        with ThreadPoolExecutor(2) as pool:
            a, b = pool.map(boot, ("A", "B"))
        da, db = a.devices[PLATFORM], b.devices[PLATFORM]
        for d in (da, db):
            # state from before the snapshot: the disk's file, the tmpfs file, the same boot, the same server process
            assert d.download("/root/before-snapshot.txt") == b"golden-disk\n"
            assert d.download("/run/before-snapshot.txt") == b"golden-memory\n"
            assert d.run("cat /proc/sys/kernel/random/boot_id").stdout.strip() == boot_id
            assert d.run(BEFORE_SNAPSHOT[3]).stdout.strip() == server
            # the wall clock is now's, not the snapshot's (which is at least MIN_SNAPSHOT_AGE s behind)
            off = float(d.run("date +%s.%N").stdout) - time.time()
            assert abs(off) < 2.0, f"guest clock off by {off:.1f} s (snapshot {time.time() - record.created:.0f} s old)"
            # a new VM generation ID: the kernel reseeded its random number generator
            assert "crng reseeded due to virtual machine fork" in d.run("dmesg").stdout
            # the profile's after_restore ran before the VM was ready, once the clock was set, with the drive there
            ran = float(d.download("/run/after-restore"))
            assert abs(ran - time.time()) < 60, f"after_restore ran at {ran}, now is {time.time()}"
        assert da.run("cat /proc/sys/kernel/random/uuid").stdout != db.run("cat /proc/sys/kernel/random/uuid").stdout
        # each task writes its own overlay: neither sees the other's change
        da.upload("/root/task.txt", b"A")
        db.upload("/root/task.txt", b"B")
        da.run("echo changed-by-A > /root/before-snapshot.txt && sync")
        assert (da.download("/root/task.txt"), db.download("/root/task.txt")) == (b"A", b"B")
        assert db.download("/root/before-snapshot.txt") == b"golden-disk\n"
        # the guest reaches its task's drive (the forwarded address, the name in its hosts file) ...
        put = ("python3 -c \"import urllib.request as u; print(u.urlopen(u.Request('http://transfer:5244/data/"
               "from-vm.txt', data=b'sent by the A guest', method='PUT', headers={'PW': 'agentPassword'}), "
               "timeout=20).status)\"")
        assert da.run(put, timeout=60).stdout.strip() == "201"
        assert a.transfer.download("/data/from-vm.txt") == b"sent by the A guest"
        assert "/data/from-vm.txt" not in b.transfer.walk("/data")  # B's drive is another (task network) one
        # ... and has no other route: none in the guest, none in its container, slirp restricted to the forwards
        for env, d in ((a, da), (b, db)):
            assert not [r for r in d.run("ip route").stdout.splitlines() if r.startswith("default")]
            routes = egress.device_routes(env.containers[PLATFORM])
            assert routes and not [r for r in routes if r.startswith("default")], routes
            qemu = [p[-1] for p in env.containers[PLATFORM].top()["Processes"] if "qemu-system" in p[-1]]
            assert len(qemu) == 1 and "restrict=on" in qemu[0] and qemu[0].count("guestfwd=") == 1
            assert "guestfwd=tcp:10.0.2.100:5244-cmd:socat - TCP:transfer:5244" in qemu[0]
            assert qemu[0].count("hostfwd=") == 1 and "hostfwd=tcp:127.0.0.1:" in qemu[0]
        for name, env in (("A", a), ("B", b)):
            close(name, env)
        # the next task starts from the golden, not from what a task did
        c = boot("C")
        dc = c.devices[PLATFORM]
        assert not dc.exists("/root/task.txt")
        assert dc.download("/root/before-snapshot.txt") == b"golden-disk\n"
        assert dc.download("/run/before-snapshot.txt") == b"golden-memory\n"
        close("C", c)
    finally:
        for env in envs:
            env.close()  # idempotent
        lifecycle.close()
        left = leftovers(docker, run_id)
        cleanup(run_id)
    assert left == {"containers": [], "networks": [], "volumes": []}  # overlays lived in the containers' layers
    assert listing(folder) == before  # the golden is read, never written
    golden.check(folder, testguest.PROFILE)
    print(f"\n[vm-runner] golden {folder.name}: {'prepared now' if prepared else 'cached'} "
          f"(ensure_golden {prepare_wall:.1f} s); its cold boot to control server {record.timings['boot_to_ready']:.1f}"
          f" s, memory save {record.timings['save']:.2f} s, state {record.state_bytes / 2**20:.0f} MiB; {record.qemu}")
    for name in ("A", "B", "C"):
        f = figures[name]
        assert "after_restore" in f["phases"], f
        phases = ", ".join(f"{k} {v:.2f}" for k, v in f["phases"].items())
        print(f"[vm-runner] task {name}{' (parallel)' if name != 'C' else ' (next)'}: VM created→ready "
              f"{f['created_to_ready']:.2f} s (runner {f['seconds']:.2f} s: {phases}); environment with network "
              f"and drive {f['environment']:.2f} s; teardown {f['teardown']:.2f} s")


@pytest.mark.containers
def test_a_restore_refuses_a_state_saved_by_another_qemu(device_images):
    """The runner's own check (the host cannot know the runner image's QEMU): exit 2, one ConfigError."""
    from jarvis_pytest.devices.vm import testguest
    from jarvis_pytest.infra.cleanup import cleanup
    from jarvis_pytest.environments.lifecycle import Lifecycle
    from jarvis_pytest.devices.backend import register_backend

    folder, _, _ = testguest.ensure_golden(commands=BEFORE_SNAPSHOT)
    copy = folder.parent / f"test-{uuid.uuid4().hex[:8]}"
    try:
        shutil.copytree(folder, copy, copy_function=os.link, ignore=shutil.ignore_patterns("READY", "*.lock"))
        data = json.loads(golden.ready_path(folder).read_text())
        golden.ready_path(copy).write_text(json.dumps({**data, "qemu": "QEMU emulator version 6.2.0"}))
        register_backend(vm_backend("vm-test-qemu", copy, testguest.PROFILE))
        run_id = f"test-{uuid.uuid4().hex[:8]}"
        lifecycle = Lifecycle(run_id, "test")
        try:
            with pytest.raises(ConfigError) as err:
                lifecycle.boot(("vm-test-qemu",))
        finally:
            lifecycle.close()
            cleanup(run_id)
        assert "saved by 'QEMU emulator version 6.2.0'" in str(err.value) and str(copy) in str(err.value)
    finally:
        shutil.rmtree(copy, ignore_errors=True)
