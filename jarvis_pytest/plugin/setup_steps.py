"""Run a subtask's setup steps (`config`) on its device before the agent starts.

Steps are the typed models of `tasks/model.py`: `UploadFile` (to `path`, from a `fixture` under
`fixtures/files/`, a literal `content`, or a registered file `generator` with `args`), `Command` (`command`,
optional `user`), `Launch` (`app`, `args`), `Open` (`path`) and `Sleep` (`seconds`). A failing step is an
infrastructure error of the task (the task could not be set up), reported with the step and the device's answer.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Sequence

from jarvis_pytest.devices.base import Device
from jarvis_pytest.errors import ConfigError, DeviceFault, InfrastructureError
from jarvis_pytest.tasks.model import Command, Launch, Open, SetupStep, Sleep, Subtask, UploadFile

FIXTURE_FILES = Path(__file__).resolve().parents[2] / "fixtures" / "files"


def _upload(device: Device, step: UploadFile) -> None:
    if step.fixture is not None:
        from jarvis_pytest.tasks.library import fixture_problem

        problem = fixture_problem(step.fixture, FIXTURE_FILES, must_exist=True)
        if problem:  # checked when the task was loaded; checked again where the file is read
            raise ConfigError(problem, field="config.upload_file.fixture", fix="use a file under fixtures/files/")
        data = (FIXTURE_FILES / step.fixture).read_bytes()
    elif step.generator is not None:
        from jarvis_pytest.generators import generate

        data = generate(step.generator, step.args)
    else:
        data = str(step.content).encode("utf-8")
    device.upload(step.path, data)


def _command(device: Device, step: Command) -> None:
    res = device.run(step.command, user=step.user, timeout=float(step.timeout or 120))
    if res.fault:
        raise DeviceFault(f"setup command hit a device fault: {res.fault}: {step.command[:300]}")
    if res.returncode != 0 and not step.allow_fail:
        raise InfrastructureError(f"setup command failed ({res.returncode}): {step.command}\n"
                                  f"{res.stdout[-1500:]}{res.stderr[-1500:]}")


def run_step(device: Device, step: SetupStep) -> None:
    """Carry out one setup step on `device`."""
    if isinstance(step, UploadFile):
        _upload(device, step)
    elif isinstance(step, Command):
        _command(device, step)
    elif isinstance(step, Launch):
        device.launch(step.app, *[str(a) for a in step.args])
    elif isinstance(step, Open):
        device.open(step.path)
    elif isinstance(step, Sleep):
        time.sleep(step.seconds)
    else:  # pragma: no cover - the union is closed
        raise ConfigError(f"unknown setup step {step!r}", field="config.type", fix="see `jarvis schema`")


def run_setup(subtasks: Sequence[Subtask], devices: dict[str, Device]) -> None:
    """Apply every subtask's setup steps in order, each on its step's (or subtask's) platform."""
    for sub in subtasks:
        for step in sub.config:
            platform = step.platform or sub.platform
            if platform not in devices:
                raise InfrastructureError(f"setup of {sub.template} needs the {platform} device")
            run_step(devices[platform], step)
