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
from jarvis_pytest.paths import FIXTURE_FILES
from jarvis_pytest.tasks.model import Command, Launch, Open, SetupStep, Sleep, Subtask, UploadFile


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


def _window_ids(device: Device) -> dict[int, dict] | None:
    """The device's top-level windows by id, where it lists them (desktops: `windows()`); None elsewhere."""
    listing = getattr(device, "windows", None)
    if listing is None:
        return None
    return {w["id"]: w for w in listing() if w.get("id") is not None}


def run_setup(subtasks: Sequence[Subtask], devices: dict[str, Device]) -> dict[int, tuple[str, int]]:
    """Apply every subtask's setup steps in order, each on its step's (or subtask's) platform. Returns the window
    each subtask's set-up opened (a `launch` or `open` step), where the device lists windows: subtask index →
    (platform, window id) of its largest new window (`_main_first`; `window_titles` reads their titles), which is
    brought to the front."""
    opened: dict[int, tuple[str, int]] = {}
    for s, sub in enumerate(subtasks):
        for step in sub.config:
            platform = step.platform or sub.platform
            if platform not in devices:
                raise InfrastructureError(f"setup of {sub.template} needs the {platform} device")
            before = _window_ids(devices[platform]) if isinstance(step, (Launch, Open)) else None
            run_step(devices[platform], step)
            if before is not None:
                new = _new_windows(devices[platform], before)
                if new:
                    window = max(new, key=_main_first)
                    opened[s] = (platform, window["id"])
                    _to_front(devices[platform], window)
    return opened


def _to_front(device: Device, window: dict) -> None:
    """The window a set-up step opened is the one in front, with the keyboard, whatever the timing: XFCE's focus
    stealing prevention can leave the keyboard with an earlier window that the new one covers (sw-0012: Calc on
    top, the keys going to Chromium under it), a state that differs from run to run and confuses any agent."""
    focus = getattr(device, "focus_window", None)
    if focus is None or window.get("focused"):
        return
    if getattr(device, "names_windows", False):
        focus(id=window["id"], timeout=2.0)
    elif window.get("title"):
        focus(window["title"], timeout=2.0)


NEW_WINDOW_WAIT = 15.0  # seconds a launch that changed a window's title (not a new window) gets to show its own


def _new_windows(device: Device, before: dict[int, dict], wait: float = NEW_WINDOW_WAIT) -> list[dict]:
    """The windows a launch opened: those not in `before`. Where there is none yet, they are awaited: a program
    already running answers a second launch with a new window of its own process some seconds later (LibreOffice's
    "Untitled 1" came to the front after set-up, over the window the first subtask works in: sw-0046), and the
    launch's own wait may have ended on another window's title changing."""
    deadline = time.monotonic() + wait
    while True:
        new = [w for i, w in (_window_ids(device) or {}).items() if i not in before]
        if new or time.monotonic() >= deadline:
            return new
        time.sleep(0.25)


def _main_first(window: dict) -> tuple:
    """How a new window ranks as the one set-up opened: the largest (an application's window, not the dialog it
    shows at start, Ristretto's thumbnailer warning), then the focused one, then the newest."""
    box = window.get("box") or [0, 0, 0, 0]
    return max(box[2], 0) * max(box[3], 0), bool(window.get("focused")), window["id"]


def window_titles(opened: dict[int, tuple[str, int]], devices: dict[str, Device]) -> dict[int, str]:
    """The titles the windows set-up opened (`run_setup`'s answer) show now, by subtask; a window that went, or
    has no title, is left out."""
    now: dict[str, dict[int, dict]] = {}
    titles: dict[int, str] = {}
    for s, (platform, wid) in opened.items():
        if platform not in now:
            now[platform] = _window_ids(devices[platform]) or {}
        title = (now[platform].get(wid) or {}).get("title")
        if title:
            titles[s] = title
    return titles
