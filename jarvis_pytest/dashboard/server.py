"""The dashboard's HTTP server (stdlib `ThreadingHTTPServer`): the viewer's static files, a JSON API over the
results directory, and the result files themselves under `/files/`.

    GET /viewer.html, /viewer.js, /viewer.css      the single-page viewer (`/` redirects to it)
    GET /api/runs                                  every run: agent, dates, progress, TSR/SSR, problems
    GET /api/runs/<run>                            one run: tasks done/running/pending, latest steps, summary
    GET /api/runs/<run>/tasks/<task>               one task: result, verdicts, every step of the trajectory
    GET /api/compare?a=<run>&b=<run>               two runs task by task
    GET /files/<run>/<path>                        a file of the results directory (screenshots, summary.md)

Request paths are decoded segment by segment and resolved under the results root; a segment that is `..`, `.`,
empty, or hides a separator, and a path whose resolution (symlinks included) leaves the root, get 403.
"""

from __future__ import annotations

import contextlib
import json
import mimetypes
import sys
import threading
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any, Iterator
from urllib.parse import parse_qs, urlsplit

from jarvis_pytest.dashboard.paths import PathRefused, resolve_under, split_segments
from jarvis_pytest.dashboard.store import NotFound, ResultsStore

STATIC_DIR = Path(__file__).parent / "static"
STATIC_FILES = {"viewer.html": "text/html", "viewer.js": "text/javascript", "viewer.css": "text/css"}


class DashboardServer(ThreadingHTTPServer):
    daemon_threads = True
    request_queue_size = 64  # several open tabs polling

    def __init__(self, address: tuple[str, int], store: ResultsStore, verbose: bool = False):
        self.store = store
        self.verbose = verbose
        super().__init__(address, DashboardHandler)

    @property
    def url(self) -> str:
        host, port = self.server_address[:2]
        return f"http://{'localhost' if host in ('127.0.0.1', '::1') else host}:{port}/viewer.html"


class DashboardHandler(BaseHTTPRequestHandler):
    server: DashboardServer
    server_version = "jarvis-dashboard"
    protocol_version = "HTTP/1.1"

    # -- plumbing -------------------------------------------------------------------------------------------
    def log_message(self, format: str, *args: Any) -> None:
        if self.server.verbose:
            super().log_message(format, *args)

    def _send(self, status: int, body: bytes, content_type: str, headers: dict[str, str] | None = None) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("X-Content-Type-Options", "nosniff")
        for k, v in (headers or {}).items():
            self.send_header(k, v)
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _json(self, data: Any, status: int = 200) -> None:
        body = json.dumps(data, ensure_ascii=False, default=str).encode()
        self._send(status, body, "application/json; charset=utf-8", {"Cache-Control": "no-store"})

    def _error(self, status: HTTPStatus, message: str) -> None:
        self._json({"error": message, "status": int(status)}, int(status))

    def _file(self, path: Path, content_type: str | None = None) -> None:
        try:
            st = path.stat()
            etag = f'"{st.st_mtime_ns:x}-{st.st_size:x}"'
            if self.headers.get("If-None-Match") == etag:
                self.send_response(304)
                self.send_header("ETag", etag)
                self.send_header("Content-Length", "0")
                self.end_headers()
                return
            body = path.read_bytes()
        except OSError:
            return self._error(HTTPStatus.NOT_FOUND, "not found")
        ctype = content_type or mimetypes.guess_type(path.name)[0] or "application/octet-stream"
        if ctype.startswith("text/") and "charset" not in ctype:
            ctype += "; charset=utf-8"
        self._send(200, body, ctype, {"ETag": etag, "Cache-Control": "no-cache"})

    # -- routing --------------------------------------------------------------------------------------------
    def do_HEAD(self) -> None:
        self.do_GET()

    def do_GET(self) -> None:
        try:
            self._route()
        except PathRefused as exc:
            self._error(HTTPStatus.FORBIDDEN, str(exc))
        except NotFound as exc:
            self._error(HTTPStatus.NOT_FOUND, str(exc))
        except (BrokenPipeError, ConnectionResetError):
            pass
        except Exception as exc:  # a bug must not take the server down; say what happened
            print(f"dashboard: {self.path}: {exc.__class__.__name__}: {exc}", file=sys.stderr)
            try:
                self._error(HTTPStatus.INTERNAL_SERVER_ERROR, f"{exc.__class__.__name__}: {exc}")
            except OSError:
                pass

    def _route(self) -> None:
        url = urlsplit(self.path)
        segments = split_segments(url.path)
        store = self.server.store
        if not segments:
            self.send_response(302)
            self.send_header("Location", "/viewer.html")
            self.send_header("Content-Length", "0")
            self.end_headers()
            return
        head, rest = segments[0], segments[1:]
        if head in STATIC_FILES and not rest:
            return self._file(STATIC_DIR / head, STATIC_FILES[head])
        if head == "files" and rest:
            path = resolve_under(store.root, rest)
            if not path.is_file():
                raise NotFound("not found")
            return self._file(path)
        if head == "api":
            return self._json(self._api(rest, parse_qs(url.query)))
        raise NotFound("not found")

    def _api(self, rest: list[str], query: dict[str, list[str]]) -> Any:
        store = self.server.store
        match rest:
            case ["runs"]:
                return store.runs()
            case ["runs", run]:
                return store.run(run)
            case ["runs", run, "tasks", task]:
                return store.task(run, task)
            case ["compare"]:
                a, b = query.get("a", [""])[0], query.get("b", [""])[0]
                if not a or not b:
                    raise NotFound("compare needs ?a=<run>&b=<run>")
                return store.compare(a, b)
        raise NotFound("no such endpoint")


def make_server(results: Path, host: str = "127.0.0.1", port: int = 8000, verbose: bool = False) -> DashboardServer:
    """A server over `results`, bound but not yet serving (call `serve_forever`); port 0 picks a free port."""
    return DashboardServer((host, port), ResultsStore(results), verbose=verbose)


@contextlib.contextmanager
def serving(results: Path, host: str = "127.0.0.1", port: int = 0) -> Iterator[DashboardServer]:
    """A server over `results` answering from a background thread for the duration of the block (tests, embedding)."""
    server = make_server(results, host, port)
    thread = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.1}, daemon=True,
                              name="jarvis-dashboard")
    thread.start()
    try:
        yield server
    finally:
        server.shutdown()
        server.server_close()
        thread.join(timeout=5)
