"""A small QMP client: JSON commands over QEMU's UNIX socket, file descriptors passed with SCM_RIGHTS (`getfd`).

Ours rather than a library: the runner needs six commands, synchronously, inside a container that has Debian's
python3 and nothing from PyPI; `qemu.qmp` (the QEMU project's own) is asyncio-only and would have to be installed
there. Events are read and dropped; every command has a deadline.
"""

from __future__ import annotations

import json
import socket
import time
from typing import Any


class QmpError(RuntimeError):
    """QEMU answered a command with an error, or the monitor could not be reached in time."""


class Qmp:
    """One QMP session (`connect` performs the greeting and capabilities negotiation)."""

    def __init__(self, sock: socket.socket):
        self.sock = sock
        self._buffer = b""

    @classmethod
    def connect(cls, path: str, timeout: float = 10.0, alive=lambda: True) -> "Qmp":
        """Connect to the monitor socket at `path`, retrying until `timeout` while `alive()` (QEMU still runs)."""
        deadline = time.monotonic() + timeout
        while True:
            sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            try:
                sock.connect(path)
                break
            except OSError as exc:
                sock.close()
                if time.monotonic() > deadline or not alive():
                    raise QmpError(f"QMP socket {path} did not answer: {exc}") from None
                time.sleep(0.02)
        session = cls(sock)
        session._read(deadline)  # the greeting
        session.execute("qmp_capabilities")
        return session

    def _read(self, deadline: float) -> dict[str, Any]:
        while b"\n" not in self._buffer:
            left = deadline - time.monotonic()
            if left <= 0:
                raise QmpError("QMP: no answer in time")
            self.sock.settimeout(left)
            try:
                chunk = self.sock.recv(65536)
            except socket.timeout:
                raise QmpError("QMP: no answer in time") from None
            except OSError as exc:
                raise QmpError(f"QMP: the monitor failed ({exc}): QEMU exited") from None
            if not chunk:
                raise QmpError("QMP: QEMU closed the monitor (it exited)")
            self._buffer += chunk
        line, _, self._buffer = self._buffer.partition(b"\n")
        return json.loads(line)

    def execute(self, command: str, arguments: dict[str, Any] | None = None, fds: list[int] | None = None,
                timeout: float = 30.0) -> Any:
        """Run one command; its `return` value, or QmpError with QEMU's description."""
        message = {"execute": command, **({"arguments": arguments} if arguments else {})}
        data = json.dumps(message).encode() + b"\n"
        try:
            if fds:
                socket.send_fds(self.sock, [data], fds)
            else:
                self.sock.sendall(data)
        except OSError as exc:
            raise QmpError(f"QMP: cannot send {command} ({exc}): QEMU exited") from None
        deadline = time.monotonic() + timeout
        while True:
            reply = self._read(deadline)
            if "return" in reply:
                return reply["return"]
            if "error" in reply:
                raise QmpError(f"{command}: {reply['error'].get('desc', reply['error'])}")
            # an event ({"event": ...}): not what we wait for

    def close(self) -> None:
        self.sock.close()
