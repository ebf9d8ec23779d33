"""HTTP routing of the control server. Every bad request gets a 4xx JSON `{"error": ...}`; nothing crashes it."""

from __future__ import annotations

import json
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any
from urllib.parse import parse_qs, urlsplit

from pydantic import BaseModel, ValidationError

from jarvis_pytest.devices import actions as A
from jarvis_pytest.devices.protocol import (A11yTree, ActionResult, ClipboardText, Health, LaunchRequest,
                                            LaunchResponse, OpenRequest, PathInfo, RunRequest, ScreenSize, WindowList)
from jarvis_pytest.devices.ubuntu.server import system

MAX_BODY = 512 * 1024 * 1024
PLATFORM = "ubuntu"  # the platform this server runs on (`--platform`), named in refusals


class HttpError(Exception):
    def __init__(self, status: int, message: str):
        super().__init__(message)
        self.status = status


class Devices:
    """The X connections, opened on first use (the display may come up after the server)."""

    def __init__(self):
        self._lock = threading.Lock()
        self._screen = None
        self._keyboard = None
        self.ready = False

    @property
    def screen(self):
        with self._lock:
            if self._screen is None:
                from jarvis_pytest.devices.ubuntu.server.screen import Screen

                self._screen = Screen()
            return self._screen

    @property
    def keyboard(self):
        with self._lock:
            if self._keyboard is None:
                from jarvis_pytest.devices.ubuntu.server.xinput import Keyboard

                self._keyboard = Keyboard()
            return self._keyboard


DEVICES = Devices()


def execute(action: A.Action) -> None:
    """Carry out one action of the unified action space on this desktop."""
    kb = DEVICES.keyboard
    t = action.type
    if t == "MOVE_TO":
        kb.move(action.x, action.y)
    elif t == "CLICK":
        kb.click(action.x, action.y, action.button, action.clicks)
    elif t == "RIGHT_CLICK":
        kb.click(action.x, action.y, "right", 1)
    elif t == "DOUBLE_CLICK":
        kb.click(action.x, action.y, "left", 2)
    elif t in ("MOUSE_DOWN", "MOUSE_UP"):
        kb.button(action.button, t == "MOUSE_DOWN")
    elif t == "DRAG_TO":
        kb.drag(action.start_x, action.start_y, action.x, action.y)
    elif t == "SWIPE":
        kb.drag(action.x, action.y, action.x + action.dx, action.y + action.dy, max(action.duration, 40))
    elif t == "LONG_PRESS":
        kb.long_press(action.x, action.y, action.duration)
    elif t == "SCROLL":
        kb.scroll(action.dx, action.dy, action.x, action.y)
    elif t == "TYPING":
        kb.type(action.text)
    elif t in ("KEY_DOWN", "KEY_UP"):
        kb.key(action.key, t == "KEY_DOWN")
    elif t == "HOTKEY":
        kb.hotkey(action.keys)
    elif t == "WAIT":
        time.sleep(action.seconds)
    elif t in ("DONE", "FAIL"):
        pass
    elif t == "SYSTEM_BUTTON":
        raise HttpError(400, f"SYSTEM_BUTTON (an Android system button) is not supported on {PLATFORM}")
    elif t == "PYAUTOGUI":
        from jarvis_pytest.devices.ubuntu.server.pyautogui_compat import run_script

        try:
            run_script(action.script, kb)
        except (Exception, SystemExit) as exc:  # the script's own error is the agent's to see, not a server failure
            raise HttpError(400, f"PYAUTOGUI script failed: {exc.__class__.__name__}: {exc}") from None
    else:  # pragma: no cover - the union is closed
        raise HttpError(400, f"unknown action type {t}")


def _validation_message(exc: ValidationError) -> str:
    parts = []
    for err in exc.errors()[:3]:
        loc = ".".join(str(x) for x in err["loc"])
        parts.append(f"{loc}: {err['msg']}" if loc else err["msg"])
    return "invalid request: " + "; ".join(parts)


