"""The Ubuntu-platform backend: the `ubuntu` image (XFCE desktop) driven through its control server."""

from __future__ import annotations

from jarvis_pytest.devices.backend import Backend
from jarvis_pytest.devices.desktop import DesktopDevice, wait_ready

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
)
