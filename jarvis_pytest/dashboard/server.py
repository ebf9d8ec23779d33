"""The dashboard's HTTP server (stdlib `ThreadingHTTPServer`): the viewer's static files, a JSON API over the
results directory, and the result files themselves under `/files/`.

    GET /viewer.html, /viewer.js, /viewer.css      the single-page viewer (`/` redirects to it)
    GET /api/runs                                  every run: agent, dates, progress, TSR/SSR, problems
    GET /api/runs/<run>                            one run: tasks done/running/pending, latest steps, summary
    GET /api/runs/<run>/tasks/<task>               one task: result, verdicts, every step of the trajectory
    GET /api/compare?a=<run>&b=<run>               two runs task by task
    GET /files/<run>/<path>                        a file of the results directory (screenshots, summary.md)
    POST /api/play  {"task": "<task id>"}          play the task yourself: starts `jarvis play` into a new run
                                                   of the results directory, answers the player's address

Request paths are decoded segment by segment and resolved under the results root; a segment that is `..`, `.`,
empty, or hides a separator, and a path whose resolution (symlinks included) leaves the root, get 403.

`/api/play` is the one request that does something: it is answered only on a loopback address (the dashboard
bound to 127.0.0.1, asked for by that address: not a page of another site, which cannot send its
`X-Jarvis-Play` header without a CORS preflight this server never grants, nor a DNS-rebinding one).
"""

from __future__ import annotations

import contextlib
import json
import mimetypes
import subprocess
import threading
from http import HTTPStatus
from http.server import ThreadingHTTPServer
from pathlib import Path
from typing import Any, Iterator
from urllib.parse import parse_qs, urlsplit

from jarvis_pytest.dashboard.paths import PathRefused, resolve_under, split_segments
from jarvis_pytest.dashboard.store import NotFound, ResultsStore
from jarvis_pytest.http_server import JsonHandler

STATIC_DIR = Path(__file__).parent / "static"
STATIC_FILES = {"viewer.html": "text/html", "viewer.js": "text/javascript", "viewer.css": "text/css"}


PLAY_HEADER = "X-Jarvis-Play"
LOOPBACK = ("127.0.0.1", "::1")


class DashboardServer(ThreadingHTTPServer):
    daemon_threads = True
    request_queue_size = 64  # several open tabs polling

    def __init__(self, address: tuple[str, int], store: ResultsStore, verbose: bool = False):
        self.store = store
        self.verbose = verbose
        self.plays: list[Any] = []  # the play runs this dashboard started (`jarvis_pytest.player.launch.Play`)
        super().__init__(address, DashboardHandler)

    def start_play(self, task_id: str) -> dict[str, Any]:
        """Start `jarvis play` of `task_id` into a new run of the results directory; its player's address."""
        from jarvis_pytest.player.launch import start_play
        from jarvis_pytest.results.run_state import new_run_id

        run = f"{new_run_id()}-play"
        play = start_play(task_id, self.store.root / run, log=self.store.root / ".play" / f"{run}.log")
        self.plays.append(play)
        threading.Thread(target=play.proc.wait, daemon=True, name=f"play-{run}").start()  # reaped when it ends
        return {"url": play.wait_url(), "run": run, "task": task_id}

    def stop_plays(self) -> None:
        """End the play runs this dashboard started that still run (each waits for a person until its time limit):
        SIGTERM, on which a run removes its devices and keeps what it wrote."""
        for play in self.plays:
            if play.proc.poll() is None:
                play.proc.terminate()
        for play in self.plays:
            try:
                play.proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                play.proc.kill()

    @property
    def url(self) -> str:
        host, port = self.server_address[:2]
        return f"http://{'localhost' if host in ('127.0.0.1', '::1') else host}:{port}/viewer.html"


class DashboardHandler(JsonHandler):
    server: DashboardServer
    server_version = "jarvis-dashboard"
    name = "dashboard"

    # -- plumbing -------------------------------------------------------------------------------------------
    def log_message(self, format: str, *args: Any) -> None:
        if self.server.verbose:
            super().log_message(format, *args)

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

    def do_POST(self) -> None:
        from jarvis_pytest.errors import JarvisError
        from jarvis_pytest.player.launch import PlayError

        try:
            if urlsplit(self.path).path != "/api/play":
                return self._error(HTTPStatus.NOT_FOUND, "no such endpoint")
            host, port = self.server.server_address[:2]
            asked = (self.headers.get("Host") or "").strip().lower()
            if host not in LOOPBACK or asked not in (f"127.0.0.1:{port}", f"localhost:{port}", f"[::1]:{port}") \
                    or self.headers.get(PLAY_HEADER) != "1":
                return self._error(HTTPStatus.FORBIDDEN, "playing a task is offered only to the dashboard's own page "
                                   "on a loopback address (jarvis dashboard --host 127.0.0.1)")
            try:
                length = int(self.headers.get("Content-Length") or "0")
                body = json.loads(self.rfile.read(length)) if 0 < length <= 4096 else None
            except (ValueError, UnicodeDecodeError):
                body = None
            task = body.get("task") if isinstance(body, dict) else None
            if not isinstance(task, str) or not task:
                return self._error(HTTPStatus.BAD_REQUEST, 'the body must be {"task": "<task id>"}')
            try:
                return self._json(self.server.start_play(task))
            except (PlayError, JarvisError) as exc:
                tail = getattr(exc, "output", "")
                return self._json({"error": str(exc), "output": tail[-2000:]}, int(HTTPStatus.BAD_REQUEST))
        except (BrokenPipeError, ConnectionResetError):
            pass

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
            self._failed(exc)

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
        server.stop_plays()
