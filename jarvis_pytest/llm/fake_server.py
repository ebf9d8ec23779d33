"""A loopback OpenAI-compatible server for tests: scripted answers, recorded requests, injected failures.

It is a real HTTP server on 127.0.0.1 (a free port) in a background thread, so the code under test makes real
httpx requests. Use it as a context manager::

    with FakeChatServer() as server:
        server.script("<step>{...}</step>", model="planner")          # answers, in order, for one model
        server.script(fail(429, retry_after=0), '{"x": 500, "y": 500}', model="holo")
        server.respond_with(lambda req: f"[{req.image_sizes()[0][0] // 2}, 10]", model="venus")  # computed
        client = ChatClient(server.url, "planner")
        ...
        server.requests          # every request received, failures included, as RecordedRequest
        server.requests_for("holo")[0].image_sizes()   # the size of the image the client actually sent

Answers are chosen in this order: the model's queue, the any-model queue, the model's responder, the default
responder. A request nothing answers gets HTTP 400 naming the model (a test bug, so the client does not retry).
Endpoints: ``POST /v1/chat/completions``, ``GET /v1/models``. With ``api_key`` set, requests without the matching
``Authorization: Bearer`` get 401. A one-token request (``max_tokens: 1``, the harness's start-up probe) is
answered "OK" for a model in ``models`` and with 404 "model does not exist" for any other, as vLLM does, without
touching the scripted answers (unless ``probe_reply`` is set: then every probe gets that reply).

A slow server: ``stall(s)`` sends nothing for `s` seconds; ``dribble(interval)`` sends its whole answer, status
line and headers included, one byte every `interval` seconds, so that no single read of the client ever waits
long. ``dribbling`` counts the answers being dribbled now and ``hangups`` those whose client closed the
connection before the end (seen within one interval of the close).
"""

from __future__ import annotations

import base64
import io
import json
import select
import socket
import sys
import threading
from collections import deque
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any, Callable

from PIL import Image


@dataclass
class Reply:
    """One scripted answer: assistant text, or an HTTP failure, optionally after a delay (to provoke timeouts)."""

    text: str = ""
    status: int = 200
    delay: float = 0.0
    headers: dict[str, str] = field(default_factory=dict)
    usage: dict[str, int] | None = None
    reasoning: str | None = None
    body: Any = None  # a raw body (dict or str) sent instead of a chat completion
    dribble: float = 0.0  # > 0: the whole answer is sent one byte per `dribble` seconds


def fail(status: int = 500, *, retry_after: float | None = None, message: str = "injected failure") -> Reply:
    """An HTTP error reply (429, 500, 503, ...)."""
    headers = {} if retry_after is None else {"Retry-After": f"{retry_after:g}"}
    return Reply(status=status, headers=headers, body={"error": {"message": message, "code": status}})


def stall(seconds: float, text: str = "") -> Reply:
    """A reply that arrives only after `seconds` (longer than the client's timeout: a timeout)."""
    return Reply(text=text, delay=seconds)


def dribble(interval: float = 1.0, text: str = "OK") -> Reply:
    """A reply sent one byte every `interval` seconds, status line and headers included (a server that is
    alive but far too slow: no read of the client waits more than `interval`)."""
    return Reply(text=text, dribble=interval)


@dataclass
class RecordedRequest:
    """One request as the server received it."""

    method: str
    path: str
    headers: dict[str, str]
    body: Any

    @property
    def model(self) -> str | None:
        return self.body.get("model") if isinstance(self.body, dict) else None

    @property
    def messages(self) -> list[dict[str, Any]]:
        return list(self.body.get("messages") or []) if isinstance(self.body, dict) else []

    def parts(self, role: str | None = None) -> list[dict[str, Any]]:
        """All content parts, in order (a string content counts as one text part)."""
        out: list[dict[str, Any]] = []
        for msg in self.messages:
            if role is not None and msg.get("role") != role:
                continue
            content = msg.get("content")
            if isinstance(content, str):
                out.append({"type": "text", "text": content})
            elif isinstance(content, list):
                out.extend(p for p in content if isinstance(p, dict))
        return out

    def text(self, role: str | None = None) -> str:
        """The text parts joined by newlines."""
        return "\n".join(p.get("text", "") for p in self.parts(role) if p.get("type") == "text")

    def image_count(self) -> int:
        """How many images the request carries (none decoded)."""
        return sum(p.get("type") == "image_url" for p in self.parts())

    def images(self) -> list[bytes]:
        """The images of the request, decoded from their data URLs."""
        out = []
        for p in self.parts():
            if p.get("type") == "image_url":
                url = (p.get("image_url") or {}).get("url", "")
                head, _, data = url.partition(",")
                if head.startswith("data:") and head.endswith(";base64"):
                    out.append(base64.b64decode(data))
        return out

    def image_sizes(self) -> list[tuple[int, int]]:
        """(width, height) of each image as sent (read from the image header only)."""
        sizes = []
        for data in self.images():
            with Image.open(io.BytesIO(data)) as img:
                sizes.append(img.size)
        return sizes