class Handler(BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"
    server_version = "jarvis-control/1"
    disable_nagle_algorithm = True  # small answers must not wait for the client's delayed ACK (~40 ms)
    wbufsize = 1 << 16  # headers and body leave in one write; the handler flushes after each request

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
        if isinstance(data, BaseModel):
            data = data.model_dump(mode="json", by_alias=True)
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

    def _model(self, cls: type[BaseModel]):
        try:
            return cls.model_validate_json(self._body() or b"{}")
        except ValidationError as exc:
            raise HttpError(400, _validation_message(exc)) from None

    def _query(self) -> dict[str, str]:
        return {k: v[-1] for k, v in parse_qs(urlsplit(self.path).query).items()}

    def _path_arg(self) -> str:
        path = self._query().get("path", "")
        if not path.startswith("/"):
            raise HttpError(400, "query parameter `path` must be an absolute path")
        return path

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
        """Ready = the display answers, the desktop's processes run, the window manager shows the desktop and the
        panels, and the desktop is drawn. Then it stays so: an agent's own full-screen window must not make a
        device "unready"."""
        if DEVICES.ready:
            self._json(200, Health(ok=True, desktop=True, details={"ready": True}))
            return
        details = system.running(system.DESKTOP_PROCESSES)
        try:
            shown = DEVICES.screen.managed_classes() if all(details.values()) else set()
            details.update({f"{cls} shown": cls in shown for cls in system.DESKTOP_WINDOWS})
            details["painted"] = all(details.values()) and DEVICES.screen.painted()
        except Exception:  # the display is not up yet
            details["painted"] = False
        DEVICES.ready = all(details.values())
        self._json(200, Health(ok=True, desktop=DEVICES.ready, details=details))

    def screen_size(self) -> None:
        w, h = DEVICES.screen.size()
        self._json(200, ScreenSize(width=w, height=h))

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
        self._json(200, A11yTree(**tree(**limits)))

    def action(self) -> None:
        from jarvis_pytest.devices.ubuntu.server.xinput import InputError

        body = self._body()
        try:
            action = A.parse_action(body)
        except ValidationError as exc:
            raise HttpError(400, _validation_message(exc)) from None
        t0 = time.perf_counter()
        try:
            execute(action)
        except (InputError, KeyError) as exc:
            raise HttpError(400, str(exc)) from None
        self._json(200, ActionResult(ok=True, elapsed_ms=(time.perf_counter() - t0) * 1000))

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
        req = self._model(RunRequest)
        self._json(200, system.run(req.command, req.user, req.timeout))

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
        deadline, shown = time.monotonic() + window_wait, False
        while window_wait and not shown and time.monotonic() < deadline:
            time.sleep(0.05)
            now = DEVICES.screen.app_windows()
            shown = any(before.get(wid) != title for wid, title in now.items())
        self._json(200, LaunchResponse(window=shown))

    def launch(self) -> None:
        req = self._model(LaunchRequest)
        self._start_and_wait(req.app, req.args, req.window_wait)

    def open(self) -> None:
        """Open a file or folder with its default application (xdg-open), waiting for its window like launch."""
        req = self._model(OpenRequest)
        if not req.path.startswith("/"):
            raise HttpError(400, "`path` must be an absolute path")
        if system.path_kind(req.path) is None:
            raise HttpError(404, f"no file or folder at {req.path}")
        self._start_and_wait("xdg-open", [req.path], req.window_wait)

    def exists(self) -> None:
        kind = system.path_kind(self._path_arg())
        self._json(200, PathInfo(exists=kind is not None, kind=kind))

    def windows(self) -> None:
        self._json(200, WindowList(windows=DEVICES.screen.windows()))

    def get_clipboard(self) -> None:
        self._json(200, ClipboardText(text=system.clipboard_get()))

    def put_clipboard(self) -> None:
        system.clipboard_set(self._model(ClipboardText).text)
        self._json(200, {"ok": True})


ROUTES = {
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
    ("GET", "/exists"): Handler.exists,
    ("GET", "/windows"): Handler.windows,
    ("GET", "/clipboard"): Handler.get_clipboard,
    ("PUT", "/clipboard"): Handler.put_clipboard,
}


class Server(ThreadingHTTPServer):
    daemon_threads = True
    allow_reuse_address = True


def serve(host: str, port: int, platform: str = "ubuntu") -> None:
    global PLATFORM
    PLATFORM = platform
    Server((host, port), Handler).serve_forever()
