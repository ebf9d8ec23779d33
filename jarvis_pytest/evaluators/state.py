"""The final state of a task as evaluators see it: getters that pull files and facts from the devices to the host.

Pulled files are cached for the evaluation of one task, so several evaluators of one file cost one download.
Getters return `None` for a file that does not exist, so checks can say "found no file".
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

from jarvis_pytest.devices.base import Device, run_read_only
from jarvis_pytest.errors import DEVICE_FAULT_ATTEMPTS, DeviceFault, InfrastructureError
from jarvis_pytest.evaluators.registry import Verdict


@dataclass
class FinalState:
    """Access to the final state of one subtask: its platform's device, the other devices, the transfer drive."""

    platform: str
    devices: dict[str, Device]
    transfer: Any = None  # the transfer-drive client (list/download), when the task has one
    baselines: dict[tuple[str, str], bytes] = field(default_factory=dict)  # (platform, path) → bytes at set-up
    ledger: Any = None    # what the drive received and served in the agent's turn (`ledger.DriveLedger`), if kept
    chain: Any = None     # a transfer subtask's place in its graph (`tasks.transfer.TransferLinks`), if composed
    _files: dict[tuple[str, str], bytes | None] = field(default_factory=dict)

    def device(self, platform: str | None = None) -> Device:
        name = platform or self.platform
        try:
            return self.devices[name]
        except KeyError:
            raise InfrastructureError(f"evaluator needs the {name} device, which this task did not boot") from None

    def run(self, command: str, platform: str | None = None, user: str | None = None):
        """Run a shell command on the device (as the desktop user unless `user` is given). Evaluators only read,
        so a command the device failed to carry out (`fault`) is simply run again; a device that keeps
        failing raises DeviceFault (never a verdict on a half-run command)."""
        res = run_read_only(self.device(platform), command, user=user)
        if not res.fault:
            return res
        raise DeviceFault(f"an evaluator's command hit a device fault {DEVICE_FAULT_ATTEMPTS} times: {res.fault}: "
                          f"{command[:300]}")

    def exists(self, path: str, platform: str | None = None) -> bool:
        return self.device(platform).exists(path)

    def pull(self, path: str, platform: str | None = None) -> bytes | None:
        """The bytes of a file on the device, or None when it does not exist."""
        key = (platform or self.platform, path)
        if key not in self._files:
            self._files[key] = self.device(platform).download(path) if self.exists(path, platform) else None
        return self._files[key]

    def baseline(self, path: str, platform: str | None = None) -> bytes | None:
        """The content `path` had right after set-up, when the template lists it under `baseline` and it existed
        then (None otherwise: e.g. a file an upstream subtask of a composed task makes)."""
        return self.baselines.get((platform or self.platform, path))

    def pull_text(self, path: str, platform: str | None = None) -> str | None:
        data = self.pull(path, platform)
        return None if data is None else as_text(data)


def as_text(data: bytes) -> str:
    """File bytes as text (UTF-8; undecodable bytes replaced)."""
    return data.decode("utf-8", errors="replace")


def judge_file(state: FinalState, path: str, want: str, parse: Callable[[bytes], Any],
               check: Callable[[Any], Verdict], platform: str | None = None) -> Verdict:
    """Pull `path`, `parse` its bytes and `check` the result. A missing file, or one that does not parse (a
    corrupt or wrong-format file is a finding, not a crash), is a failed verdict saying so."""
    data = state.pull(path, platform)
    if data is None:
        return Verdict.check(False, want, f"no file at {path}")
    try:
        parsed = parse(data)
    except Exception as exc:
        return Verdict.check(False, want, f"{path} unreadable: {exc}")
    return check(parsed)
