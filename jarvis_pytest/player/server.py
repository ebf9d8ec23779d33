"""The player's HTTP server (stdlib `ThreadingHTTPServer`), bound to 127.0.0.1 only.

    GET  /  /player.js  /player.css       the page (static; the address's fragment carries the token)
    GET  /api/state                       the task, the step, the inputs waiting, the latest steps
    GET  /api/frame/<platform>            the device's screen now (PNG)
    POST /api/input                       one input event of the page (`inputs.translate`)

Every /api request must carry the session's token in the `X-Player-Token` header: another web page open in the
same browser cannot read or drive the player (a cross-origin request with that header needs a CORS preflight,
which this server never grants), and a request whose `Host` is not this server's loopback address is refused (a
DNS-rebinding page).
"""

from __future__ import annotations

import hmac
import json
import secrets
import threading
from http import HTTPStatus
from http.server import ThreadingHTTPServer
from pathlib import Path
from typing import Any
from urllib.parse import unquote, urlsplit

from jarvis_pytest.http_server import JsonHandler
from jarvis_pytest.player.agent import NotTaking, Player
from jarvis_pytest.player.inputs import InputRefused

HOST = "127.0.0.1"
STATIC_DIR = Path(__file__).parent / "static"
STATIC_FILES = {"player.html": "text/html; charset=utf-8", "player.js": "text/javascript; charset=utf-8",
                "player.css": "text/css; charset=utf-8"}
MAX_BODY = 256 * 1024  # bytes of one input event (a pasted text of MAX_TEXT characters fits)
TOKEN_HEADER = "X-Player-Token"


class PlayerServer(ThreadingHTTPServer):
    daemon_threads = True
    allow_reuse_address = True

    def __init__(self, player: Player, port: int = 0):
        self.player = player
        self.token = secrets.token_urlsafe(18)
        super().__init__((HOST, port), PlayerHandler)
        self.thread: threading.Thread | None = None

    @property
    def port(self) -> int:
        return self.server_address[1]

    @property
    def url(self) -> str:
        return f"http://{HOST}:{self.port}/#token={self.token}"

    def stop(self) -> None:
        self.shutdown()
        self.server_close()
        if self.thread is not None:
            self.thread.join(timeout=5)


class PlayerHandler(JsonHandler):
    server: PlayerServer
    server_version = "jarvis-player"
    name = "player"
    always = {"X-Frame-Options": "DENY", "Cache-Control": "no-store"}

    def log_message(self, format: str, *args: Any) -> None:  # quiet: the terminal belongs to pytest
        pass

    def _host_ok(self) -> bool:
        host = (self.headers.get("Host") or "").strip().lower()
        return host in (f"{HOST}:{self.server.port}", f"localhost:{self.server.port}")

    def _token_ok(self) -> bool:
        given = self.headers.get(TOKEN_HEADER) or ""
        return hmac.compare_digest(given.encode(), self.server.token.encode())

    def _guarded(self, handle) -> None:
        try:
            if not self._host_ok():
                return self._error(HTTPStatus.FORBIDDEN, "the player answers only on its loopback address")
            handle()
        except (BrokenPipeError, ConnectionResetError):
            pass
        except Exception as exc:  # a bug must not take the player down; say what happened
            self._failed(exc)

    def do_GET(self) -> None:
        self._guarded(self._get)

    def do_POST(self) -> None:
        self._guarded(self._post)

    def _get(self) -> None:
        path = urlsplit(self.path).path
        name = path.lstrip("/") or "player.html"
        if name in STATIC_FILES:
            return self._send(200, (STATIC_DIR / name).read_bytes(), STATIC_FILES[name])
        if not path.startswith("/api/"):
            return self._error(HTTPStatus.NOT_FOUND, "not found")
        if not self._token_ok():
            return self._error(HTTPStatus.FORBIDDEN, f"missing or wrong {TOKEN_HEADER}")
        player = self.server.player
        if path == "/api/state":
            return self._json(player.state())
        if path.startswith("/api/frame/"):
            platform = unquote(path.removeprefix("/api/frame/"))
            try:
                png, live = player.frame(platform)
            except LookupError as exc:
                return self._error(HTTPStatus.NOT_FOUND, str(exc))
            return self._send(200, png, "image/png", {"X-Live": "1" if live else "0"})
        return self._error(HTTPStatus.NOT_FOUND, "no such endpoint")

    def _post(self) -> None:
        if urlsplit(self.path).path != "/api/input":
            return self._error(HTTPStatus.NOT_FOUND, "no such endpoint")
        if not self._token_ok():
            return self._error(HTTPStatus.FORBIDDEN, f"missing or wrong {TOKEN_HEADER}")
        try:
            length = int(self.headers.get("Content-Length") or "0")
        except ValueError:
            length = -1
        if not 0 < length <= MAX_BODY:
            return self._error(HTTPStatus.BAD_REQUEST, f"an input event is a JSON body of at most {MAX_BODY} bytes")
        try:
            event = json.loads(self.rfile.read(length))
        except (ValueError, UnicodeDecodeError):
            return self._error(HTTPStatus.BAD_REQUEST, "the body is not JSON")
        if not isinstance(event, dict):
            return self._error(HTTPStatus.BAD_REQUEST, "an input event is a JSON object")
        try:
            return self._json(self.server.player.receive(event))
        except NotTaking as exc:
            return self._error(HTTPStatus.CONFLICT, str(exc))
        except InputRefused as exc:
            return self._error(HTTPStatus.BAD_REQUEST, str(exc))


def start_player_server(player: Player, port: int = 0) -> PlayerServer:
    """A player server for `player` on 127.0.0.1:`port` (0: a free one), answering from a daemon thread."""
    server = PlayerServer(player, port)
    server.thread = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.2}, daemon=True,
                                     name="jarvis-player")
    server.thread.start()
    return server
