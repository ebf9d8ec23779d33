"""HTTP routing of the Ubuntu control server: the JSON shapes of `devices/protocol.py`, validated by hand
(`devices/validate.py`, as the Windows server does: importing pydantic was half of this server's CPU at every
boot); the plumbing shared with every platform's server is in `devices/control_http.py`. Every bad request gets
a 4xx JSON `{"error": ...}`; nothing crashes it."""

from __future__ import annotations

import time

from jarvis_pytest.devices.control_http import (ControlHandler, ControlServer, HttpError, Lazy, execute,
                                                readiness_within, wait_for_window)
from jarvis_pytest.devices.ubuntu.server import system

PLATFORM = "ubuntu"  # the platform this server runs on (`--platform`), named in refusals


def _screen():
    from jarvis_pytest.devices.ubuntu.server.screen import Screen

    return Screen()


def _keyboard():
    from jarvis_pytest.devices.ubuntu.server.xinput import Keyboard

    return Keyboard()


DEVICES = Lazy(screen=_screen, keyboard=_keyboard)  # the X connections, opened on first use


def _pyautogui(script: str) -> None:
    """A PYAUTOGUI script, in a child process of its own (`run_script_here` there)."""
    import os
    import sys

    from jarvis_pytest.devices.pyautogui_compat import run_isolated
    from jarvis_pytest.devices.ubuntu.server.xinput import SPARE_ENV

    kb = DEVICES.keyboard  # the child binds symbols to the same spare keycodes as this server: it takes them over
    env = {**os.environ, SPARE_ENV: ",".join(map(str, kb.spare))}
    try:
        run_isolated([sys.executable, "-m", "jarvis_pytest.devices.ubuntu.server", "--run-script"], script, env=env)
    finally:
        kb.refresh_spare()


def run_script_here(script: str) -> None:
    """A PYAUTOGUI script on this process's own X connection (the child of `_pyautogui`)."""
    from jarvis_pytest.devices.pyautogui_compat import run_script

    kb = DEVICES.keyboard

    def position() -> tuple[int, int]:
        p = kb.root.query_pointer()
        return p.root_x, p.root_y

    run_script(script, kb, position, lambda: (kb.width, kb.height))


def _desktop_readiness() -> dict[str, bool]:
    """What of the desktop is up (all True once it was seen ready: `DEVICES.ready` latches)."""
    if DEVICES.ready:
        return {"ready": True}
    details = system.running(system.DESKTOP_PROCESSES)
    try:
        shown = DEVICES.screen.managed_classes() if all(details.values()) else set()
        details.update({f"{cls} shown": cls in shown for cls in system.DESKTOP_WINDOWS})
        details["painted"] = all(details.values()) and DEVICES.screen.painted()
    except Exception:  # the display is not up yet
        details["painted"] = False
    DEVICES.ready = all(details.values())
    return details


