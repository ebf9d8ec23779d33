"""The platform-independent device interface. Backends (Ubuntu container now; Windows, Android later) implement it."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

from jarvis_pytest.devices.actions import Action


@dataclass(frozen=True)
class Observation:
    """What an agent sees of one device at one step."""

    platform: str
    screenshot_png: bytes
    width: int
    height: int
    a11y_tree: str | None = None
    available: bool = True  # False: a device the task does not use (initial screenshot only)


@dataclass(frozen=True)
class ActionOutcome:
    """What executing one action did. `error` is fed back to the agent's history, never raised."""

    ok: bool
    error: str | None = None
    elapsed_ms: float = 0.0


@dataclass(frozen=True)
class CommandResult:
    returncode: int
    stdout: str
    stderr: str
    extra: dict = field(default_factory=dict)
    fault: str | None = None  # the device could not start a program that exists (RunResponse.fault)


@runtime_checkable
class Device(Protocol):
    """One device of a task: observe, act, move files, run commands."""

    platform: str

    def observe(self, *, a11y: bool = False) -> Observation: ...

    def act(self, action: Action) -> ActionOutcome: ...

    def screen_size(self) -> tuple[int, int]: ...

    def upload(self, path: str, data: bytes) -> None: ...

    def download(self, path: str) -> bytes: ...

    def run(self, command: str, *, timeout: float = 60.0, user: str | None = None) -> CommandResult: ...

    def launch(self, app: str, *args: str, window_wait: float = 20.0) -> bool:
        """Start an application; return once it shows a window (True) or after `window_wait` s (False)."""

    def open(self, path: str, *, window_wait: float = 20.0) -> bool:
        """Open a file or folder with the device's default application; True once its window shows."""

    def exists(self, path: str) -> bool:
        """Whether a file or folder exists at `path` on the device."""


def run_read_only(device: "Device", command: str, **options) -> CommandResult:
    """Run a command that only reads; one the device failed to carry out (`CommandResult.fault`: Wine's cmd could
    not start a program that exists) is run again, up to DEVICE_FAULT_ATTEMPTS runs in all. The last result is
    returned, still with its fault where every run had one: the caller says what that means."""
    from jarvis_pytest.errors import DEVICE_FAULT_ATTEMPTS

    for _ in range(DEVICE_FAULT_ATTEMPTS):
        result = device.run(command, **options)
        if not result.fault:
            break
    return result
