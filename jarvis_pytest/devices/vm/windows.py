"""A Windows 10 VM as dockur/windows 6.05 gives it (`VERSION=10`), as a machine profile our runner boots and snapshots.

Read in dockur/windows v6.05 (commit efe47da, image `dockurr/windows:6.05`), whose Dockerfile:6 copies qemux/qemu
7.48 (qemus/qemu v7.48, commit 5eb8878; QEMU 11.1 from Debian sid, its Dockerfile:15), then its own `src/` over
it (Dockerfile:50): entry, define, install, legacy, power, samba and the unattended-install helpers. The machine is
qemus/qemu's `src/*.sh`, sourced after install.sh (dockur entry.sh:24-35). `VERSION=10` (define.sh:54-55:
`win10x64`) boots an installed Windows in mode `windows` (entry.sh:6;
install.sh:98-130 restores saved machine state, which legacy.sh:11-74 writes only for legacy Windows, never for
Windows 10). With dockur's defaults that machine is (qemus/qemu v7.48 `file:line`):

- `-machine type=q35,smm=off,graphics=off,vmport=off,dump-guest-core=off,hpet=off,accel=kvm` (config.sh:87-88;
  MACHINE init.sh:16, SMM boot.sh:393, VMPORT config.sh:10, HPET config.sh:9) and `-global
  kvm-pit.lost_tick_policy=discard` (proc.sh:70);
- `-cpu host,kvm=on,l3-cache=on,+hypervisor,migratable=no,-vmx` (proc.sh:67-81: `+hypervisor` with VM, which is
  Y unless set, proc.sh:237; `-vmx` since VMX is N for Windows, proc.sh:246-259), then `arch_capabilities=off` on an
  AMD host for Windows (proc.sh:93-95; AMD told by /proc/cpuinfo's vendor_id, utils.sh:339-345), `+invtsc` where the
  host scales the TSC (proc.sh:89-91, 105-107), and `hv_passthrough` (HV is Y for Windows, proc.sh:239-244;
  proc.sh:112-146); `-smp N,sockets=1,dies=1,cores=N,threads=1` (config.sh:14), `-m RAM_SIZE` (config.sh:40);
- UEFI without Secure Boot or TPM: `OVMF_CODE_4M.fd`/`OVMF_VARS_4M.fd` copied to `/storage/windows.rom` and
  `windows.vars` (boot.sh:53-56, 128, 227-228; SMM and TPM N, boot.sh:393-394), `-rtc base=localtime`, `-global
  ICH9-LPC.disable_s3=1`, `-global ICH9-LPC.disable_s4=1` (boot.sh:114-119);
- `-vga virtio` (display.sh:7, 29); `-serial mon:stdio`, an ISA serial port (config.sh:13, 53);
- devices in this order (QEMU gives a device without `addr=` the next free slot, so the order is the machine):
  `qemu-xhci,id=xhci,p2=7,p3=7` and `usb-tablet` (config.sh:144-151, MOUSE config.sh:12);
  `virtio-net-pci,id=net0,netdev=hostnet0,romfile=,mac=<windows.mac>` (network.sh:11, 2379; the MAC kept in
  `/storage/windows.mac`, network.sh:2119-2136); the disk `-drive
  file=/storage/data.qcow2,id=data3,format=qcow2,cache=none,aio=native,discard=unmap,detect-zeroes=on,if=none`
  (disk.sh:565; cache, discard and rotation defaults disk.sh:13-15, aio disk.sh:937-939) on
  `virtio-scsi-pci,id=data3,bus=pcie.0,addr=0xa,iothread=io2,hotplug=off` with
  `scsi-hd,drive=data3,bus=data3.0,channel=0,scsi-id=0,lun=0,rotation_rate=1,bootindex=3` (disk.sh:595-596; type
  scsi disk.sh:926, slot and boot index disk.sh:1179-1180, bus utils.sh:358-370) and `-object iothread,id=io2`
  (disk.sh:707, 941); `-object rng-random,id=objrng0,filename=/dev/urandom` with `virtio-rng-pci,rng=objrng0,
  id=rng0,bus=pcie.0` (config.sh:107-110); no balloon for Windows (config.sh:114), no sound (AUDIO N, init.sh:14),
  no shared folder (config.sh:130), no install media once installed (dockur power.sh:403-410 removes them);
- `-fw_cfg name=opt/org.tianocore/UninstallMemAttrProtocol,string=y` for OVMF (config.sh:236).

What we change, and why (the guest sees only the first four):
- CPU: `migratable=no`, `hv_passthrough` and `+invtsc` each stop QEMU from saving the VM (an invariant TSC only
  migrates with a fixed TSC frequency); we ask for the same host CPU, migratable, with the Hyper-V enlightenments
  named one by one. A snapshot restores only on a host with the same CPU model (KVM's rule for `-cpu host`).
- The machine version: the runner is Debian 12's QEMU 7.2 (`pc-q35-7.2`), dockur 6.05's is QEMU 11.1
  (`pc-q35-11.1`): Windows is prepared (cold-booted, then snapshot) on the runner's machine.
- A VM generation ID device (Windows reseeds its random number generator when it changes); no `-smbios` serial
  copied from the host (boot.sh:284-301: a task VM has no business knowing the host's serial).
- Network: not dockur's tap and NAT but slirp, closed (`restrict=on`), on 20.20.20.0/24 (dockur's older user-mode
  network, still aliased for Windows in network.sh:1911-1920), the guest .21 by DHCP: the guest reaches its control
  port's forward and, at 20.20.20.100:5244, the task's drive. It needs `transfer` in its hosts file
  (`prepare_windows` adds it before the snapshot). The NIC, its MAC and the disk are dockur's.
- Host side only: the disk's cache (`writeback`, `threads`: the overlay lives in the container's layer, where
  O_DIRECT may not be had; the guest sees a write cache either way), device and drive ids, no VNC or monitors.

A golden installed by another dockur release (its `windows.ver`, written from the image's /etc/version at the end
of the installation, dockur install.sh:403-404, Dockerfile:59) is refused: its machine may differ (v4.35 gave no
`hotplug=off`, `graphics=off` or `+hypervisor`). The release is part of the profile's name, recorded with the
snapshot.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

from jarvis_pytest.devices.vm.golden import Record
from jarvis_pytest.devices.vm.profile import DRIVE_ID, NETDEV_ID, Profile
from jarvis_pytest.errors import ConfigError

DOCKUR_RELEASE = "6.05"    # the dockur/windows release this profile was read from (its base: qemus/qemu v7.48)
MODE = "windows"           # dockur's BOOT_MODE for Windows 10: UEFI, no Secure Boot, no TPM
NET, GUEST_IP, HOST_IP, DRIVE_IP = "20.20.20.0/24", "20.20.20.21", "20.20.20.1", "20.20.20.100"
HYPERV = ("hv-relaxed", "hv-vapic", "hv-spinlocks=0x1fff", "hv-vpindex", "hv-runtime", "hv-synic", "hv-stimer",
          "hv-frequencies", "hv-time", "hv-reset", "hv-tlbflush", "hv-ipi")
MACHINE = "q35,smm=off,graphics=off,vmport=off,dump-guest-core=off,hpet=off"
# Sets the wall clock through the Windows control server's /run (cmd /c): the user is an administrator, UAC off.
# The time PowerShell took to start (by its own clock, which the restore left at the snapshot's) is added.
CLOCK = ('powershell -NoProfile -NonInteractive -Command "$d=[DateTimeOffset]::FromUnixTimeMilliseconds('
         '[long]({epoch:.3f}*1000)).LocalDateTime+((Get-Date)-(Get-Process -Id $PID).StartTime); '
         'Set-Date -Date $d | Out-Null"')
HOSTS_ENTRY = f"echo {DRIVE_IP} transfer>> %SystemRoot%\\System32\\drivers\\etc\\hosts"
# After a restore: S: as the task's drive. The golden's logon could not map it (nothing answered at `transfer`
# while it was prepared); start.bat's `map` tries the name, then the address DNS gives, then the drive's address.
MAP_DRIVE = f"C:\\jarvis\\start.bat map {DRIVE_IP}"
CPUINFO = Path("/proc/cpuinfo")


def _read(storage: Path, name: str, fix: str) -> str:
    path = storage / name
    try:
        return "".join(ch for ch in path.read_text() if ch.isprintable()).strip()
    except FileNotFoundError:
        raise ConfigError("dockur's storage lacks this file", path=path, fix=fix) from None


def amd_host(cpuinfo: str | None = None) -> bool:
    """Whether this host's CPU is AMD's, as dockur tells it (qemus/qemu utils.sh:339-345: /proc/cpuinfo's first
    vendor_id)."""
    text = CPUINFO.read_text() if cpuinfo is None else cpuinfo
    for line in text.splitlines():
        if line.startswith("vendor_id"):
            return line.split(":", 1)[1].strip() == "AuthenticAMD"
    return False


def cpu(amd: bool) -> str:
    """dockur 6.05's KVM CPU for Windows (proc.sh:67-146), made migratable (see the module's docstring)."""
    features = ["host", "kvm=on", "l3-cache=on", "+hypervisor", "migratable=on", "-vmx"]
    if amd:
        features.append("arch_capabilities=off")
    return ",".join((*features, *HYPERV))


def profile_from_storage(storage: Path, *, ram_mb: int = 4096, cores: int = 2, cpuinfo: str | None = None) -> Profile:
    """The machine of the Windows that dockur 6.05 installed in `storage` (its `/storage` folder: the disk, the UEFI
    files, the MAC), `ram_mb` of RAM and `cores` CPUs as dockur's RAM_SIZE and CPU_CORES gave it, on this host's CPU
    (`cpuinfo`: /proc/cpuinfo's text). A storage that is not a finished, cleanly shut down Windows 10 install of
    dockur 6.05 in mode `windows` is a ConfigError naming the file."""
    storage = Path(storage)
    _read(storage, "windows.boot", fix="let dockur finish installing and stop it cleanly (SIGTERM, long grace "
                                       "period): it writes windows.boot")
    release = _read(storage, "windows.ver", fix=f"install Windows with dockurr/windows:{DOCKUR_RELEASE} (it writes "
                                                "its release there when the installation ends)")
    if release != DOCKUR_RELEASE:
        raise ConfigError(f"installed by dockur/windows {release!r}; the runner boots dockur {DOCKUR_RELEASE}'s "
                          "machine, and another release's differs (disk controller, CPU flags)",
                          path=storage / "windows.ver",
                          fix=f"prepare the golden again with dockurr/windows:{DOCKUR_RELEASE}")
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
        name=f"windows-10-dockur-{DOCKUR_RELEASE}", machine=MACHINE, accel="kvm", cpu=cpu(amd_host(cpuinfo)),
        smp=f"{cores},sockets=1,dies=1,cores={cores},threads=1", memory_mb=ram_mb, disk=disk, disk_format=disk_format,
        drive_options="cache=writeback,aio=threads,discard=unmap,detect-zeroes=on",
        objects=("iothread,id=io2", "rng-random,id=objrng0,filename=/dev/urandom"),
        devices=("qemu-xhci,id=xhci,p2=7,p3=7", "usb-tablet",
                 f"virtio-net-pci,id=net0,netdev={NETDEV_ID},romfile=,mac={mac}",
                 f"virtio-scsi-pci,id={DRIVE_ID}b,bus=pcie.0,addr=0xa,iothread=io2,hotplug=off",
                 f"scsi-hd,drive={DRIVE_ID},bus={DRIVE_ID}b.0,channel=0,scsi-id=0,lun=0,rotation_rate=1,bootindex=3",
                 "virtio-rng-pci,rng=objrng0,id=rng0,bus=pcie.0"),
        globals=("ICH9-LPC.disable_s3=1", "ICH9-LPC.disable_s4=1", "kvm-pit.lost_tick_policy=discard"),
        vga="virtio", rtc="base=localtime", firmware="windows.rom", firmware_vars="windows.vars",
        extra=("-fw_cfg", "name=opt/org.tianocore/UninstallMemAttrProtocol,string=y"),
        net=NET, guest_ip=GUEST_IP, host_ip=HOST_IP, drive_ip=DRIVE_IP, clock_command=CLOCK,
        after_restore=(MAP_DRIVE,))


def prepare_windows(storage: Path, *, ram_mb: int = 4096, cores: int = 2, commands: Sequence[str] = (),
                    ready_timeout: float = 900.0, settle: float = 30.0, source: dict[str, Any] | None = None,
                    **options: Any) -> Record:
    """Boot dockur's installed Windows in `storage` with our runner (its disk stays as dockur left it: the boot
    writes an overlay), wait for the control server (started at logon), add `transfer` to its hosts file, run
    `commands`, let it settle, save its memory: `storage/snapshot/`. `source` (e.g. the dockur image and its
    digest) is recorded with the release; `options` go to `prepare_snapshot`."""
    from jarvis_pytest.devices.vm.prepare import prepare_snapshot

    profile = profile_from_storage(storage, ram_mb=ram_mb, cores=cores)
    recorded = {**(source or {}), "dockur_release": DOCKUR_RELEASE, "storage": str(storage)}
    return prepare_snapshot(storage, profile, commands=(HOSTS_ENTRY, *commands), ready_timeout=ready_timeout,
                            settle=settle, source=recorded, **options)
