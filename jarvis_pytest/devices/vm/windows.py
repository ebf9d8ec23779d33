"""A Windows 10 VM as dockur/windows gives it, as a machine profile our runner boots and snapshots.

Read in dockur/windows v4.35 (`src/entry.sh`, `install.sh`, `define.sh`), built on qemus/qemu v7.12 (`src/boot.sh`,
`config.sh`, `disk.sh`, `network.sh`, `proc.sh`): a Windows 10 x64 install boots in mode `windows` (UEFI without
Secure Boot or TPM: OVMF_CODE_4M.fd / OVMF_VARS_4M.fd, which dockur copies to `/storage/windows.rom` and
`windows.vars`), on `q35` with SMM, vmport and HPET off, `-rtc base=localtime`, S3/S4 disabled, `-vga virtio`, a
qemu-xhci controller with a USB tablet, a virtio-net NIC (no option ROM) with the MAC kept in
`/storage/windows.mac`, the disk on virtio-scsi at PCI address 0xa (iothread `io2`, `rotation_rate=1`, boot index
3) and a virtio-rng. QEMU gives devices without an address the next free slot, so they are listed in dockur's order.

What we change, and why:
- CPU: dockur's `host,...,migratable=no,hv_passthrough` cannot be migrated (QEMU refuses to save such a VM); we
  ask for the same host CPU, migratable, with the Hyper-V enlightenments named one by one. A snapshot restores
  only on a host with the same CPU model (KVM's rule for `-cpu host`).
- Network: not dockur's tap and NAT but slirp, closed (`restrict=on`), on dockur's own user-mode addresses
  (20.20.20.0/24, the guest .21 by DHCP): the guest reaches its control port's forward and, at 20.20.20.100:5244,
  the task's drive. It needs `transfer` in its hosts file (`prepare_windows` adds it before the snapshot).
- No VNC, monitor or the install's CD drives (not part of an installed machine), no `-smbios` serial copied from
  the host; a VM generation ID device (Windows reseeds its random number generator when it changes).

Later dockur releases changed the machine: at v6.05 (on qemux/qemu 7.48) the virtio-scsi controller has
`hotplug=off`, `+hypervisor` comes only with `VM=Y`, and AMD hosts get `arch_capabilities=off` for Windows. A golden
installed by another release than v4.35 (its `windows.ver`) boots with this machine all the same, but Windows sees
those differences; the release that installed it is recorded with the snapshot.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

from jarvis_pytest.devices.vm.golden import Record
from jarvis_pytest.devices.vm.profile import DRIVE_ID, NETDEV_ID, Profile
from jarvis_pytest.errors import ConfigError

DOCKUR_TAG = "v4.35"       # the dockur/windows release this profile was read from (its base: qemus/qemu v7.12)
MODE = "windows"           # dockur's BOOT_MODE for Windows 10: UEFI, no Secure Boot, no TPM
NET, GUEST_IP, HOST_IP, DRIVE_IP = "20.20.20.0/24", "20.20.20.21", "20.20.20.1", "20.20.20.100"
HYPERV = ("hv-relaxed", "hv-vapic", "hv-spinlocks=0x1fff", "hv-vpindex", "hv-runtime", "hv-synic", "hv-stimer",
          "hv-frequencies", "hv-time", "hv-reset", "hv-tlbflush", "hv-ipi")
CPU = ",".join(("host", "migratable=on", "kvm=on", "l3-cache=on", "+hypervisor", "-vmx", *HYPERV))
# Sets the wall clock through the Windows control server's /run (cmd /c): the user is an administrator, UAC off.
CLOCK = ('powershell -NoProfile -NonInteractive -Command "Set-Date -Date ([DateTimeOffset]::FromUnixTimeMilliseconds('
         '[long]({epoch:.3f}*1000)).LocalDateTime) | Out-Null"')
HOSTS_ENTRY = f"echo {DRIVE_IP} transfer>> %SystemRoot%\\System32\\drivers\\etc\\hosts"


def _read(storage: Path, name: str, fix: str) -> str:
    path = storage / name
    try:
        return "".join(ch for ch in path.read_text() if ch.isprintable()).strip()
    except FileNotFoundError:
        raise ConfigError("dockur's storage lacks this file", path=path, fix=fix) from None


def profile_from_storage(storage: Path, *, ram_mb: int = 4096, cores: int = 2, name: str = "windows-10") -> Profile:
    """The machine of the Windows that dockur installed in `storage` (its `/storage` folder: the disk, the UEFI
    files, the MAC), `ram_mb` of RAM and `cores` CPUs as dockur's RAM_SIZE and CPU_CORES gave it. A storage that
    is not a finished, cleanly shut down Windows 10 install in mode `windows` is a ConfigError naming the file."""
    storage = Path(storage)
    _read(storage, "windows.boot", fix="let dockur finish installing and stop it cleanly (SIGTERM, long grace "
                                       "period): it writes windows.boot")
    mode = (storage / "windows.mode").read_text().strip() if (storage / "windows.mode").exists() else MODE
    if mode != MODE:
        raise ConfigError(f"dockur booted this Windows in mode {mode!r}; this profile is for {MODE!r} (UEFI without "
                          "Secure Boot or TPM, as dockur installs Windows 10)", path=storage / "windows.mode",
                          fix="install with VERSION=10 (or ltsc10) and dockur's default BOOT_MODE")
    mac = _read(storage, "windows.mac", fix="boot the install once with dockur (it writes the MAC it gave the NIC)")
    for firmware in ("windows.rom", "windows.vars"):
        if not (storage / firmware).is_file():
            raise ConfigError("dockur's UEFI file is missing", path=storage / firmware,
                              fix="keep the whole of dockur's /storage folder, not only the disk")
    disks = [(f, fmt) for f, fmt in (("data.qcow2", "qcow2"), ("data.img", "raw")) if (storage / f).is_file()]
    if not disks:
        raise ConfigError("no disk (data.qcow2 or data.img)", path=storage, fix="point at dockur's /storage folder")
    disk, disk_format = disks[0]
    return Profile(
        name=name, machine="q35,smm=off,vmport=off,dump-guest-core=off,hpet=off", accel="kvm", cpu=CPU,
        smp=f"{cores},sockets=1,dies=1,cores={cores},threads=1", memory_mb=ram_mb, disk=disk, disk_format=disk_format,
        drive_options="cache=writeback,aio=threads,discard=on,detect-zeroes=on",
        objects=("iothread,id=io2", "rng-random,id=objrng0,filename=/dev/urandom"),
        devices=("qemu-xhci,id=xhci,p2=7,p3=7", "usb-tablet",
                 f"virtio-net-pci,id=net0,netdev={NETDEV_ID},romfile=,mac={mac}",
                 f"virtio-scsi-pci,id={DRIVE_ID}b,bus=pcie.0,addr=0xa,iothread=io2",
                 f"scsi-hd,drive={DRIVE_ID},bus={DRIVE_ID}b.0,channel=0,scsi-id=0,lun=0,rotation_rate=1,bootindex=3",
                 "virtio-rng-pci,rng=objrng0,id=rng0,bus=pcie.0"),
        globals=("ICH9-LPC.disable_s3=1", "ICH9-LPC.disable_s4=1", "kvm-pit.lost_tick_policy=discard"),
        vga="virtio", rtc="base=localtime", firmware="windows.rom", firmware_vars="windows.vars",
        net=NET, guest_ip=GUEST_IP, host_ip=HOST_IP, drive_ip=DRIVE_IP, clock_command=CLOCK)


def prepare_windows(storage: Path, *, ram_mb: int = 4096, cores: int = 2, commands: Sequence[str] = (),
                    ready_timeout: float = 900.0, settle: float = 30.0, **options: Any) -> Record:
    """Boot dockur's installed Windows in `storage` with our runner (its disk stays as dockur left it: the boot
    writes an overlay), wait for the control server (started at logon), add `transfer` to its hosts file, run
    `commands`, let it settle, save its memory: `storage/snapshot/`. `options` go to `prepare_snapshot`."""
    from jarvis_pytest.devices.vm.prepare import prepare_snapshot

    profile = profile_from_storage(storage, ram_mb=ram_mb, cores=cores)
    version = Path(storage) / "windows.ver"
    installed_by = version.read_text().strip() if version.exists() else ""
    source = {"profile_from_dockur": DOCKUR_TAG, "installed_by_dockur": installed_by, "storage": str(storage)}
    return prepare_snapshot(storage, profile, commands=(HOSTS_ENTRY, *commands), ready_timeout=ready_timeout,
                            settle=settle, source=source, **options)
