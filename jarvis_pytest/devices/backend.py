"""How the infrastructure layer boots a device of a platform: the contract between `infra/` and `devices/`.

A `Backend` names the image of its platform, the port its control server listens on inside the container, the
container options it needs, and how to connect a host-side `Device` to a published port and wait until it is
ready. `infra/` creates containers and networks; it knows nothing else about a platform. Register backends in
`BACKENDS`; Windows and Android backends will be added here later.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

from jarvis_pytest.devices.base import Device

CONTROL_PORT = 5000          # the control server's port inside a device container
DESKTOP_USER = "user"        # the non-root desktop user of desktop devices
TRANSFER_ALIAS = "transfer"  # the transfer server's name on a task's Docker network
TRANSFER_PORT = 5244
TRANSFER_USER = "agent"
TRANSFER_PASSWORD = "agentPassword"
TRANSFER_FOLDER = "/data"


@dataclass(frozen=True)
class Backend:
    """Everything `infra/` needs to boot and connect one platform's device."""

    platform: str
    image: str                                   # image name under fixtures/images/
    port: int                                    # control port inside the container
    connect: Callable[[str], Device]             # base URL on 127.0.0.1 → a Device
    wait_ready: Callable[[str, float], None]     # base URL, timeout s → returns when ready, raises otherwise
    container_options: dict[str, Any] = field(default_factory=dict)  # extra docker-py `containers.run` kwargs


BACKENDS: dict[str, Backend] = {}


def register_backend(backend: Backend) -> None:
    BACKENDS[backend.platform] = backend


def backend_for(platform: str) -> Backend:
    """The backend of a platform; importing the platform modules registers them."""
    from jarvis_pytest.devices import ubuntu  # noqa: F401  (registers the ubuntu backend)

    try:
        return BACKENDS[platform]
    except KeyError:
        from jarvis_pytest.errors import InfrastructureError

        raise InfrastructureError(
            f"no device backend for platform {platform!r} on this machine (available: {sorted(BACKENDS)}); "
            "Windows and Android devices need KVM images that cannot be built here"
        ) from None
