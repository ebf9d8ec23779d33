"""HTTP routing of the Windows control server: the Ubuntu server's API and JSON shapes (`devices/protocol.py`),
validated by hand (`validate.py`). Every bad request gets a 4xx JSON `{"error": ...}`; nothing crashes it."""

from __future__ import annotations

import json
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any
from urllib.parse import parse_qs, urlsplit

from . import validate

MAX_BODY = 512 * 1024 * 1024
PLATFORM = "windows"


class HttpError(Exception):
    def __init__(self, status: int, message: str):
        super().__init__(message)
        self.status = status


class Devices:
    """Screen and input, made on first use; `ready` latches once the desktop was seen up."""

    def __init__(self):
        self._lock = threading.Lock()
        self._screen = None
        self._input = None
        self.ready = False

    @property
    def screen(self):
        with self._lock:
            if self._screen is None:
                from .screen import Screen

                self._screen = Screen()
            return self._screen

    @property
    def input(self):
        with self._lock:
            if self._input is None:
                from .input import Input

                self._input = Input()
            return self._input


DEVICES = Devices()


def execute(a: dict) -> None:
    """Carry out one validated action of the unified action space."""
    kb = DEVICES.input
    t = a["type"]
    if t == "MOVE_TO":
        kb.move(a["x"], a["y"])
    elif t == "CLICK":
        kb.click(a["x"], a["y"], a["button"], a["clicks"])
    elif t == "RIGHT_CLICK":
        kb.click(a["x"], a["y"], "right", 1)
    elif t == "DOUBLE_CLICK":
        kb.click(a["x"], a["y"], "left", 2)
    elif t in ("MOUSE_DOWN", "MOUSE_UP"):
        kb.button(a["button"], t == "MOUSE_DOWN")
    elif t == "DRAG_TO":
        kb.drag(a["start_x"], a["start_y"], a["x"], a["y"])
    elif t == "SWIPE":
        kb.drag(a["x"], a["y"], a["x"] + a["dx"], a["y"] + a["dy"], max(a["duration"], 40))
    elif t == "LONG_PRESS":
        kb.long_press(a["x"], a["y"], a["duration"])
    elif t == "SCROLL":
        kb.scroll(a["dx"], a["dy"], a["x"], a["y"])
    elif t == "TYPING":
        kb.type(a["text"])
    elif t in ("KEY_DOWN", "KEY_UP"):
        kb.key(a["key"], t == "KEY_DOWN")
    elif t == "HOTKEY":
        kb.hotkey(a["keys"])
    elif t == "WAIT":
        time.sleep(a["seconds"])
    elif t in ("DONE", "FAIL"):
        pass
    elif t == "SYSTEM_BUTTON":
        raise HttpError(400, f"SYSTEM_BUTTON (an Android system button) is not supported on {PLATFORM}")
    elif t == "PYAUTOGUI":
        from .pyautogui_compat import run_script

        try:
            run_script(a["script"], kb, DEVICES.screen.size)
        except (Exception, SystemExit) as exc:  # the script's own error is the agent's to see, not a server failure
            raise HttpError(400, f"PYAUTOGUI script failed: {exc.__class__.__name__}: {exc}") from None
    else:  # pragma: no cover - validate.ACTIONS is closed
        raise HttpError(400, f"unknown action type {t}")


def wait_for_window(before: dict[int, str], seconds: float) -> bool:
    """Whether a new application window shows, or an existing one changes its title, within `seconds`."""
    from .desktop import app_windows

    deadline = time.monotonic() + seconds
    while seconds and time.monotonic() < deadline:
        time.sleep(0.05)
        now = app_windows()
        if any(before.get(hwnd) != title for hwnd, title in now.items()):
            return True
    return False


