"""What the control servers of every platform share (standard library only: it runs on the device, the Windows
one included, where the embeddable CPython has nothing else): the HTTP plumbing — routing, bodies (requests and
actions checked by `validate.py`), queries, JSON answers, errors as 4xx/5xx JSON `{"error": ...}` so nothing
crashes a server — the execution of the unified action space against a platform's input object, and the wait
for an application's window."""

from __future__ import annotations

import json
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any, Callable
from urllib.parse import parse_qs, urlsplit

from jarvis_pytest.devices import validate

MAX_BODY = 512 * 1024 * 1024
ACTION_SECONDS = 20.0   # what one action may take on a device (the harness waits 30 s for its answer)
TYPE_CHUNK = 100        # characters typed between two looks at the clock
HEALTH_WAIT_MAX = 5.0   # seconds a `GET /health?wait=S` may hold its answer
HEALTH_RECHECK = 0.05   # seconds between the server's own readiness checks while it holds one


class HttpError(Exception):
    """An answer other than 200: its status and message."""

    def __init__(self, status: int, message: str):
        super().__init__(message)
        self.status = status


class Lazy:
    """A server's device objects (screen, input), each made on first use — the display may come up after the
    server — under one lock; `ready` latches once the desktop was seen up."""

    def __init__(self, **factories: Callable[[], Any]):
        self._factories = factories
        self._made: dict[str, Any] = {}
        self._lock = threading.Lock()
        self.ready = False

    def __getattr__(self, name: str) -> Any:
        factories = self.__dict__.get("_factories", {})
        if name not in factories:
            raise AttributeError(name)
        with self._lock:
            if name not in self._made:
                self._made[name] = factories[name]()
            return self._made[name]


class ControlHandler(BaseHTTPRequestHandler):
    """Plumbing of a control server; a subclass sets `routes` ({(method, path): handler}) and its endpoints."""

    protocol_version = "HTTP/1.1"
    disable_nagle_algorithm = True  # small answers must not wait for the client's delayed ACK (~40 ms)
    wbufsize = 1 << 16  # headers and body leave in one write; the handler flushes after each request
    routes: dict[tuple[str, str], Callable[[Any], None]] = {}

    def log_message(self, fmt: str, *args: Any) -> None:  # quiet; errors are answered, not logged
        pass

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
        """The body of request `name` (`run`, `launch`, …), checked by `validate.request`; else a 400."""
        try:
            return validate.request(name, self._body())
        except validate.Invalid as exc:
            raise HttpError(400, f"invalid request: {exc}") from None

    def _action(self) -> dict:
        """The body as one action (`validate.action`: `type` and every field); else a 400."""
        try:
            return validate.action(self._body())
        except validate.Invalid as exc:
            raise HttpError(400, f"invalid request: {exc}") from None

    def _query(self) -> dict[str, str]:
        return {k: v[-1] for k, v in parse_qs(urlsplit(self.path).query).items()}

    def _health_wait(self) -> float:
        """The `wait` query parameter of /health: seconds to hold the answer until the device is ready (0 when
        absent, at most `HEALTH_WAIT_MAX`)."""
        raw = self._query().get("wait", "0")
        try:
            wait = float(raw)
        except ValueError:
            raise HttpError(400, f"query parameter `wait` must be a number of seconds, not {raw!r}") from None
        if not 0 <= wait <= HEALTH_WAIT_MAX:
            raise HttpError(400, f"query parameter `wait` must be between 0 and {HEALTH_WAIT_MAX:g} seconds")
        return wait

    def _dispatch(self, method: str) -> None:
        route = urlsplit(self.path).path.rstrip("/") or "/"
        handler = self.routes.get((method, route))
        self._body_read = False
        try:
            if handler is None:
                known = {r for _, r in self.routes}
                raise HttpError(404 if route not in known else 405, f"no route {method} {route}")
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


def readiness_within(check: Callable[[], dict[str, bool]], seconds: float) -> dict[str, bool]:
    """`check()` (what is up, by name) again every `HEALTH_RECHECK` seconds until everything is or `seconds`
    passed; its last answer. Behind `/health?wait=S`: a booting device is asked once a second by the host, not
    fifty times (each ask crossing the harness, Docker's port proxy and the server cost CPU that the boots of a
    busy machine need), and the answer still comes within 50 ms of the device being ready."""
    deadline = time.monotonic() + seconds
    while True:
        details = check()
        if all(details.values()) or time.monotonic() + HEALTH_RECHECK > deadline:
            return details
        time.sleep(HEALTH_RECHECK)