Responder = Callable[[RecordedRequest], "Reply | str"]


class FakeChatServer:
    """The loopback server; see the module docstring."""

    def __init__(self, responder: Responder | None = None, *, api_key: str | None = None,
                 models: tuple[str, ...] = ("fake-model",), record: bool = True):
        self.api_key = api_key
        self.models = tuple(models)
        self.record = record  # False: `requests` stays empty (a long benchmark would hold every screenshot sent)
        self.requests: list[RecordedRequest] = []
        self.received = 0  # requests received, recorded or not
        self.probe_reply: Reply | None = None  # set: the start-up probes get this instead of "OK"
        self.dribbling = 0  # answers being dribbled now
        self.hangups = 0  # dribbled answers whose client closed the connection before the end
        self._default = responder
        self._responders: dict[str | None, Responder] = {}
        self._queues: dict[str | None, deque[Reply | str]] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._httpd: ThreadingHTTPServer | None = None
        self._thread: threading.Thread | None = None

    # -- scripting ---------------------------------------------------------------------------------------------
    def script(self, *replies: Reply | str, model: str | None = None) -> FakeChatServer:
        """Queue answers (texts or Replies) for `model` (None: any model), served first in, first out."""
        with self._lock:
            self._queues.setdefault(model, deque()).extend(replies)
        return self

    def respond_with(self, responder: Responder, model: str | None = None) -> FakeChatServer:
        """Answer `model`'s requests (None: every model) by calling `responder(request)`."""
        with self._lock:
            self._responders[model] = responder
        return self

    def pending(self, model: str | None = None) -> int:
        """How many scripted answers are still queued for `model`."""
        with self._lock:
            return len(self._queues.get(model, ()))

    def requests_for(self, model: str | None) -> list[RecordedRequest]:
        with self._lock:
            return [r for r in self.requests if r.model == model and r.path.endswith("/chat/completions")]

    # -- lifecycle ---------------------------------------------------------------------------------------------
    @property
    def url(self) -> str:
        """The base URL to give a client (``http://127.0.0.1:<port>/v1``)."""
        if self._httpd is None:
            raise RuntimeError("the fake server is not running; use it as a context manager or call start()")
        return f"http://127.0.0.1:{self._httpd.server_address[1]}/v1"

    def start(self) -> FakeChatServer:
        if self._httpd is None:
            self._stop.clear()
            self._httpd = _Server(("127.0.0.1", 0), _Handler, self)
            self._thread = threading.Thread(target=self._httpd.serve_forever, kwargs={"poll_interval": 0.05},
                                            name="fake-chat-server", daemon=True)
            self._thread.start()
        return self

    def close(self) -> None:
        self._stop.set()  # wakes stalled replies
        if self._httpd is not None:
            self._httpd.shutdown()
            self._httpd.server_close()
            self._httpd = None
        if self._thread is not None:
            self._thread.join(timeout=5)
            self._thread = None

    def __enter__(self) -> FakeChatServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- answering ---------------------------------------------------------------------------------------------
    def _record(self, req: RecordedRequest) -> None:
        with self._lock:
            self.received += 1
            if self.record:
                self.requests.append(req)

    def _choose(self, req: RecordedRequest) -> Reply | str:
        with self._lock:
            for key in (req.model, None):
                queue = self._queues.get(key)
                if queue:
                    return queue.popleft()
            responder = self._responders.get(req.model) or self._responders.get(None) or self._default
        if responder is None:
            return Reply(status=400, body={"error": {"message": f"fake server: nothing scripted for model "
                                                                f"{req.model!r}"}})
        return responder(req)

    def _completion(self, req: RecordedRequest, reply: Reply) -> dict[str, Any]:
        prompt_chars = len(req.text())
        usage = reply.usage or {"prompt_tokens": prompt_chars // 4 + 100 * req.image_count(),
                                "completion_tokens": max(1, len(reply.text) // 4)}
        usage = {**usage, "total_tokens": usage.get("prompt_tokens", 0) + usage.get("completion_tokens", 0)}
        message: dict[str, Any] = {"role": "assistant", "content": reply.text}
        if reply.reasoning is not None:
            message["reasoning_content"] = reply.reasoning
        return {"id": f"chatcmpl-fake-{self.received}", "object": "chat.completion", "created": 0,
                "model": req.model, "choices": [{"index": 0, "message": message, "finish_reason": "stop"}],
                "usage": usage, "system_fingerprint": "fp_fake"}


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    allow_reuse_address = True

    def __init__(self, address, handler, fake: FakeChatServer):
        super().__init__(address, handler)
        self.fake = fake

    def handle_error(self, request, client_address) -> None:
        if isinstance(sys.exc_info()[1], (ConnectionResetError, BrokenPipeError)):
            return  # a client that gave up (a provoked timeout or size limit): not a server fault
        super().handle_error(request, client_address)


class _Handler(BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"
    server: _Server

    def log_message(self, format: str, *args: Any) -> None:  # quiet
        pass

    def _send(self, status: int, body: Any, headers: dict[str, str] | None = None) -> None:
        data = body if isinstance(body, bytes) else (body if isinstance(body, str) else json.dumps(body)).encode()
        try:
            self.send_response(status)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(data)))
            for k, v in (headers or {}).items():
                self.send_header(k, v)
            self.end_headers()
            self.wfile.write(data)
        except (BrokenPipeError, ConnectionResetError):
            pass  # the client gave up (a provoked timeout)

    def _authorized(self) -> bool:
        key = self.server.fake.api_key
        return key is None or self.headers.get("Authorization") == f"Bearer {key}"

    def do_GET(self) -> None:
        fake = self.server.fake
        fake._record(RecordedRequest("GET", self.path, dict(self.headers), None))
        if not self._authorized():
            return self._send(401, {"error": {"message": "invalid api key"}})
        if self.path.rstrip("/").endswith("/models"):
            return self._send(200, {"object": "list", "data": [{"id": m, "object": "model", "owned_by": "fake"}
                                                              for m in fake.models]})
        self._send(404, {"error": {"message": f"no route {self.path}"}})

    def do_POST(self) -> None:
        fake = self.server.fake
        length = int(self.headers.get("Content-Length") or 0)
        raw = self.rfile.read(length) if length else b""
        try:
            body = json.loads(raw or b"null")
        except json.JSONDecodeError:
            body = raw.decode("utf-8", "replace")
        req = RecordedRequest("POST", self.path, dict(self.headers), body)
        fake._record(req)
        if not self.path.rstrip("/").endswith("/chat/completions"):
            return self._send(404, {"error": {"message": f"no route {self.path}"}})
        if not self._authorized():
            return self._send(401, {"error": {"message": "invalid api key"}})
        if not isinstance(body, dict) or "messages" not in body:
            return self._send(400, {"error": {"message": "body must be a JSON object with messages"}})
        if body.get("max_tokens") == 1:  # a start-up probe: a real server answers it whatever was scripted
            if body.get("model") not in fake.models:
                return self._send(404, {"error": {"message": f"The model `{body.get('model')}` does not exist.",
                                                  "code": 404}})
            reply = fake.probe_reply or Reply(text="OK")
        else:
            try:
                reply = fake._choose(req)
            except Exception as exc:  # a responder's bug: visible in the client's error
                return self._send(400, {"error": {"message": f"fake server responder failed: {exc!r}"}})
        if isinstance(reply, str):
            reply = Reply(text=reply)
        if reply.delay and fake._stop.wait(reply.delay):
            return
        body_out = reply.body if reply.body is not None else fake._completion(req, reply)
        if reply.dribble > 0:
            return self._dribble(reply.status, body_out, reply.headers, reply.dribble)
        self._send(reply.status, body_out, reply.headers)

    def _dribble(self, status: int, body: Any, headers: dict[str, str], interval: float) -> None:
        """Send the whole answer one byte per `interval` seconds; stop when the client hangs up."""
        fake = self.server.fake
        data = (body if isinstance(body, str) else json.dumps(body)).encode()
        head = [f"HTTP/1.1 {status} {self.responses.get(status, ('',))[0]}", "Content-Type: application/json",
                f"Content-Length: {len(data)}", *(f"{k}: {v}" for k, v in headers.items())]
        payload = ("\r\n".join(head) + "\r\n\r\n").encode() + data
        self.close_connection = True
        with fake._lock:
            fake.dribbling += 1
        try:
            for i in range(len(payload)):
                try:
                    self.connection.sendall(payload[i:i + 1])
                except OSError:
                    return self._hung_up()
                if i + 1 < len(payload) and self._gone_within(interval):
                    return self._hung_up() if not fake._stop.is_set() else None
        finally:
            with fake._lock:
                fake.dribbling -= 1

    def _gone_within(self, seconds: float) -> bool:
        """Wait up to `seconds`; True as soon as the client closed the connection (or the server stops)."""
        fake = self.server.fake
        readable, _, _ = select.select([self.connection], [], [], seconds)
        if fake._stop.is_set():
            return True
        if not readable:
            return False
        try:
            return self.connection.recv(1, socket.MSG_PEEK) == b""
        except OSError:
            return True

    def _hung_up(self) -> None:
        with self.server.fake._lock:
            self.server.fake.hangups += 1
