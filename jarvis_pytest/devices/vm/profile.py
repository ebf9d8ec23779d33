"""A machine profile: everything about a VM that must be identical when its memory state is saved and when it is
restored (machine type, CPU, RAM, firmware, disk and NIC models, device order, extra arguments), and the QEMU
command line built from it. The profile is recorded with the golden (`golden.py`); a restore with another one is
refused, naming the fields that differ.

Files a profile names (disk, kernel, firmware) are names inside the golden folder. Devices are QEMU `-device`
values in the order given: QEMU places a device without `addr=` in the next free PCI slot, so the order is part of
the machine the guest sees. The disk is the drive `disk0`, the NIC's back end the netdev `net0` (QEMU user-mode
networking, slirp: the guest reaches the control port forwarded to it and one address forwarded to the task's
drive, nothing else: `restrict=on`).
"""

from __future__ import annotations

import dataclasses
import ipaddress
import json
from dataclasses import dataclass
from typing import Any

from jarvis_pytest.errors import ConfigError

DRIVE_ID, NETDEV_ID = "disk0", "net0"
RUNNER_PORT = 5001  # the runner's own forward to the guest's control server, on the container's loopback only
# Fields that are not part of the machine: they may differ between save and restore.
RUNTIME_FIELDS = ("clock_command", "drive_target", "after_restore")