class ControlServer(ThreadingHTTPServer):
    daemon_threads = True
    allow_reuse_address = True


def execute(a: dict, kb: Any, platform: str, pyautogui: Callable[[str], None]) -> None:
    """Carry out one action of the unified action space (a validated dict) with the platform's input object
    `kb`; `pyautogui(script)` runs a PYAUTOGUI script. Refusals are HttpError(400)."""
    t = a["type"]
    if t == "MOVE_TO":
        kb.move(a["x"], a["y"])
    elif t == "CLICK":
        kb.click(a.get("x"), a.get("y"), a.get("button", "left"), a.get("clicks", 1))
    elif t == "RIGHT_CLICK":
        kb.click(a.get("x"), a.get("y"), "right", 1)
    elif t == "DOUBLE_CLICK":
        kb.click(a.get("x"), a.get("y"), "left", 2)
    elif t in ("MOUSE_DOWN", "MOUSE_UP"):
        kb.button(a.get("button", "left"), t == "MOUSE_DOWN")
    elif t == "DRAG_TO":
        kb.drag(a.get("start_x"), a.get("start_y"), a["x"], a["y"])
    elif t == "SWIPE":
        kb.drag(a["x"], a["y"], a["x"] + a["dx"], a["y"] + a["dy"], max(a.get("duration", 300), 40))
    elif t == "LONG_PRESS":
        kb.long_press(a["x"], a["y"], a.get("duration", 800))
    elif t == "SCROLL":
        kb.scroll(a.get("dx", 0), a.get("dy", 0), a.get("x"), a.get("y"))
    elif t == "TYPING":
        type_within(kb, a["text"], ACTION_SECONDS)
    elif t in ("KEY_DOWN", "KEY_UP"):
        kb.key(a["key"], t == "KEY_DOWN")
    elif t == "HOTKEY":
        kb.hotkey(a["keys"])
    elif t == "WAIT":
        time.sleep(a.get("seconds", 1.0))
    elif t in ("DONE", "FAIL"):
        pass
    elif t == "SYSTEM_BUTTON":
        raise HttpError(400, f"SYSTEM_BUTTON (an Android system button) is not supported on {platform}")
    elif t == "PYAUTOGUI":
        from jarvis_pytest.devices.pyautogui_compat import ScriptError

        try:
            pyautogui(a["script"])
        except ScriptError as exc:  # the script's own doing is the agent's to see, not a server failure
            raise HttpError(400, f"PYAUTOGUI script failed: {exc}") from None
    else:
        raise HttpError(400, f"unknown action type {t}")


def type_within(kb: Any, text: str, seconds: float) -> None:
    """Type `text` with `kb`, a chunk at a time; past `seconds` stop and refuse the rest (an HttpError(400) that
    says how much was typed), so that no text keeps a device busy past the harness's wait for its answer."""
    deadline = time.monotonic() + seconds
    for i in range(0, len(text), TYPE_CHUNK):
        if i and time.monotonic() >= deadline:
            raise HttpError(400, f"typed the first {i} of {len(text)} characters: the rest did not fit the "
                                 f"{seconds:g} s one action may take (type it in another step)")
        kb.type(text[i:i + TYPE_CHUNK])


def wait_for_window(app_windows: Callable[[], dict[int, str]], before: dict[int, str], seconds: float) -> bool:
    """Whether, within `seconds`, a new application window shows or an existing one changes its title (a file
    opened into a tab), compared with `before` (window id → title)."""
    deadline = time.monotonic() + seconds
    while seconds and time.monotonic() < deadline:
        time.sleep(0.05)
        if any(before.get(wid) != title for wid, title in app_windows().items()):
            return True
    return False


def title_matches(pattern: str, title: str) -> bool:
    """Whether a window title shows `pattern`, case-insensitive: as a substring, or where the pattern has `*`
    (any text) as a whole-title match — "notes.txt - *wordpad" names WordPad's window under Wine ("Wine Wordpad")
    and on Windows ("WordPad") but not Notepad's window on the same file."""
    want, text = pattern.casefold(), title.casefold()
    if "*" not in want:
        return want in text
    import re

    return re.fullmatch(".*".join(map(re.escape, want.split("*"))), text, re.S) is not None
