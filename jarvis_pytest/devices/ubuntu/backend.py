"""The Ubuntu-platform backend: the `ubuntu` image driven through its control server. The platform keeps the
paper's name; the device is Debian 12 (bookworm) with XFCE (built offline from Debian packages), and every result
says so (`describe`, read inside the device)."""

from __future__ import annotations

import re

from jarvis_pytest.devices.backend import Backend, os_release_name
from jarvis_pytest.devices.desktop import DesktopDevice, wait_ready

DESCRIBE_COMMAND = "cat /etc/os-release; xfce4-session --version 2>/dev/null | head -n 1"


def describe(device: DesktopDevice) -> str:
    """The device's system and desktop, as it says: e.g. `Debian GNU/Linux 12 (bookworm), XFCE 4.18`."""
    out = device.run(DESCRIBE_COMMAND, timeout=20).stdout
    system = os_release_name(out) or "unknown system (no /etc/os-release)"
    xfce = re.search(r"\(Xfce ([0-9.]+)\)", out)
    if xfce:
        return f"{system}, XFCE {xfce.group(1)}"
    return f"{system}, XFCE" if "xfce4-session" in out else system


BACKEND = Backend(
    platform="ubuntu",
    name="docker",
    image="ubuntu",
    connect=lambda url: DesktopDevice(url, platform="ubuntu"),
    wait_ready=wait_ready,
    container_options={"shm_size": "512m"},
    memory="4g",
    booted_memory_mb=200,   # 150 MB idle (`jarvis bench devices`), with room for the task's set-up
    ready_timeout=60.0,
    holder=True,
    describe=describe,
)
