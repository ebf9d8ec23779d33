"""The input files of a task as set-up left them, hashed: the proof that an instance starts from the same bytes on
any machine, at any time (`TaskResult.inputs`).

A task's input files are those its set-up puts in place and names: every `upload_file` path, every `baseline` path
and every input slot of a file type (`..._file`) of its subtasks. They are read after set-up, before the agent's
first step (the baselines already read are not read again); one that is not there then (a file an upstream subtask
makes, or one a later step of set-up moved) is left out.
"""

from __future__ import annotations

import hashlib
from typing import Sequence

from jarvis_pytest.devices.base import Device
from jarvis_pytest.devices.platforms import spec
from jarvis_pytest.evaluators.state import FinalState
from jarvis_pytest.tasks.model import Subtask, UploadFile
from jarvis_pytest.tasks.transfer import is_transfer


def input_paths(subtasks: Sequence[Subtask]) -> list[tuple[str, str]]:
    """(platform, path) of every input file of `subtasks`, in set-up order, each once."""
    found: list[tuple[str, str]] = []
    for sub in subtasks:
        found += [(step.platform or sub.platform, step.path) for step in sub.config if isinstance(step, UploadFile)]
        found += [(sub.platform, path) for path in sub.baseline]
        if not is_transfer(sub.template):  # a transfer's inputs are the file an upstream subtask makes, elsewhere
            found += [(sub.platform, str(slot.value)) for slot in sub.input.values()
                      if slot.type.endswith("_file") and _absolute(sub.platform, slot.value)]
    return list(dict.fromkeys(found))


def _absolute(platform: str, path: object) -> bool:
    """`path` is a path from a root on `platform`: `/...`, or a drive's `C:\\...` on Windows."""
    if not isinstance(path, str):
        return False
    if spec(platform).path_style == "windows":
        return len(path) > 2 and path[0].isalpha() and path[1] == ":" and path[2] in "\\/"
    return path.startswith("/")


def input_hashes(subtasks: Sequence[Subtask], devices: dict[str, Device],
                 baselines: dict[tuple[str, str], bytes]) -> dict[str, str]:
    """`platform:path` → SHA-256 (hex) of each input file (`input_paths`) now, on `devices`."""
    out: dict[str, str] = {}
    states: dict[str, FinalState] = {}
    for platform, path in input_paths(subtasks):
        data = baselines.get((platform, path))
        if data is None and platform in devices:
            state = states.setdefault(platform, FinalState(platform=platform, devices=devices))
            data = state.pull(path)
        if data is not None:
            out[f"{platform}:{path}"] = hashlib.sha256(data).hexdigest()
    return out
