"""Device backends: how a platform's device comes to life, found through one explicit registry.

A `Backend` is a provider in the sense of Inspect AI's sandbox providers: it owns its device's lifecycle
(`boot`, `close`; the default is one container, `infra/containers.py`), its image and how that image comes
to be (`built` here from `fixtures/images/`, `pulled` from a registry, or `prepared` once on a capable machine,
such as a Windows VM disk), its readiness check and timeout, and its memory and CPU defaults. `infra/` creates
networks and hands a backend what it needs; it knows nothing else about a platform.

`BUILTIN` maps each platform to its backends (imported on first use); `register_backend` adds more (tests,
extensions). `backend_for(platform, name)` picks one: the named backend, else the platform's first backend that
can run on this machine. Every result records the backend that ran (`Backend.label`), and stand-ins
(`stand_in=True`, e.g. Windows under Wine) are marked as such in the tables.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, Literal

from jarvis_pytest.devices.base import Device
from jarvis_pytest.errors import ConfigError, InfrastructureError

if TYPE_CHECKING:
    from jarvis_pytest.infra.containers import BootRequest, BootedDevice

CONTROL_PORT = 5000   # the control server's port inside a device container
ImageKind = Literal["built", "pulled", "prepared"]


@dataclass(frozen=True)
class Backend:
    """Everything `infra/` needs to boot, connect and remove one platform's device."""

    platform: str
    image: str                                   # image name: under fixtures/images/ (built) or a reference
    connect: Callable[[str], Device]             # base URL on 127.0.0.1 → a Device
    wait_ready: Callable[[str, float], None]     # base URL, timeout s → returns when ready, raises otherwise
    name: str = "docker"                         # e.g. docker, wine, kvm, emulator, attach
    port: int = CONTROL_PORT                     # control port inside the container
    container_options: dict[str, Any] = field(default_factory=dict)  # extra docker-py `containers.run` kwargs
    image_kind: ImageKind = "built"
    ready_timeout: float = 60.0                  # seconds from create until ready
    memory: str | None = "4g"                    # default memory limit of one device
    booted_memory_mb: int = 512                  # about what one freshly booted device holds: a pre-warm starts
                                                 # only with this much free above the pool's reserve (`infra/pool.py`)
    cpus: float | None = None                    # default CPU limit of one device
    stand_in: bool = False                       # not the real platform (e.g. Windows under Wine)
    drive_mount: str | None = None               # where the device mounts the task's drive storage, if it does
    holder: bool = False                         # the default boot runs the device in a kept `PortHolder`'s
                                                 # network namespace (only for devices without NET_ADMIN)
    unavailable: Callable[[], str | None] = lambda: None  # why it cannot run on this machine (None: it can)
    how_to_run: str = ""                         # what a user does to run this backend where it cannot run yet

    @property
    def label(self) -> str:
        """What results record: e.g. `ubuntu (docker)`, `windows (wine)`, `windows (kvm)`."""
        return f"{self.platform} ({self.name})"

    @property
    def image_ref(self) -> str:
        """The image reference to run: a built image's tag, or the reference as given."""
        if self.image_kind == "built":
            from jarvis_pytest.infra.images import image_tag

            return image_tag(self.image)
        return self.image

    def boot(self, request: "BootRequest") -> "BootedDevice":
        """Start the device and wait until it is ready (default: one container)."""
        from jarvis_pytest.infra.containers import boot_container

        return boot_container(self, request)

    def close(self, booted: "BootedDevice") -> list[str]:
        """Remove what `boot` made; returns what could not be removed (default: the container)."""
        from jarvis_pytest.infra.containers import remove_all

        return remove_all([booted.container])


# platform → backend name → "module:attribute", imported on first use; the first that can run is the default
BUILTIN: dict[str, dict[str, str]] = {
    "ubuntu": {"docker": "jarvis_pytest.devices.ubuntu.backend:BACKEND"},
    "windows": {"kvm": "jarvis_pytest.devices.windows.backend:KVM",
                "wine": "jarvis_pytest.devices.windows.backend:WINE"},
    "android": {"emulator": "jarvis_pytest.devices.android.backend:EMULATOR",
                "attach": "jarvis_pytest.devices.android.backend:ATTACH"},
}
ALIASES = {("windows", "real"): "kvm"}
_REGISTERED: dict[str, dict[str, Backend]] = {}


def register_backend(backend: Backend) -> None:
    """Add a backend (tests, extensions); it comes before the built-in backends of its platform."""
    _REGISTERED.setdefault(backend.platform, {})[backend.name] = backend


def _load(ref: str) -> Backend:
    module, _, attr = ref.partition(":")
    return getattr(importlib.import_module(module), attr)


def backends_of(platform: str) -> dict[str, Backend]:
    """Every backend of a platform, registered ones first, then the built-in ones in their order."""
    out = dict(_REGISTERED.get(platform, {}))
    for name, ref in BUILTIN.get(platform, {}).items():
        out.setdefault(name, _load(ref))
    return out


def backend_for(platform: str, name: str | None = None) -> Backend:
    """The backend `name` of `platform`, or (no name) the first of its backends that can run here."""
    choices = backends_of(platform)
    if not choices:
        raise InfrastructureError(
            f"no device backend for platform {platform!r} (platforms with backends: "
            f"{sorted(set(BUILTIN) | set(_REGISTERED))})")
    if name not in (None, "", "auto"):
        name = ALIASES.get((platform, name), name)
        if name not in choices:
            raise ConfigError(f"no {platform} backend {name!r}", field=f"--{platform}-backend",
                              fix=f"choose one of {', '.join(['auto', *choices])}")
        return choices[name]
    reasons = []
    for backend in choices.values():
        why = backend.unavailable()
        if why is None:
            return backend
        reasons.append(f"{backend.name}: {why}")
    raise InfrastructureError(f"no {platform} backend can run on this machine ({'; '.join(reasons)})")
