"""Commands, files, application launch and desktop readiness, for the desktop user (root through sudo)."""

from __future__ import annotations

import os
import signal
import subprocess
import threading
from pathlib import Path

DESKTOP_PROCESSES = ("xfwm4", "xfdesktop", "xfce4-panel")  # the desktop is up when these run ...
DESKTOP_WINDOWS = ("xfdesktop", "xfce4-panel")              # ... and the window manager shows their windows


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


def run(command: str, user: str | None, timeout: float) -> dict:
    """Run `command` with bash; on timeout its whole process group is killed and the return code is 124. The
    answer has the fields of `protocol.RunResponse`.

    Processes the command leaves in the background keep running only if they close its output (e.g.
    `app >/dev/null 2>&1 &`); the answer comes when the command's output is closed.
    """
    argv = _argv(command, user)
    proc = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=True)
    try:
        out, err = proc.communicate(timeout=timeout)
        code = proc.returncode
    except subprocess.TimeoutExpired:
        _kill_group(proc.pid, through_sudo=argv[0] == "sudo")
        try:
            out, err = proc.communicate(timeout=5)
        except subprocess.TimeoutExpired:  # a process that left the group still holds the output
            proc.kill()
            out, err = b"", b""
        code, err = 124, err + f"timed out after {timeout:g} s".encode()
    return {"returncode": code, "stdout": out.decode("utf-8", "replace"), "stderr": err.decode("utf-8", "replace"),
            "fault": None}


def _kill_group(pgid: int, through_sudo: bool) -> None:
    """Kill a command's process group; one run through sudo (no pty: it stays in the group) is killed as root."""
    if through_sudo:
        subprocess.run(["sudo", "-n", "kill", "-KILL", "--", f"-{pgid}"], capture_output=True)
        return
    try:
        os.killpg(pgid, signal.SIGKILL)
    except ProcessLookupError:
        pass


def launch(app: str, args: list[str]) -> None:
    """Start an application detached from the server, in the desktop session; it is reaped when it ends (no
    zombie left behind for `pgrep` to find)."""
    proc = subprocess.Popen([app, *args], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True, cwd=os.path.expanduser("~"))
    threading.Thread(target=proc.wait, name=f"reap {app}", daemon=True).start()


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


def path_kind(path: str) -> str | None:
    """`file`, `dir`, `other` or None (missing), as the desktop user sees it (root-only paths through sudo)."""
    p = Path(path)
    try:
        if p.is_file():
            return "file"
        if p.is_dir():
            return "dir"
        if p.exists() or p.is_symlink():
            return "other"
        return None
    except PermissionError:
        res = subprocess.run(["sudo", "-n", "bash", "-c", '[ -f "$1" ] && echo file || { [ -d "$1" ] && echo dir; } '
                              '|| { [ -e "$1" ] && echo other; }', "_", path], capture_output=True, text=True)
        return res.stdout.strip() or None


def clipboard_get() -> str:
    """The text of the CLIPBOARD selection ("" when it holds none)."""
    res = subprocess.run(["xclip", "-selection", "clipboard", "-o"], capture_output=True, timeout=5)
    return res.stdout.decode("utf-8", "replace") if res.returncode == 0 else ""


def clipboard_set(text: str) -> None:
    """Own the CLIPBOARD selection with `text` (xclip keeps serving it in the background)."""
    proc = subprocess.Popen(["xclip", "-selection", "clipboard", "-i"], stdin=subprocess.PIPE,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    proc.stdin.write(text.encode("utf-8"))
    proc.stdin.close()
    threading.Thread(target=proc.wait, name="reap xclip", daemon=True).start()
