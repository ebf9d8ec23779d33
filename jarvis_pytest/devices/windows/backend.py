"""The Windows-platform backends: `wine` (the offline stand-in built here, `fixtures/images/windows/`) and `kvm`
(a real Windows VM, `real.py`). Both run the same control server and are driven by the same client; results
record which ran and what the device is (a Windows, or Wine on Debian), and Wine results are marked as a stand-in.

The kvm backend's options are the VM's settings (`real.WindowsVMSettings`): `--backend-option windows.version=10`,
`windows.ram`, `windows.cpus`, `windows.image`, `windows.disks`, `windows.disk_size`, each else read from its
older environment variable (`real.ENV`), else its default.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Callable

from jarvis_pytest.devices.backend import Backend, BackendOption, os_release_name
from jarvis_pytest.devices.desktop import DesktopDevice, wait_ready
from jarvis_pytest.devices.windows import real
from jarvis_pytest.errors import InfrastructureError

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
    "image": ("the dockur/windows image the VM runs, pinned by a tag or a digest", "dockurr/windows:6.05"),
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
    """The fields of the kvm backend that follow from the VM's settings."""
    settings = real.settings({}, **values)
    return {"image": settings.image, "container_options": real.task_container_options(None, settings),
            "booted_memory_mb": real.ram_mb(settings) + 256,  # the VM's RAM, and QEMU
            "unavailable": lambda: real.unavailable(settings)}


WINE = Backend(
    platform="windows", name="wine", image="windows", connect=_connect, wait_ready=wait_ready,
    memory="2g", booted_memory_mb=200, ready_timeout=60.0, stand_in=True, drive_mount=DRIVE_MOUNT, holder=True,
    how_to_run="`jarvis images build --only windows` (offline, from Debian's Wine)", describe=describe_wine,
)

KVM = Backend(
    platform="windows", name="kvm", image=real.IMAGE, image_kind="prepared", connect=_connect,
    wait_ready=wait_ready, memory=None, ready_timeout=300.0, how_to_run=real.HOW_TO_RUN, describe=describe_vm,
    options=_kvm_options(), derive=_kvm,
)
