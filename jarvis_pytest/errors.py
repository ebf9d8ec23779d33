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
