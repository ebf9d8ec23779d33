"""Run a subtask's setup steps (`config`) on its device before the agent starts.

Steps are dicts with a `type`: `upload_file` (`path` on the device from `fixture` under `fixtures/files/`, a
literal `content`, or a registered file `generator` with `args`), `command` (`command`, optional `user`), `launch` (`app`, `args`), `open` (`path`),
`sleep` (`seconds`). A failing step is an infrastructure error of the task (the task could not be set up),
reported with the step and the device's answer.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Callable

from jarvis_pytest.devices.base import Device
from jarvis_pytest.errors import ConfigError, InfrastructureError

FIXTURE_FILES = Path(__file__).resolve().parents[2] / "fixtures" / "files"


def _upload(device: Device, step: dict[str, Any]) -> None:
    path = step["path"]
    if step.get("fixture") is not None:
        from jarvis_pytest.tasks.library import fixture_problem

        problem = fixture_problem(step["fixture"], FIXTURE_FILES, must_exist=True)
        if problem:  # checked when the task was loaded; checked again where the file is read
            raise ConfigError(problem, field="config.upload_file.fixture", fix="use a file under fixtures/files/")
        data = (FIXTURE_FILES / step["fixture"]).read_bytes()
    elif step.get("generator") is not None:
        from jarvis_pytest.generators import generate

        data = generate(step["generator"], step.get("args") or {})
    elif step.get("content") is not None:
        data = str(step["content"]).encode("utf-8")
    else:
        raise ConfigError("upload_file needs `fixture` or `content`", field="config.upload_file",
                          fix="name a file under fixtures/files/ or give literal content")
    device.upload(path, data)


def _command(device: Device, step: dict[str, Any]) -> None:
    res = device.run(step["command"], user=step.get("user"), timeout=float(step.get("timeout", 120)))
    if res.returncode != 0 and not step.get("allow_fail", False):
        raise InfrastructureError(f"setup command failed ({res.returncode}): {step['command']}\n"
                                  f"{res.stdout[-1500:]}{res.stderr[-1500:]}")


def _launch(device: Device, step: dict[str, Any]) -> None:
    device.launch(step["app"], *[str(a) for a in step.get("args", [])])


def _open(device: Device, step: dict[str, Any]) -> None:
    device.open(step["path"])


def _sleep(device: Device, step: dict[str, Any]) -> None:
    time.sleep(float(step.get("seconds", 1)))


STEP_TYPES: dict[str, Callable[[Device, dict[str, Any]], None]] = {
    "upload_file": _upload,
    "command": _command,
    "launch": _launch,
    "open": _open,
    "sleep": _sleep,
}


def run_setup(subtasks: list[dict[str, Any]], devices: dict[str, Device]) -> None:
    """Apply every subtask's setup steps in order, each on its step's (or subtask's) platform."""
    for sub in subtasks:
        for step in sub.get("config", []):
            kind = step.get("type")
            if kind not in STEP_TYPES:
                raise ConfigError(f"unknown setup step type {kind!r} in subtask {sub.get('template')}",
                                  field="config.type", fix=f"use one of {sorted(STEP_TYPES)}")
            platform = step.get("platform") or sub["platform"]
            if platform not in devices:
                raise InfrastructureError(f"setup of {sub.get('template')} needs the {platform} device")
            STEP_TYPES[kind](devices[platform], step)


