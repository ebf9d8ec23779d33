"""Errors that a user can act on: each names the file, the field and the fix."""

from __future__ import annotations


class JarvisError(Exception):
    """Base class of the project's own errors."""


class ConfigError(JarvisError):
    """Bad input (a task file, an option, a type file): says where, what and how to fix it."""

    def __init__(self, message: str, *, path: object | None = None, field: str | None = None, fix: str | None = None):
        self.path = None if path is None else str(path)
        self.field = field
        self.fix = fix
        self.detail = message
        parts = []
        if self.path:
            parts.append(self.path)
        if field:
            parts.append(f"field {field!r}")
        head = ": ".join(parts)
        text = f"{head}: {message}" if head else message
        if fix:
            text += f" (fix: {fix})"
        super().__init__(text)


class InfrastructureError(JarvisError):
    """The harness, not the agent, failed: a device did not boot, an endpoint stayed unreachable, ..."""


class DeviceFault(InfrastructureError):
    """A device failed to carry out a command although the command was fine (e.g. Wine could not start a program
    that exists). Raised only where running the work again on fresh devices is safe: set-up, the oracle and the
    quality gate's near-miss states."""


DEVICE_FAULT_ATTEMPTS = 3  # work hit by a DeviceFault is done on fresh devices up to this many times in all


def retry_device_faults(work):
    """`work(faults)` until it does not raise DeviceFault, at most DEVICE_FAULT_ATTEMPTS times (the last fault is
    raised); returns its value and the messages of the faults before it. `work` boots its own fresh devices."""
    faults: list[str] = []
    while True:
        try:
            return work(faults), faults
        except DeviceFault as exc:
            if len(faults) + 1 >= DEVICE_FAULT_ATTEMPTS:
                raise
            faults.append(str(exc))
