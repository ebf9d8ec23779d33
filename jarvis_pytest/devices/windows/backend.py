"""The Windows-platform backends: `wine` (the offline stand-in built here, `fixtures/images/windows/`) and `kvm`
(a real Windows VM, `real.py`). Both run the same control server and are driven by the same client; results
record which ran, and Wine results are marked as a stand-in."""

from __future__ import annotations

from jarvis_pytest.devices.backend import Backend
from jarvis_pytest.devices.desktop import DesktopDevice, wait_ready
from jarvis_pytest.devices.windows import real

DRIVE_MOUNT = "/mnt/drive"  # where the Wine device mounts the task drive's storage; its prefix maps S: there


def _connect(url: str) -> DesktopDevice:
    return DesktopDevice(url, platform="windows")


WINE = Backend(
    platform="windows", name="wine", image="windows", connect=_connect, wait_ready=wait_ready,
    memory="2g", booted_memory_mb=200, ready_timeout=60.0, stand_in=True, drive_mount=DRIVE_MOUNT, holder=True,
    how_to_run="`jarvis images build --only windows` (offline, from Debian's Wine)",
)

KVM = Backend(
    platform="windows", name="kvm", image=real.IMAGE, image_kind="prepared", connect=_connect,
    wait_ready=wait_ready, container_options=real.task_container_options(), memory=None, ready_timeout=300.0,
    booted_memory_mb=real.ram_mb() + 256,  # the VM's RAM, and QEMU
    unavailable=real.unavailable, how_to_run=real.HOW_TO_RUN,
)