@dataclass(frozen=True)
class Profile:
    """One VM's machine (see the module's docstring). `clock_command` sets the guest's wall clock after a restore,
    through its control server's `/run` (`{epoch}`: seconds since 1970, UTC, a float); `after_restore` are more
    commands run there after it, each of which must exit 0 before the VM counts as ready (e.g. a Windows guest
    maps its drive letter, which the golden could not reach while it was prepared)."""

    name: str
    machine: str = "q35"                  # `-machine` value
    accel: str = "tcg"                    # tcg (anywhere) or kvm (needs /dev/kvm)
    cpu: str = "qemu64"                   # `-cpu` value
    smp: str = "1"                        # `-smp` value
    memory_mb: int = 256
    disk: str = "disk.qcow2"              # the base disk in the golden folder (never written: an overlay is)
    disk_format: str = "qcow2"            # qcow2 or raw
    drive_options: str = "cache=writeback,aio=threads,discard=unmap,detect-zeroes=unmap"
    devices: tuple[str, ...] = (f"virtio-blk-pci,drive={DRIVE_ID},bootindex=1",
                                f"virtio-net-pci,netdev={NETDEV_ID},mac=52:54:00:12:34:56,romfile=")
    objects: tuple[str, ...] = ()         # `-object` values (iothreads, RNG back ends), before the devices
    globals: tuple[str, ...] = ()         # `-global` values
    vga: str = "none"                     # `-vga` value
    rtc: str = "base=utc"                 # `-rtc` value
    firmware: str = ""                    # UEFI code in the golden folder (pflash 0, read-only); "" = SeaBIOS
    firmware_vars: str = ""               # UEFI variables (pflash 1): each VM writes a copy of its own
    kernel: str = ""                      # direct kernel boot: kernel, initrd and command line in the golden
    initrd: str = ""
    append: str = ""
    vmgenid: bool = True                  # a VM generation ID device: a new ID at each restore (guests reseed)
    net: str = "10.0.2.0/24"              # slirp's network; the guest's address, slirp's own (host) address and
    guest_ip: str = "10.0.2.15"           # the address forwarded to the drive are in it
    host_ip: str = "10.0.2.2"
    drive_ip: str = "10.0.2.100"
    drive_port: int = 5244
    control_port: int = 5000              # the guest's control server, forwarded to the container's same port
    extra: tuple[str, ...] = ()           # more QEMU arguments, as given
    clock_command: str = "date -u -s @{epoch:.3f}"
    drive_target: str = "transfer:5244"   # where the runner connects the guest's drive address (the task network)
    after_restore: tuple[str, ...] = ()   # guest commands run after the clock is set, before the VM is ready

    # -- reading and writing ------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        return {f.name: list(v) if isinstance(v := getattr(self, f.name), tuple) else v
                for f in dataclasses.fields(self)}

    @classmethod
    def from_dict(cls, data: Any, where: str = "profile") -> "Profile":
        """A profile from JSON data; a wrong field is a ConfigError naming it (`where`: the file it came from)."""
        if not isinstance(data, dict):
            raise ConfigError("a machine profile must be a JSON object", path=where)
        known = {f.name: f for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - set(known))
        if unknown:
            raise ConfigError(f"unknown field(s) {unknown}", path=where, field=unknown[0],
                              fix=f"use only {sorted(known)}")
        values: dict[str, Any] = {}
        for name, value in data.items():
            default = known[name].default if known[name].default is not dataclasses.MISSING else ""
            want = type(default)
            if want is tuple:
                if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
                    raise ConfigError(f"must be a list of strings, not {value!r}", path=where, field=name)
                value = tuple(value)
            elif want is bool:
                if not isinstance(value, bool):
                    raise ConfigError(f"must be true or false, not {value!r}", path=where, field=name)
            elif want is int:
                if not isinstance(value, int) or isinstance(value, bool):
                    raise ConfigError(f"must be a whole number, not {value!r}", path=where, field=name)
            elif not isinstance(value, str):
                raise ConfigError(f"must be a string, not {value!r}", path=where, field=name)
            values[name] = value
        if "name" not in values:
            raise ConfigError("a machine profile needs a name", path=where, field="name")
        profile = cls(**values)
        profile.check(where)
        return profile

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)

    def check(self, where: str = "profile") -> None:
        """Raise ConfigError (naming the field and the fix) for a profile QEMU or the runner could not use."""
        if self.accel not in ("tcg", "kvm"):
            raise ConfigError(f"accel {self.accel!r} is not tcg or kvm", path=where, field="accel")
        if self.disk_format not in ("qcow2", "raw"):
            raise ConfigError(f"disk_format {self.disk_format!r} is not qcow2 or raw", path=where,
                              field="disk_format")
        if self.memory_mb < 16:
            raise ConfigError(f"memory_mb {self.memory_mb} is too small", path=where, field="memory_mb",
                              fix="give the guest's RAM in MiB, e.g. 256 or 4096")
        for name, value in self.file_fields().items():
            if "/" in value or value in (".", ".."):
                raise ConfigError(f"{name} {value!r} must be a file name in the golden folder, not a path",
                                  path=where, field=name)
        if not self.disk:
            raise ConfigError("a profile needs a disk", path=where, field="disk")
        if self.firmware_vars and not self.firmware:
            raise ConfigError("firmware_vars without firmware", path=where, field="firmware",
                              fix="name the UEFI code file too (pflash 0)")
        if bool(self.initrd or self.append) and not self.kernel:
            raise ConfigError("initrd or append without a kernel", path=where, field="kernel")
        for what, ident in (("drive", DRIVE_ID), ("netdev", NETDEV_ID)):
            users = [d for d in self.devices if f"{what}={ident}" in d.split(",")]
            if len(users) != 1:
                raise ConfigError(f"exactly one device must use {what}={ident}, found {len(users)}", path=where,
                                  field="devices", fix=f"attach the disk to `drive={DRIVE_ID}` and the NIC to "
                                                       f"`netdev={NETDEV_ID}`, once each")
        try:
            net = ipaddress.ip_network(self.net)
            inside = {n: ipaddress.ip_address(getattr(self, n)) in net for n in ("guest_ip", "host_ip", "drive_ip")}
        except ValueError as exc:
            raise ConfigError(f"bad address: {exc}", path=where, field="net") from None
        for name, ok in inside.items():
            if not ok:
                raise ConfigError(f"{name} {getattr(self, name)} is not in net {self.net}", path=where, field=name)
        if len({self.guest_ip, self.host_ip, self.drive_ip}) != 3:
            raise ConfigError("guest_ip, host_ip and drive_ip must differ", path=where, field="drive_ip")
        try:
            self.clock_command.format(epoch=0.0)
        except (KeyError, IndexError, ValueError) as exc:
            raise ConfigError(f"clock_command cannot be filled in: {exc}", path=where, field="clock_command",
                              fix="use {epoch} (seconds since 1970, a float) and no other placeholder") from None

    def differences(self, other: "Profile") -> list[str]:
        """The machine fields in which `other` differs from this profile (runtime fields left out)."""
        return [f.name for f in dataclasses.fields(self)
                if f.name not in RUNTIME_FIELDS and getattr(self, f.name) != getattr(other, f.name)]

    def file_fields(self) -> dict[str, str]:
        """The golden-folder files this profile boots from, by field."""
        names = ("disk", "firmware", "firmware_vars", "kernel", "initrd")
        return {name: getattr(self, name) for name in names if getattr(self, name)}

    def files(self) -> list[str]:
        return list(self.file_fields().values())

    # -- the command line ---------------------------------------------------------------------------------
    def netdev(self, forward_runner: bool = True) -> str:
        """The `-netdev` value: slirp closed to everything (`restrict=on`) but the forwards: the runner's own
        loopback port to the control server, and the drive's guest address to the task's drive."""
        parts = [f"user,id={NETDEV_ID}", f"net={self.net}", f"host={self.host_ip}", f"dhcpstart={self.guest_ip}",
                 "restrict=on"]
        if forward_runner:
            parts.append(f"hostfwd=tcp:127.0.0.1:{RUNNER_PORT}-{self.guest_ip}:{self.control_port}")
        parts.append(f"guestfwd=tcp:{self.drive_ip}:{self.drive_port}-cmd:socat - TCP:{self.drive_target}")
        return ",".join(parts)

    def command(self, *, root: str, disk: str, firmware_vars: str = "", qmp: str, console: str,
                vmgenid: str = "", incoming: bool = False) -> list[str]:
        """The QEMU command line: files the profile names are under `root` (the golden folder as mounted), `disk`
        is the overlay this VM writes, `firmware_vars` its copy of the UEFI variables, `vmgenid` its generation
        ID; `incoming` waits for a memory state (`migrate-incoming`) and stays paused once it is loaded."""
        def file(name: str) -> str:
            return f"{root.rstrip('/')}/{name}"

        args = ["qemu-system-x86_64", "-name", f"jarvis-{self.name},debug-threads=on", "-nodefaults",
                "-no-user-config", "-machine", self.machine, "-accel", self.accel, "-cpu", self.cpu,
                "-smp", self.smp, "-m", f"{self.memory_mb}M", "-display", "none", "-vga", self.vga,
                "-rtc", self.rtc, "-qmp", f"unix:{qmp},server=on,wait=off",
                "-chardev", f"file,id=console,path={console}", "-serial", "chardev:console"]
        for value in self.globals:
            args += ["-global", value]
        if self.firmware:
            args += ["-drive", f"file={file(self.firmware)},if=pflash,unit=0,format=raw,readonly=on"]
            if self.firmware_vars:
                args += ["-drive", f"file={firmware_vars},if=pflash,unit=1,format=raw"]
        if self.kernel:
            args += ["-kernel", file(self.kernel)]
            if self.initrd:
                args += ["-initrd", file(self.initrd)]
            if self.append:
                args += ["-append", self.append]
        args += ["-drive", f"file={disk},if=none,id={DRIVE_ID},format=qcow2,{self.drive_options}",
                 "-netdev", self.netdev()]
        for value in self.objects:
            args += ["-object", value]
        for value in self.devices:
            args += ["-device", value]
        if self.vmgenid:
            args += ["-device", f"vmgenid,id=vmgenid0,guid={vmgenid or 'auto'}"]
        args += list(self.extra)
        if incoming:
            args += ["-incoming", "defer", "-S"]
        return args


def overlay_command(backing: str, backing_format: str, overlay: str) -> list[str]:
    """`qemu-img` making `overlay`, a qcow2 that writes nothing to `backing` (which it reads)."""
    return ["qemu-img", "create", "-q", "-f", "qcow2", "-F", backing_format, "-b", backing, overlay]
