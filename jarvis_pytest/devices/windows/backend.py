"""The Windows-platform backends: `wine` (the offline stand-in built here, `fixtures/images/windows/`) and `kvm`
(a real Windows VM, `real.py`). Both run the same control server and are driven by the same client; results
record which ran and what the device is (a Windows, or Wine on Debian), and Wine results are marked as a stand-in.

A kvm task's device is a VM runner container (`devices/vm/`, image `vm-runner`) that restores the golden's memory
snapshot into an overlay of the golden disk: dockur installed the golden once and does not run at task time. Its
results also record the dockur image (registry digest) that installed the golden and the snapshot
(`real.provenance`, as `device_provenance`).

The kvm backend's options are the VM's settings (`real.WindowsVMSettings`): `--backend-option windows.version=10`,
`windows.ram`, `windows.cpus`, `windows.image`, `windows.disks`, `windows.disk_size`, each else read from its
older environment variable (`real.ENV`), else its default.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Callable

from jarvis_pytest.devices.backend import Backend, BackendOption, os_release_name
from jarvis_pytest.devices.desktop import DesktopDevice, wait_ready
from jarvis_pytest.devices.vm.backend import QEMU_MEMORY_MB, vm_backend
from jarvis_pytest.devices.vm.prepare import QEMU_OVERHEAD_MB, RUNNER_IMAGE
from jarvis_pytest.devices.windows import real
from jarvis_pytest.errors import ConfigError, InfrastructureError

DRIVE_MOUNT = "/mnt/drive"  # where the Wine device mounts the task drive's storage; its prefix maps S: there
PYTHON = r"C:\jarvis\python\python.exe"  # the device's own CPython (both backends)
# Asked of a Wine device by its own Python: the Windows version it reports, Wine's version and the system under
# Wine (its / is Z:). `platform.win32_ver` is not used: it asks WMI, which Wine 8 lacks.
WINE_SCRIPT = ("import ctypes,sys;w=sys.getwindowsversion();print(f'{w.major}.{w.minor}.{w.build}');"
               "f=getattr(ctypes.WinDLL('ntdll'),'wine_get_version',None);f and setattr(f,'restype',ctypes.c_char_p);"
               "print(f().decode() if f else '');print(open('Z:/etc/os-release').read() if f else '')")


def _connect(url: str) -> DesktopDevice:
    return DesktopDevice(url, platform="windows")


def describe_wine(device: DesktopDevice) -> str:
    """E.g. `Wine 8.0 on Debian GNU/Linux 12 (bookworm), reporting Windows 10.0.18362`."""
    result = device.run(f'"{PYTHON}" -I -c "{WINE_SCRIPT}"', timeout=30)
    lines = result.stdout.splitlines()
    if result.returncode != 0 or len(lines) < 2:
        raise InfrastructureError(f"the device could not say what it is (exit {result.returncode}: "
                                  f"{(result.stderr or result.stdout)[-300:]})")
    windows, wine = lines[0].strip(), lines[1].strip()
    if not wine:
        return f"Windows {windows} (not Wine)"
    system = os_release_name("\n".join(lines[2:])) or "an unknown system"
    return f"Wine {wine} on {system}, reporting Windows {windows}"


def describe_vm(device: DesktopDevice) -> str:
    """E.g. `Windows 10 Professional 22H2 (build 19045.3803)`, from the device itself (`real.device_os`)."""
    facts = real.device_os(device)
    name = f"Windows {facts['windows']}" if facts.get("windows") else facts.get("product", "Windows")
    words = [name, facts.get("edition", ""), facts.get("release", "")]
    build = facts.get("build") or facts.get("version")
    return " ".join(w for w in words if w) + (f" (build {build})" if build else "")


KVM_HELP = {
    "image": ("the dockur/windows image that installs the golden: its 6.05 tag or a digest", "dockurr/windows:6.05"),
    "version": ("dockur's VERSION, a Windows 10: 10 (22H2) or 10l (Enterprise LTSC 2021)", "10"),
    "ram": ("the VM's memory, as dockur's RAM_SIZE takes it", "6G"),
    "cpus": ("the VM's cores (dockur's CPU_CORES)", "4"),
    "disk_size": ("the VM's disk (dockur's DISK_SIZE)", "64G"),
    "disks": ("the folder of the prepared golden disk (`jarvis images build --only windows-real`)",
              "/var/lib/jarvis/windows-real"),
}


def _setting(name: str) -> Callable[[str], str]:
    """An option's parser: the text as `real.settings` takes it, checked there (one ConfigError with its fix)."""
    def parse(text: str) -> str:
        error = real.settings({}, **{name: text}).problem()
        if error is not None:
            raise error
        return text
    return parse


def _kvm_options() -> tuple[BackendOption, ...]:
    defaults = real.WindowsVMSettings()
    options = []
    for name, var in real.ENV.items():
        help, example = KVM_HELP.get(name, (f"the Windows VM's {name}", ""))
        options.append(BackendOption(name, help, default=str(getattr(defaults, name)), parse=_setting(name), env=var,
                                     example=example))
    return tuple(options)


def _kvm(values: Mapping[str, Any]) -> dict[str, Any]:
    """The fields of the kvm backend that follow from the VM's settings (the machine profile and the runner's
    container options follow from the golden too: `KvmBackend.boot` reads them when a task boots)."""
    settings = real.settings({}, **values)
    ram = real.ram_mb(settings)
    return {"settings": settings, "memory": f"{ram + QEMU_OVERHEAD_MB}m",
            "booted_memory_mb": ram + QEMU_MEMORY_MB,  # the VM's RAM, and QEMU
            "unavailable": lambda: real.unavailable(settings), "provenance": lambda: real.provenance(settings)}


@dataclass(frozen=True)
class KvmBackend(Backend):
    """The kvm backend: each device a VM restored by the runner from the golden's memory snapshot (`real.py`)."""

    settings: real.WindowsVMSettings = field(default_factory=real.WindowsVMSettings)

    def runner(self) -> Any:
        """The VM runner backend that boots this golden's tasks (`vm.backend.vm_backend`): the golden read-only,
        the saved state, dockur 6.05's machine with these settings' RAM and cores. A golden that cannot be restored
        (`real.golden_problem`) is one ConfigError saying why, before any container exists."""
        why = real.golden_problem(self.settings)
        if why is not None:
            raise ConfigError(why, fix=real.HOW_TO_RUN)
        return vm_backend("windows", self.settings.golden, real.task_profile(self.settings), name=self.name,
                          connect=self.connect, ready_timeout=self.ready_timeout, memory=self.memory,
                          how_to_run=self.how_to_run)

    def boot(self, request: Any) -> Any:
        return self.runner().boot(request)


WINE = Backend(
    platform="windows", name="wine", image="windows", connect=_connect, wait_ready=wait_ready,
    memory="2g", booted_memory_mb=200, ready_timeout=60.0, stand_in=True, drive_mount=DRIVE_MOUNT, holder=True,
    how_to_run="`jarvis images build --only windows` (offline, from Debian's Wine)", describe=describe_wine,
)

KVM = KvmBackend(
    platform="windows", name="kvm", image=RUNNER_IMAGE, connect=_connect, wait_ready=wait_ready,
    ready_timeout=real.READY_TIMEOUT, how_to_run=real.HOW_TO_RUN, describe=describe_vm, options=_kvm_options(),
    derive=_kvm,
)