class Handler(BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"
    server_version = "jarvis-control-windows/1"
    disable_nagle_algorithm = True  # small answers must not wait for the client's delayed ACK
    wbufsize = 1 << 16

    def log_message(self, fmt: str, *args: Any) -> None:  # quiet; errors are answered, not logged
        pass

    # -- plumbing ---------------------------------------------------------------------------------------------
    def _send(self, status: int, body: bytes, ctype: str) -> None:
        self.send_response(status)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        if not self._body_read and self.headers.get("Content-Length", "0") != "0":
            self.send_header("Connection", "close")  # the unread body would be taken for the next request
        self.end_headers()
        self.wfile.write(body)

    def _json(self, status: int, data: Any) -> None:
        self._send(status, json.dumps(data).encode(), "application/json")

    def _body(self) -> bytes:
        try:
            n = int(self.headers.get("Content-Length") or 0)
        except ValueError:
            raise HttpError(400, "Content-Length is not a number") from None
        if not 0 <= n <= MAX_BODY:
            raise HttpError(413, f"body of {n} bytes is not within the {MAX_BODY} byte limit")
        self._body_read = True
        return self.rfile.read(n) if n else b""

    def _request(self, name: str) -> dict:
        try:
            return validate.request(name, self._body())
        except validate.Invalid as exc:
            raise HttpError(400, f"invalid request: {exc}") from None

    def _query(self) -> dict[str, str]:
        return {k: v[-1] for k, v in parse_qs(urlsplit(self.path).query).items()}

    def _path_arg(self) -> str:
        from .system import PathError, windows_path

        try:
            return windows_path(self._query().get("path", ""))
        except PathError as exc:
            raise HttpError(400, f"query parameter `path`: {exc}") from None

    def _dispatch(self, method: str) -> None:
        route = urlsplit(self.path).path.rstrip("/") or "/"
        handler = ROUTES.get((method, route))
        self._body_read = False
        try:
            if handler is None:
                raise HttpError(404 if route not in {r for _, r in ROUTES} else 405, f"no route {method} {route}")
            handler(self)
        except HttpError as exc:
            self._json(exc.status, {"error": str(exc)})
        except Exception as exc:  # a failure inside the device is reported, the server stays up
            self._json(500, {"error": f"{exc.__class__.__name__}: {exc}"})

    def do_GET(self) -> None:
        self._dispatch("GET")

    def do_POST(self) -> None:
        self._dispatch("POST")

    def do_PUT(self) -> None:
        self._dispatch("PUT")

    # -- endpoints --------------------------------------------------------------------------------------------
    def health(self) -> None:
        """Ready = the shell's taskbar exists, shows and is drawn (then it stays so: an agent's full-screen window
        must not make the device "unready")."""
        if DEVICES.ready:
            self._json(200, {"ok": True, "desktop": True, "details": {"ready": True}})
            return
        from .desktop import readiness

        try:
            details = readiness(DEVICES.screen)
        except Exception:  # the display is not up yet
            details = {"taskbar": False, "painted": False}
        DEVICES.ready = all(details.values())
        self._json(200, {"ok": True, "desktop": DEVICES.ready, "details": details})

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

        try:
            action = validate.action(self._body())
        except validate.Invalid as exc:
            raise HttpError(400, f"invalid request: {exc}") from None
        t0 = time.perf_counter()
        try:
            execute(action)
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
        changed its title, so the next screenshot shows the program."""
        from .desktop import app_windows
        from .system import launch

        req = self._request("launch")
        before = app_windows() if req["window_wait"] else {}
        try:
            launch(req["app"], req["args"])
        except FileNotFoundError:
            raise HttpError(404, f"no application {req['app']!r} on this device (give a program on its PATH, e.g. "
                                 "notepad, wordpad, regedit, explorer, cmd, taskmgr, or a full path)") from None
        except OSError as exc:
            raise HttpError(400, f"cannot start {req['app']!r}: {exc}") from None
        self._json(200, {"ok": True, "window": wait_for_window(before, req["window_wait"])})

    def open(self) -> None:
        """Open a file or folder with its associated program and wait like `launch`."""
        import os

        from .desktop import app_windows
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
            open_path(path)
        except OSError as exc:
            raise HttpError(400, str(exc)) from None
        self._json(200, {"ok": True, "window": wait_for_window(before, req["window_wait"])})

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


ROUTES = {
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
    ("GET", "/windows"): Handler.windows,
    ("GET", "/clipboard"): Handler.get_clipboard,
    ("PUT", "/clipboard"): Handler.put_clipboard,
}


class Server(ThreadingHTTPServer):
    daemon_threads = True
    allow_reuse_address = False  # on Windows SO_REUSEADDR would let a second server take the same port


def serve(host: str, port: int) -> None:
    Server((host, port), Handler).serve_forever()


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
