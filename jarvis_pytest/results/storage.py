"""Whether a results folder can take a run's files: writable, and at least a small minimum of free space.

Checked at start-up (a run refuses a folder it could not write into) and again when a write fails or a task
starts (a folder that filled mid-run ends the run: `plugin/session.py`). The minimum is `$JARVIS_MIN_FREE_MB`,
default MIN_FREE_MB (a task writes a few MB: screenshots, its trajectory, its result).
"""

from __future__ import annotations

import os
from pathlib import Path

from jarvis_pytest.errors import ConfigError

MIN_FREE_ENV = "JARVIS_MIN_FREE_MB"
MIN_FREE_MB = 20
PROBE_BYTES = 4096


def min_free_mb() -> float:
    """The free space (MiB) a results folder must have: $JARVIS_MIN_FREE_MB, else MIN_FREE_MB."""
    raw = os.environ.get(MIN_FREE_ENV, "")
    try:
        return max(0.0, float(raw)) if raw else float(MIN_FREE_MB)
    except ValueError:
        raise ConfigError(f"not a number of MiB: {raw!r}", field=MIN_FREE_ENV,
                          fix=f"set it to a number such as {MIN_FREE_MB}, or unset it") from None


def problem(folder: Path, create: bool = True) -> str | None:
    """Why `folder` cannot take a run's files now (it cannot be made, or is gone when not `create`; a file cannot
    be written and synced there; it has less free space than `min_free_mb()`), or None when it can."""
    folder = Path(folder)
    if not create and not folder.is_dir():
        return "the results folder is gone (removed while the run wrote into it)"
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        return f"cannot create the results folder ({exc.strerror or exc})"
    probe = folder / f".jarvis-write-probe-{os.getpid()}"
    try:
        fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        try:
            os.write(fd, b"\0" * PROBE_BYTES)
            os.fsync(fd)
        finally:
            os.close(fd)
    except OSError as exc:
        return f"cannot write into the results folder ({exc.strerror or exc})"
    finally:
        try:
            probe.unlink()
        except OSError:
            pass
    need = min_free_mb()
    try:
        st = os.statvfs(folder)
    except OSError as exc:
        return f"cannot tell the free space of the results folder ({exc.strerror or exc})"
    free = st.f_bavail * st.f_frsize / 2**20
    if free < need:
        return f"the results folder's file system is full: {free:.1f} MiB free, a run needs at least {need:g} MiB"
    return None


def check(folder: Path, option: str = "--results-dir") -> None:
    """Raise ConfigError naming `folder` when it cannot take a run's files (`problem`)."""
    why = problem(folder)
    if why is not None:
        raise ConfigError(why, path=folder, field=option,
                          fix=f"free space there, make it writable, or give another {option} "
                              f"(the minimum free space is ${MIN_FREE_ENV}, default {MIN_FREE_MB} MiB)")
