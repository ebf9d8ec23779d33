"""HTTP routing of the Windows control server: the Ubuntu server's API and JSON shapes (`devices/protocol.py`),
validated by hand (`devices/validate.py`: no pydantic on the embeddable CPython); the plumbing shared with every
platform's server is in `devices/control_http.py`. Every bad request gets a 4xx JSON `{"error": ...}`; nothing
crashes it."""

from __future__ import annotations

import time

from jarvis_pytest.devices.control_http import (ControlHandler, ControlServer, HttpError, Lazy, execute,
                                                readiness_within)

PLATFORM = "windows"


def _screen():
    from .screen import Screen

    return Screen()


def _input():
    from .input import Input

    return Input()


DEVICES = Lazy(screen=_screen, input=_input)  # screen and input, made on first use


def _pyautogui(script: str) -> None:
    """A PYAUTOGUI script, in a child process of its own (`run_script_here` there)."""
    import sys

    from jarvis_pytest.devices.pyautogui_compat import run_isolated

    run_isolated([sys.executable, "-m", "jarvis_pytest.devices.windows.server", "--run-script"], script)


def run_script_here(script: str) -> None:
    """A PYAUTOGUI script on this process's own input (the child of `_pyautogui`)."""
    from jarvis_pytest.devices.pyautogui_compat import run_script

    kb = DEVICES.input
    run_script(script, kb, kb.position, DEVICES.screen.size)


def _shell_readiness() -> dict[str, bool]:
    """What of the shell is up (all True once it was seen ready: `DEVICES.ready` latches)."""
    if DEVICES.ready:
        return {"ready": True}
    from .desktop import readiness

    try:
        details = readiness(DEVICES.screen)
    except Exception:  # the display is not up yet
        details = {"taskbar": False, "painted": False}
    DEVICES.ready = all(details.values())
    return details


