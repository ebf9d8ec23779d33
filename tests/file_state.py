"""A FinalState over files held in memory, for the evaluator tests that need no container."""

from __future__ import annotations

from jarvis_pytest.evaluators.state import FinalState


class _NoDevice:
    """A device that has no file: `test -e` of any path the state does not hold fails."""

    def run(self, command, user=None):
        return type("Result", (), {"returncode": 1, "stdout": "", "stderr": ""})()


def state_with(files: dict[str, bytes], platform: str = "ubuntu") -> FinalState:
    """A FinalState whose device holds exactly `files` (its pull cache pre-filled; any other path is missing)."""
    state = FinalState(platform=platform, devices={platform: _NoDevice()})
    state._files.update({(platform, path): data for path, data in files.items()})
    return state
