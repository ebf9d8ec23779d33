"""What the project's small HTTP servers share (the dashboard's and the browser player's, both stdlib
`ThreadingHTTPServer`s): answers with their length and `nosniff`, JSON answers that are never cached, errors as
`{"error": ..., "status": ...}`, and a bug in a handler answered 500 and logged instead of taking the server down."""

from __future__ import annotations

import json
import sys
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler
from typing import Any


class JsonHandler(BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"
    always: dict[str, str] = {}  # headers of every answer
    name = "server"  # how its log lines begin

    def _send(self, status: int, body: bytes, content_type: str, headers: dict[str, str] | None = None) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("X-Content-Type-Options", "nosniff")
        for k, v in {**self.always, **(headers or {})}.items():
            self.send_header(k, v)
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _json(self, data: Any, status: int = 200) -> None:
        body = json.dumps(data, ensure_ascii=False, default=str).encode()
        self._send(status, body, "application/json; charset=utf-8", {"Cache-Control": "no-store"})

    def _error(self, status: HTTPStatus, message: str) -> None:
        self._json({"error": message, "status": int(status)}, int(status))

    def _failed(self, exc: Exception) -> None:
        """A bug of the handler: said on stderr and answered 500 with what happened."""
        print(f"{self.name}: {self.command} {self.path}: {exc.__class__.__name__}: {exc}", file=sys.stderr)
        try:
            self._error(HTTPStatus.INTERNAL_SERVER_ERROR, f"{exc.__class__.__name__}: {exc}")
        except OSError:
            pass
