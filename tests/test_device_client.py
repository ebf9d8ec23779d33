"""The host side of a desktop device without a container: the backend contract and how failures surface."""

from __future__ import annotations

import io
import socket
import time

import pytest
from PIL import Image

from jarvis_pytest.devices import actions as A
from jarvis_pytest.devices.backend import CONTROL_PORT, backend_for
from jarvis_pytest.devices.base import Device
from jarvis_pytest.devices.desktop import DesktopDevice, png_size, wait_ready
from jarvis_pytest.errors import InfrastructureError


@pytest.fixture
def closed_url() -> str:
    """A loopback URL where nothing listens."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    return f"http://127.0.0.1:{port}"


def test_the_ubuntu_backend():
    b = backend_for("ubuntu")
    assert (b.platform, b.image, b.port) == ("ubuntu", "ubuntu", CONTROL_PORT)
    assert b.container_options.get("shm_size")
    device = b.connect("http://127.0.0.1:1")
    assert isinstance(device, Device) and device.platform == "ubuntu"


def test_wait_ready_gives_up_with_an_infrastructure_error(closed_url):
    t0 = time.monotonic()
    with pytest.raises(InfrastructureError, match="not ready after"):
        wait_ready(closed_url, 0.5)
    assert time.monotonic() - t0 < 5


def test_an_unreachable_device_is_an_infrastructure_error_not_an_agent_error(closed_url):
    with DesktopDevice(closed_url) as device:
        with pytest.raises(InfrastructureError, match="did not answer POST /action"):
            device.act(A.Click(x=1, y=1))
        with pytest.raises(InfrastructureError, match="did not answer GET /screenshot"):
            device.observe()


def test_png_size_reads_the_header():
    out = io.BytesIO()
    Image.new("RGB", (1920, 1080)).save(out, "PNG")
    assert png_size(out.getvalue()) == (1920, 1080)
