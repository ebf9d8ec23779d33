"""The Ubuntu-platform backend: the `ubuntu` image (XFCE desktop) driven through its control server."""

from __future__ import annotations

from jarvis_pytest.devices.backend import CONTROL_PORT, Backend, register_backend
from jarvis_pytest.devices.desktop import DesktopDevice, wait_ready

register_backend(Backend(
    platform="ubuntu",
    image="ubuntu",
    port=CONTROL_PORT,
    connect=lambda url: DesktopDevice(url, platform="ubuntu"),
    wait_ready=wait_ready,
    container_options={"shm_size": "512m"},
))
