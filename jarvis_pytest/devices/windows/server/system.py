"""Commands (`cmd /c` in a Job object, killed with everything it started on timeout), files by Windows path,
program launch by name or path, opening a file with its associated program."""

from __future__ import annotations

import ctypes
import ntpath
import os
import re
import shutil
import subprocess
import threading
import time

from . import win32 as w
from .programs import KNOWN_PROGRAMS

USERS_ALLOWED = {"", "user", "root", "admin", "administrator", "system"}  # all run as the server's own account


class PathError(ValueError):
    """A path that is not an absolute Windows path."""


def windows_path(path: str) -> str:
    """An absolute Windows path (`C:\\...`; forward slashes accepted), normalised; PathError otherwise."""
    p = path.replace("/", "\\")
    drive, rest = ntpath.splitdrive(p)
    if not drive or not rest.startswith("\\"):
        raise PathError(f"path {path!r} must be an absolute Windows path such as C:\\Users\\user\\Desktop\\a.txt")
    return ntpath.normpath(p)


def decode(data: bytes) -> str:
    """Command output as text: UTF-16 when it is (`cmd /u`), UTF-8 when it is valid UTF-8, else the ANSI code page
    (what `cmd` writes without a console, e.g. cp1252), else the OEM one. Characters outside the ANSI code page
    (e.g. CJK in `echo`) are lost by `cmd` itself before they reach us, as on Windows."""
    if data.startswith(b"\xff\xfe") or (len(data) >= 4 and data[1:4:2] == b"\0\0" and data[0] and data[2]):
        try:
            return data.decode("utf-16-le").lstrip("\ufeff")
        except UnicodeDecodeError:
            pass
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        pass
    for cp in (w.GetACP(), w.GetOEMCP()):
        try:
            return data.decode(f"cp{cp}")
        except (UnicodeDecodeError, LookupError):
            continue
    return data.decode("utf-8", "replace")


def _job() -> int:
    job = w.CreateJobObjectW(None, None)
    if not job:
        raise OSError(f"CreateJobObject failed (error {ctypes.get_last_error()})")
    return job


ERROR_INTERNAL_ERROR = 1359  # what Wine's CreateProcess now and then answers (the new process died while it started)


def _popen(args: str | list[str], attempts: int = 3, **kwargs) -> subprocess.Popen:
    """`subprocess.Popen(args, **kwargs)`; a start that fails with Wine's transient internal error is tried again
    (nothing ran, so nothing is done twice); any other failure is raised at once."""
    for attempt in range(attempts):
        try:
            return subprocess.Popen(args, **kwargs)
        except OSError as exc:
            if getattr(exc, "winerror", None) != ERROR_INTERNAL_ERROR or attempt == attempts - 1:
                raise
            time.sleep(0.2 * (attempt + 1))
    raise AssertionError("unreachable")


# What `cmd` prints when it cannot start a program: Wine's cmd says so also when the program exists and only its
# start failed (the transient internal error above, inside cmd); Windows' own wording for a missing program.
_NOT_STARTED = re.compile(r"Can't recognize '(?P<wine>.+?)' as an internal or external command"
                          r"|'(?P<win>[^'\r\n]+)' is not recognized as an internal or external command")


def _first_word(command: str) -> str:
    command = command.strip()
    if command.startswith('"'):
        return command[1:].split('"', 1)[0]
    return command.split(None, 1)[0] if command else ""


def start_fault(stderr: str) -> str | None:
    """Why the output says a program could not be started although it exists (a fault of the device), or None
    when every program named was missing or started. Whatever the return code: Wine's cmd goes on after such a
    failure as if the program had run and failed (`a && b && c` runs `c` when `b` could not start)."""
    for match in _NOT_STARTED.finditer(stderr):
        program = _first_word(match.group("wine") or match.group("win") or "")
        where = resolve(program) if program else None
        if where:
            return f"{program} exists ({where}) but the device could not start it: the command did not all run"
    return None


