"""Commands, files, application launch and desktop readiness, for the desktop user (root through sudo)."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

from jarvis_pytest.devices.protocol import RunResponse

DESKTOP_PROCESSES = ("xfwm4", "xfdesktop", "xfce4-panel")


def running(names: tuple[str, ...]) -> dict[str, bool]:
    """Which of these process names run (read from /proc, no process spawned)."""
    found = {n: False for n in names}
    for pid in os.listdir("/proc"):
        if pid.isdigit():
            try:
                comm = Path(f"/proc/{pid}/comm").read_text().strip()
            except OSError:
                continue
            if comm in found:
                found[comm] = True
    return found


def _argv(command: str, user: str | None) -> list[str]:
    if user in (None, "", "user", os.environ.get("USER", "user")):
        return ["bash", "-c", command]
    if user == "root":
        return ["sudo", "-n", "-E", "bash", "-c", command]
    return ["sudo", "-n", "-E", "-u", user, "bash", "-c", command]


def run(command: str, user: str | None, timeout: float) -> RunResponse:
    try:
        proc = subprocess.run(_argv(command, user), capture_output=True, timeout=timeout, stdin=subprocess.DEVNULL)
        return RunResponse(returncode=proc.returncode, stdout=proc.stdout.decode("utf-8", "replace"),
                           stderr=proc.stderr.decode("utf-8", "replace"))
    except subprocess.TimeoutExpired as exc:
        out = (exc.stdout or b"").decode("utf-8", "replace")
        return RunResponse(returncode=124, stdout=out, stderr=f"timed out after {timeout:g} s")


def launch(app: str, args: list[str]) -> None:
    """Start an application detached from the server, in the desktop session."""
    subprocess.Popen([app, *args], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                     stderr=subprocess.DEVNULL, start_new_session=True, cwd=os.path.expanduser("~"))


def write_file(path: str, data: bytes) -> None:
    """Write `path` (parents created); paths the desktop user cannot write are written through sudo."""
    p = Path(path)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(data)
    except PermissionError:
        res = subprocess.run(["sudo", "-n", "bash", "-c", 'mkdir -p "$(dirname "$1")" && cat > "$1"', "_", path],
                             input=data, capture_output=True)
        if res.returncode != 0:
            raise PermissionError(res.stderr.decode("utf-8", "replace").strip() or f"cannot write {path}")


def read_file(path: str) -> bytes:
    try:
        return Path(path).read_bytes()
    except PermissionError:
        res = subprocess.run(["sudo", "-n", "cat", "--", path], capture_output=True)
        if res.returncode != 0:
            raise
        return res.stdout
