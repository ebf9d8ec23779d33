"""The network layer of model calls: every socket operation ends by the calling thread's wall-clock deadline, and
one call (`stop_all`) cuts every model connection of the process at once.

httpx's timeouts bound each read on its own, so a server that sends one byte a second never trips them. Here
each connect, TLS handshake, write and read gets as its timeout the time left before the deadline of
`jarvis_pytest.llm.deadline` (at most the timeout httpx asked for), and one that starts after the deadline fails
at once with httpx's own timeout error. httpcore then closes the connection, as for any timeout: an abandoned
call leaves no socket behind. The I/O of a synchronous httpx client runs in the thread that made the request,
so the thread-local deadline of that thread is the one that applies.

`stop_all()` (the session calls it on SIGINT and SIGTERM) shuts down every open model connection, so a call
blocked in any thread fails immediately, and refuses new connections and back-off waits for the rest of the
process.
"""

from __future__ import annotations

import socket
import ssl
import threading
import typing
import weakref

import httpcore
import httpx

from jarvis_pytest.llm.deadline import remaining

_STOP = threading.Event()
_OPEN: weakref.WeakSet[_DeadlineStream] = weakref.WeakSet()
_OPEN_LOCK = threading.RLock()  # re-entrant: `stop_all` runs in a signal handler, maybe inside `_track`


class Stopped(httpcore.ReadError):
    """The process is stopping (`stop_all`): no model call may start or go on."""


def stopping() -> bool:
    """Whether `stop_all` was called in this process."""
    return _STOP.is_set()


def pause(seconds: float) -> bool:
    """Sleep up to `seconds` (a retry's back-off); False at once when the process is stopping."""
    return not _STOP.wait(max(0.0, seconds))


def stop_all() -> int:
    """Cut every open model connection of this process and refuse new ones; returns how many were cut.
    Safe to call from a signal handler (it takes no lock another thread can hold for long)."""
    _STOP.set()
    with _OPEN_LOCK:
        streams = list(_OPEN)
    for stream in streams:
        stream.cut()
    return len(streams)


def open_connections() -> int:
    """How many model connections of this process are open (in use or kept alive in a pool)."""
    with _OPEN_LOCK:
        return len(_OPEN)


def _cap(timeout: float | None, error: type[Exception]) -> float | None:
    """`timeout` cut to the time left before the thread's deadline; `error` when none is left or we stop."""
    if _STOP.is_set():
        raise Stopped("the process is stopping: model calls are cancelled")
    left = remaining()
    if left is None:
        return timeout
    if left <= 0:
        raise error("the call's wall-clock deadline passed")
    return left if timeout is None else min(timeout, left)


class _DeadlineStream(httpcore.NetworkStream):
    """A network stream whose every operation ends by the thread's deadline."""

    def __init__(self, inner: httpcore.NetworkStream):
        self._inner = inner
        with _OPEN_LOCK:
            _OPEN.add(self)

    def read(self, max_bytes: int, timeout: float | None = None) -> bytes:
        return self._inner.read(max_bytes, _cap(timeout, httpcore.ReadTimeout))

    def write(self, buffer: bytes, timeout: float | None = None) -> None:
        self._inner.write(buffer, _cap(timeout, httpcore.WriteTimeout))

    def close(self) -> None:
        with _OPEN_LOCK:
            _OPEN.discard(self)
        self._inner.close()

    def start_tls(self, ssl_context: ssl.SSLContext, server_hostname: str | None = None,
                  timeout: float | None = None) -> httpcore.NetworkStream:
        with _OPEN_LOCK:
            _OPEN.discard(self)  # the TLS stream owns the socket from here on
        return _DeadlineStream(self._inner.start_tls(ssl_context, server_hostname,
                                                     _cap(timeout, httpcore.ConnectTimeout)))

    def get_extra_info(self, info: str) -> typing.Any:
        return self._inner.get_extra_info(info)

    def cut(self) -> None:
        """Shut the socket down from any thread: a read or write blocked on it in another thread fails now."""
        sock = self._inner.get_extra_info("socket")
        if sock is not None:
            try:
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:  # already closed or never connected
                pass


class _DeadlineBackend(httpcore.NetworkBackend):
    def __init__(self, inner: httpcore.NetworkBackend):
        self._inner = inner

    def connect_tcp(self, host: str, port: int, timeout: float | None = None, local_address: str | None = None,
                    socket_options: typing.Iterable[typing.Any] | None = None) -> httpcore.NetworkStream:
        stream = self._inner.connect_tcp(host, port, _cap(timeout, httpcore.ConnectTimeout), local_address,
                                         socket_options)
        return _DeadlineStream(stream)

    def connect_unix_socket(self, path: str, timeout: float | None = None,
                            socket_options: typing.Iterable[typing.Any] | None = None) -> httpcore.NetworkStream:
        return _DeadlineStream(self._inner.connect_unix_socket(path, _cap(timeout, httpcore.ConnectTimeout),
                                                               socket_options))

    def sleep(self, seconds: float) -> None:
        pause(seconds)


def install(client: httpx.Client) -> httpx.Client:
    """Make every network transport of `client` (its own and those mounted for proxies) honour deadlines and
    `stop_all`. A transport that is not httpx's network transport (e.g. `httpx.MockTransport`) is left as is."""
    for transport in (client._transport, *client._mounts.values()):  # private: httpx has no public hook for this
        if isinstance(transport, httpx.HTTPTransport):
            pool = transport._pool
            inner = getattr(pool, "_network_backend", None)
            if inner is None:
                raise RuntimeError(f"httpcore {httpcore.__version__} changed: its connection pool has no network "
                                   "backend to wrap, so model calls would have no wall-clock deadline")
            if not isinstance(inner, _DeadlineBackend):
                pool._network_backend = _DeadlineBackend(inner)
    return client