def run(command: str, timeout: float) -> dict:
    """Run `command` with `cmd /c`; on timeout the command and every process it started are killed (return code
    124). Programs it leaves running in the background keep running (e.g. `start notepad`). `fault` says when
    the device, not the command, failed: `cmd` itself or a program it names could not be started."""
    job = _job()
    try:
        # A hidden console (CREATE_NO_WINDOW), not none: without one (DETACHED_PROCESS) every console program cmd
        # starts (reg, hostname, python) gets a console of its own and its output never reaches our pipes.
        try:
            proc = _popen(f'cmd.exe /d /s /c "{command}"', stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, creationflags=w.CREATE_SUSPENDED | w.CREATE_NO_WINDOW,
                          cwd=os.path.expanduser("~"))
        except OSError as exc:
            if getattr(exc, "winerror", None) != ERROR_INTERNAL_ERROR:
                raise
            return {"returncode": 9009, "stdout": "", "stderr": str(exc),
                    "fault": f"cmd.exe could not be started ({exc}); nothing ran"}
        handle = int(proc._handle)  # the process handle Popen holds
        w.AssignProcessToJobObject(job, handle)  # before it runs: whatever it starts belongs to the job too
        w.NtResumeProcess(handle)
        try:
            out, err = proc.communicate(timeout=timeout)
            code = proc.returncode
        except subprocess.TimeoutExpired:
            w.TerminateJobObject(job, 124)
            try:
                out, err = proc.communicate(timeout=5)
            except subprocess.TimeoutExpired:
                proc.kill()
                out, err = b"", b""
            code, err = 124, err + f"timed out after {timeout:g} s".encode()
    finally:
        w.CloseHandle(job)
    stderr = decode(err)
    return {"returncode": code, "stdout": decode(out), "stderr": stderr, "fault": start_fault(stderr)}


def resolve(app: str) -> str | None:
    """The executable of a program name (on PATH, with PATHEXT; App Paths; known places) or of a full path."""
    if "\\" in app or "/" in app or ":" in app:
        path = os.path.expandvars(app)
        for candidate in (path, path + ".exe"):
            if os.path.isfile(candidate):
                return candidate
        return None
    found = shutil.which(app)
    if found:
        return found
    name = app if app.lower().endswith(".exe") else app + ".exe"
    import winreg

    for root in (winreg.HKEY_CURRENT_USER, winreg.HKEY_LOCAL_MACHINE):
        try:
            path = os.path.expandvars(winreg.QueryValue(root, rf"Software\Microsoft\Windows\CurrentVersion\App Paths"
                                                              rf"\{name}").strip('"'))
            if os.path.isfile(path):
                return path
        except OSError:
            continue
    known = KNOWN_PROGRAMS.get(app.lower().removesuffix(".exe"))
    if known and os.path.isfile(os.path.expandvars(known)):
        return os.path.expandvars(known)
    return None


def _reap(proc: subprocess.Popen) -> None:
    threading.Thread(target=proc.wait, name="reap", daemon=True).start()


def launch(app: str, args: list[str]) -> int:
    """Start a program detached from the server (a console program in its own console window); its process id.
    FileNotFoundError when there is no such program."""
    exe = resolve(app)
    if exe is None:
        raise FileNotFoundError(app)
    # No standard handles given: a console program talks to its new console window (cmd stays open).
    flags = subprocess.CREATE_NEW_CONSOLE | subprocess.CREATE_NEW_PROCESS_GROUP
    proc = _popen([exe, *args], creationflags=flags, cwd=os.path.expanduser("~"))
    _reap(proc)
    return proc.pid


def open_path(path: str) -> int:
    """Open a file or folder with its associated program (ShellExecuteEx "open"); the id of the process it
    started, 0 when it started none (the file went to a program that was running)."""
    mask = w.SEE_MASK_FLAG_NO_UI | w.SEE_MASK_NOASYNC | w.SEE_MASK_NOCLOSEPROCESS
    info = w.SHELLEXECUTEINFOW(cbSize=ctypes.sizeof(w.SHELLEXECUTEINFOW), lpVerb="open", lpFile=path,
                               nShow=w.SW_SHOWNORMAL, fMask=mask, lpDirectory=ntpath.dirname(path))
    if not w.ShellExecuteExW(ctypes.byref(info)):
        raise OSError(ctypes.get_last_error(), f"no program opens {path} (error {ctypes.get_last_error()})")
    if not info.hProcess:
        return 0
    try:
        return int(w.GetProcessId(info.hProcess))
    finally:
        w.CloseHandle(info.hProcess)


def write_file(path: str, data: bytes) -> None:
    os.makedirs(ntpath.dirname(path), exist_ok=True)
    with open(path, "wb") as f:
        f.write(data)


def read_file(path: str) -> bytes:
    with open(path, "rb") as f:
        return f.read()


def exists(path: str) -> dict:
    if os.path.isdir(path):
        return {"exists": True, "kind": "dir"}
    if os.path.exists(path):
        return {"exists": True, "kind": "file"}
    return {"exists": False, "kind": None}