class Handler(ControlHandler):
    server_version = "jarvis-control-windows/1"

    def _path_arg(self) -> str:
        from .system import PathError, windows_path

        try:
            return windows_path(self._query().get("path", ""))
        except PathError as exc:
            raise HttpError(400, f"query parameter `path`: {exc}") from None

    # -- endpoints --------------------------------------------------------------------------------------------
    def health(self) -> None:
        """Ready = the shell's taskbar exists, shows and is drawn (then it stays so: an agent's full-screen window
        must not make the device "unready"). `?wait=S` holds the answer up to S seconds until the device is
        ready."""
        details = readiness_within(_shell_readiness, self._health_wait())
        ready = all(details.values())
        self._json(200, {"ok": True, "desktop": ready, "details": {"ready": True} if ready else details})

    def screen_size(self) -> None:
        w, h = DEVICES.screen.size()
        self._json(200, {"width": w, "height": h})

    def screenshot(self) -> None:
        fmt = self._query().get("format", "png")
        if fmt == "png":
            self._send(200, DEVICES.screen.png(), "image/png")
        elif fmt == "bmp":
            self._send(200, DEVICES.screen.bmp(), "image/bmp")
        else:
            raise HttpError(400, f"query parameter `format` must be png or bmp, not {fmt!r}")

    def a11y(self) -> None:
        from .a11y import tree

        q = self._query()
        try:
            limits = dict(max_nodes=int(q.get("max_nodes", 2000)), max_depth=int(q.get("max_depth", 30)),
                          timeout=float(q.get("timeout", 5)), showing_only=q.get("all", "0") in ("0", "false"))
            if limits["max_nodes"] < 1 or limits["max_depth"] < 1 or not 0 < limits["timeout"] <= 60:
                raise ValueError
        except ValueError:
            raise HttpError(400, "max_nodes and max_depth must be integers ≥ 1 and timeout a number of seconds "
                                 "in (0, 60]") from None
        self._json(200, tree(**limits))

    def action(self) -> None:
        from .input import InputError

        action = self._action()
        t0 = time.perf_counter()
        try:
            execute(action, DEVICES.input, PLATFORM, _pyautogui)
        except InputError as exc:
            raise HttpError(400, str(exc)) from None
        self._json(200, {"ok": True, "error": None, "elapsed_ms": (time.perf_counter() - t0) * 1000})

    def put_file(self) -> None:
        from .system import write_file

        path = self._path_arg()
        try:
            write_file(path, self._body())
        except (PermissionError, IsADirectoryError, NotADirectoryError, FileExistsError) as exc:
            raise HttpError(403, f"cannot write {path}: {exc}") from None
        except FileNotFoundError as exc:  # e.g. a drive letter that does not exist
            raise HttpError(404, f"cannot write {path}: {exc}") from None
        self._json(200, {"ok": True, "path": path})

    def get_file(self) -> None:
        from .system import read_file

        path = self._path_arg()
        try:
            data = read_file(path)
        except FileNotFoundError:
            raise HttpError(404, f"no file at {path}") from None
        except (PermissionError, IsADirectoryError) as exc:
            raise HttpError(403, f"cannot read {path}: {exc}") from None
        self._send(200, data, "application/octet-stream")

    def exists(self) -> None:
        from .system import exists

        self._json(200, exists(self._path_arg()))

    def run(self) -> None:
        from .system import USERS_ALLOWED, run

        req = self._request("run")
        if (req["user"] or "").lower() not in USERS_ALLOWED:
            raise HttpError(400, f"run.user: {req['user']!r} is not an account of this device (commands run as the "
                                 "desktop user, who is an administrator)")
        self._json(200, run(req["command"], req["timeout"]))

    def launch(self) -> None:
        """Start a program; with `window_wait`, answer once a new application window shows or an existing one
        changed its title, so the next screenshot shows the program; `id` names that window."""
        from .desktop import app_windows, new_window
        from .system import launch

        req = self._request("launch")
        before = app_windows() if req["window_wait"] else {}
        try:
            pid = launch(req["app"], req["args"])
        except FileNotFoundError:
            raise HttpError(404, f"no application {req['app']!r} on this device (give a program on its PATH, e.g. "
                                 "notepad, wordpad, regedit, explorer, cmd, taskmgr, or a full path)") from None
        except OSError as exc:
            raise HttpError(400, f"cannot start {req['app']!r}: {exc}") from None
        self._window_shown(new_window(before, req["window_wait"], pid))

    def _window_shown(self, hwnd: int | None) -> None:
        self._json(200, {"ok": True, "window": hwnd is not None, "id": hwnd})

    def focus(self) -> None:
        """Bring a window to the front: the one `id` names (with `title`: once it shows that title, e.g. a program
        launched a moment ago that is still loading its file), else the newest application window whose title shows
        `title` (`desktop.newest`), waiting up to `timeout` s for it; 404 when there is none. A foreground that is
        already the window's own (it, a menu it opened, a dialog it shows) is left as it is. Answers once the
        foreground is the window's own (409 when it does not become so): `id`, `title`, `pid` of the window,
        `changed` (whether the foreground had to move) and `before` (the foreground window then)."""
        from jarvis_pytest.devices.control_http import title_matches

        from . import win32 as w
        from .desktop import belongs_to, bring_to_front, describe, newest, shows

        req = self._request("focus")
        title, hwnd = req["title"], req["id"]
        if title is None and hwnd is None:
            raise HttpError(400, "invalid request: focus needs `title` or `id`")
        deadline = time.monotonic() + req["timeout"]
        while True:
            if hwnd is not None:
                found = hwnd if shows(hwnd) and (title is None or title_matches(title, w.window_text(hwnd))) else None
            else:
                found = newest(title)
            if found or time.monotonic() >= deadline or (hwnd is not None and not shows(hwnd)):
                break
            time.sleep(0.1)
        if not found:
            if hwnd is None:
                raise HttpError(404, f"no window whose title contains {title!r}")
            raise HttpError(404, f"window {hwnd} is gone" if not shows(hwnd) else
                            f"window {hwnd} does not show {title!r} (its title: {w.window_text(hwnd)!r})")
        fg = w.GetForegroundWindow() or 0
        before = describe(fg)
        changed = not belongs_to(fg, found)
        if changed and not bring_to_front(found):
            now = describe(w.GetForegroundWindow() or 0)
            raise HttpError(409, f"window {found} ({w.window_text(found)!r}) could not be brought to the front: the "
                                 f"foreground is {now['title']!r} ({now['class']}, window {now['id']}, process "
                                 f"{now['pid']})")
        self._json(200, {"ok": True, "window": True, **describe(found), "changed": changed, "before": before})

    def open(self) -> None:
        """Open a file or folder with its associated program and wait like `launch`."""
        import os

        from .desktop import app_windows, new_window
        from .system import PathError, open_path, windows_path

        req = self._request("open")
        try:
            path = windows_path(req["path"])
        except PathError as exc:
            raise HttpError(400, f"invalid request: open.path: {exc}") from None
        if not os.path.exists(path):
            raise HttpError(404, f"no file or folder at {path}")
        before = app_windows() if req["window_wait"] else {}
        try:
            pid = open_path(path)
        except OSError as exc:
            raise HttpError(400, str(exc)) from None
        self._window_shown(new_window(before, req["window_wait"], pid))

    def windows(self) -> None:
        from .desktop import windows

        self._json(200, {"windows": windows()})

    def get_clipboard(self) -> None:
        from .clipboard import get_text

        self._json(200, {"text": get_text()})

    def put_clipboard(self) -> None:
        from .clipboard import set_text

        set_text(self._request("clipboard")["text"])
        self._json(200, {"ok": True})


Handler.routes = ROUTES = {
    ("GET", "/health"): Handler.health,
    ("GET", "/screen_size"): Handler.screen_size,
    ("GET", "/screenshot"): Handler.screenshot,
    ("GET", "/a11y"): Handler.a11y,
    ("POST", "/action"): Handler.action,
    ("PUT", "/files"): Handler.put_file,
    ("GET", "/files"): Handler.get_file,
    ("GET", "/exists"): Handler.exists,
    ("POST", "/run"): Handler.run,
    ("POST", "/launch"): Handler.launch,
    ("POST", "/open"): Handler.open,
    ("POST", "/focus"): Handler.focus,
    ("GET", "/windows"): Handler.windows,
    ("GET", "/clipboard"): Handler.get_clipboard,
    ("PUT", "/clipboard"): Handler.put_clipboard,
}


def serve(host: str, port: int) -> None:
    ControlServer((host, port), Handler).serve_forever()


def wait_desktop(seconds: float) -> bool:
    """Poll the desktop's readiness for up to `seconds` (the image's build-time check)."""
    from .desktop import readiness

    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        try:
            details = readiness(DEVICES.screen)
            if all(details.values()):
                return True
        except Exception:
            pass
        time.sleep(0.05)
    return False
