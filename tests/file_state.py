"""A FinalState over files held in memory, for the evaluator tests that need no container."""

from __future__ import annotations

from jarvis_pytest.evaluators.state import FinalState


class _FilesDevice:
    """A device that holds exactly `files`: any other path does not exist, and every command fails."""

    def __init__(self, files: dict[str, bytes]):
        self.files = files

    def exists(self, path: str) -> bool:
        return path in self.files or any(f.startswith(path.rstrip("/") + "/") for f in self.files)

    def download(self, path: str) -> bytes:
        return self.files[path]

    def run(self, command, user=None, timeout=60.0):
        return type("Result", (), {"returncode": 1, "stdout": "", "stderr": ""})()


def state_with(files: dict[str, bytes], platform: str = "ubuntu",
               baselines: dict[str, bytes] | None = None) -> FinalState:
    """A FinalState whose device holds exactly `files` (any other path is missing); `baselines` are the files
    as they were right after set-up."""
    return FinalState(platform=platform, devices={platform: _FilesDevice(dict(files))},
                      baselines={(platform, p): d for p, d in (baselines or {}).items()})