class Handler(ControlHandler):
    server_version = "jarvis-control/1"

    def _path_arg(self) -> str:
        path = self._query().get("path", "")
        if not path.startswith("/"):
            raise HttpError(400, "query parameter `path` must be an absolute path")
        return path

    # -- endpoints --------------------------------------------------------------------------------------------
    def health(self) -> None:
        """Ready = the display answers, the desktop's processes run, the window manager shows the desktop and the
        panels, and the desktop is drawn. Then it stays so: an agent's own full-screen window must not make a
        device "unready". `?wait=S` holds the answer up to S seconds until the device is ready."""
        details = readiness_within(_desktop_readiness, self._health_wait())
        ready = all(details.values())
        self._json(200, {"ok": True, "desktop": ready, "details": {"ready": True} if ready else details})

    def screen_size(self) -> None:
        w, h = DEVICES.screen.size()
        self._json(200, {"width": w, "height": h})

    def screenshot(self) -> None:
        self._send(200, DEVICES.screen.png(), "image/png")

    def a11y(self) -> None:
        from jarvis_pytest.devices.ubuntu.server.a11y import tree

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
        from jarvis_pytest.devices.ubuntu.server.xinput import InputError

        action = self._action()
        t0 = time.perf_counter()
        try:
            execute(action, DEVICES.keyboard, PLATFORM, _pyautogui)
        except (InputError, KeyError) as exc:
            raise HttpError(400, str(exc)) from None
        self._json(200, {"ok": True, "error": None, "elapsed_ms": (time.perf_counter() - t0) * 1000})

    def put_file(self) -> None:
        path = self._path_arg()
        try:
            system.write_file(path, self._body())
        except (PermissionError, IsADirectoryError, NotADirectoryError) as exc:
            raise HttpError(403, f"cannot write {path}: {exc}") from None
        self._json(200, {"ok": True, "path": path})

    def get_file(self) -> None:
        path = self._path_arg()
        try:
            data = system.read_file(path)
        except FileNotFoundError:
            raise HttpError(404, f"no file at {path}") from None
        except (PermissionError, IsADirectoryError) as exc:
            raise HttpError(403, f"cannot read {path}: {exc}") from None
        self._send(200, data, "application/octet-stream")

    def run(self) -> None:
        req = self._request("run")
        self._json(200, system.run(req["command"], req["user"], req["timeout"]))

    def _start_and_wait(self, app: str, args: list[str], window_wait: float) -> None:
        """Start a program; with `window_wait`, answer once the desktop shows a new application window or an
        existing one changed its title (a file opened into a tab), so the next screenshot shows the app."""
        before = DEVICES.screen.app_windows() if window_wait else {}
        try:
            system.launch(app, args)
        except FileNotFoundError:
            raise HttpError(404, f"no application {app!r} on this device (give a command on its PATH, "
                                 "e.g. mousepad, libreoffice, chromium, gimp, thunar)") from None
        except PermissionError:
            raise HttpError(400, f"{app!r} is not an executable") from None
        shown = wait_for_window(DEVICES.screen.app_windows, before, window_wait)
        self._json(200, {"ok": True, "window": shown})

    def launch(self) -> None:
        req = self._request("launch")
        self._start_and_wait(req["app"], req["args"], req["window_wait"])

    def open(self) -> None:
        """Open a file or folder with its default application (xdg-open), waiting for its window like launch."""
        req = self._request("open")
        path = req["path"]
        if not path.startswith("/"):
            raise HttpError(400, "`path` must be an absolute path")
        if system.path_kind(path) is None:
            raise HttpError(404, f"no file or folder at {path}")
        self._start_and_wait("xdg-open", [path], req["window_wait"])

    def focus(self) -> None:
        """Bring the application window whose title contains `title` to the front (waiting up to `timeout` s for it
        to show); 404 when none does."""
        req = self._request("focus")
        if req["id"] is not None:
            raise HttpError(400, "invalid request: focus.id names a window on Windows devices only; give `title`")
        if req["title"] is None:
            raise HttpError(400, "invalid request: focus.title: field required")
        deadline = time.monotonic() + req["timeout"]
        while True:
            found = DEVICES.screen.focus(req["title"])
            if found or time.monotonic() >= deadline:
                break
            time.sleep(0.1)
        if not found:
            raise HttpError(404, f"no window whose title contains {req['title']!r}")
        self._json(200, {"ok": True, "window": True})

    def exists(self) -> None:
        kind = system.path_kind(self._path_arg())
        self._json(200, {"exists": kind is not None, "kind": kind})

    def windows(self) -> None:
        self._json(200, {"windows": DEVICES.screen.windows()})

    def get_clipboard(self) -> None:
        self._json(200, {"text": system.clipboard_get()})

    def put_clipboard(self) -> None:
        system.clipboard_set(self._request("clipboard")["text"])
        self._json(200, {"ok": True})


Handler.routes = ROUTES = {
    ("GET", "/health"): Handler.health,
    ("GET", "/screen_size"): Handler.screen_size,
    ("GET", "/screenshot"): Handler.screenshot,
    ("GET", "/a11y"): Handler.a11y,
    ("POST", "/action"): Handler.action,
    ("PUT", "/files"): Handler.put_file,
    ("GET", "/files"): Handler.get_file,
    ("POST", "/run"): Handler.run,
    ("POST", "/launch"): Handler.launch,
    ("POST", "/open"): Handler.open,
    ("POST", "/focus"): Handler.focus,
    ("GET", "/exists"): Handler.exists,
    ("GET", "/windows"): Handler.windows,
    ("GET", "/clipboard"): Handler.get_clipboard,
    ("PUT", "/clipboard"): Handler.put_clipboard,
}


def serve(host: str, port: int, platform: str = "ubuntu") -> None:
    global PLATFORM
    PLATFORM = platform
    ControlServer((host, port), Handler).serve_forever()
