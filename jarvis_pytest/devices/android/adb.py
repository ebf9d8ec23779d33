"""One thin wrapper over the real `adb` binary: every call a subprocess with a deadline, `-s serial` always.

Why not `adbutils`: it speaks the adb server protocol itself and bundles its own `adb` binary (36.x) for
starting the server. Two adb versions on one machine kill each other's server on every version mismatch
("adb server version (41) doesn't match this client (39); killing..."), and what we need from adb is a dozen
commands whose output formats are stable. A subprocess per call also gives the one property that matters most
here: a stuck adb (AndroidWorld #59: `adb` hanging forever on a wedged emulator) is killed with its process group
at the deadline and becomes an `InfrastructureError` in bounded time.

The adb server is ours: started on demand on a port of its own (`JARVIS_ADB_SERVER_PORT`, default 5137, so a
user's own server on 5037 of another adb version is never killed), listening on 127.0.0.1 only (adb's `-P`
server binds `localhost`; `-a`, all interfaces, is never passed). A USB phone is claimed by one adb server only:
to attach one that the user's own server holds, set `JARVIS_ADB_SERVER_PORT=5037` (or `adb kill-server` first).
"""

from __future__ import annotations

import os
import re
import secrets
import shutil
import signal
import subprocess
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from jarvis_pytest.errors import InfrastructureError

DEFAULT_SERVER_PORT = 5137
SERVER_START_TIMEOUT = 20.0
DEFAULT_TIMEOUT = 30.0
DEBIAN_ADB = "/usr/lib/android-sdk/platform-tools/adb"   # where Debian's `adb` package installs the binary
INSTALL_HINT = ("install Debian's adb (`apt-get install adb`), or point JARVIS_ADB at an adb binary "
                "(e.g. the Android SDK's platform-tools/adb)")
_DEVICE_ERRORS = ("device offline", "device unauthorized", "not found", "no devices", "no emulators",
                  "closed", "protocol fault", "cannot connect", "failed to connect", "device still authorizing",
                  "more than one device")

_started: set[tuple[str, int]] = set()
_start_lock = threading.Lock()


def adb_binary() -> str:
    """The adb executable: $JARVIS_ADB, else `adb` on PATH, else Debian's install path."""
    configured = os.environ.get("JARVIS_ADB")
    if configured:
        if not Path(configured).is_file():
            raise InfrastructureError(f"JARVIS_ADB={configured} does not exist; {INSTALL_HINT}")
        return configured
    found = shutil.which("adb") or (DEBIAN_ADB if Path(DEBIAN_ADB).is_file() else None)
    if not found:
        raise InfrastructureError(f"no adb binary on this machine: {INSTALL_HINT}")
    return found


def server_port() -> int:
    """The port of our adb server: $JARVIS_ADB_SERVER_PORT, else 5137."""
    raw = os.environ.get("JARVIS_ADB_SERVER_PORT", str(DEFAULT_SERVER_PORT))
    try:
        port = int(raw)
    except ValueError:
        raise InfrastructureError(f"JARVIS_ADB_SERVER_PORT={raw!r} is not a port number") from None
    if not 1 <= port <= 65535:
        raise InfrastructureError(f"JARVIS_ADB_SERVER_PORT={port} is not a port number")
    return port


@dataclass(frozen=True)
class AdbResult:
    """What one adb invocation returned."""

    argv: tuple[str, ...]
    returncode: int
    stdout: bytes
    stderr: bytes
    elapsed_s: float = 0.0

    @property
    def out(self) -> str:
        return self.stdout.decode("utf-8", "replace")

    @property
    def err(self) -> str:
        return self.stderr.decode("utf-8", "replace")

    @property
    def message(self) -> str:
        """stdout and stderr, stripped, for error messages."""
        return " ".join(p for p in (self.out.strip(), self.err.strip()) if p)[:1000] or "(no output)"


@dataclass(frozen=True)
class ShellResult:
    """A command's exit status and output on the device."""

    returncode: int
    stdout: str
    stderr: str


@dataclass
class Adb:
    """The adb client for one device (`serial`) or for the server itself (no serial)."""

    serial: str | None = None
    port: int = field(default_factory=server_port)
    binary: str = field(default_factory=adb_binary)
    _features: set[str] | None = field(default=None, repr=False)

    def for_serial(self, serial: str) -> "Adb":
        return Adb(serial=serial, port=self.port, binary=self.binary)

    def argv(self, *args: str) -> list[str]:
        base = [self.binary, "-P", str(self.port)]
        if self.serial:
            base += ["-s", self.serial]
        return [*base, *args]

    def describe(self, args: tuple[str, ...] | list[str]) -> str:
        """The command line as a user would type it (for messages)."""
        shown = ["adb", "-P", str(self.port)] + (["-s", self.serial] if self.serial else []) + list(args)
        return " ".join(a if a and not re.search(r"[\s'\"$`\\|&;<>()*?]", a) else repr(a) for a in shown)

    # -- the one place a process is made ------------------------------------------------------------------------
    def call(self, *args: str, timeout: float = DEFAULT_TIMEOUT, stdin: bytes | None = None,
             ensure_server: bool = True) -> AdbResult:
        """Run `adb -P port [-s serial] args...`; kill it (and its children) at `timeout` s and raise
        InfrastructureError. Never raises for a non-zero exit status: callers decide."""
        if ensure_server:
            self.ensure_server()
        argv = self.argv(*args)
        env = dict(os.environ)
        env.pop("ANDROID_SERIAL", None)  # -s is always explicit
        env.pop("ADB_SERVER_SOCKET", None)  # the port is ours (-P)
        t0 = time.monotonic()
        try:
            proc = subprocess.Popen(argv, stdin=subprocess.PIPE if stdin is not None else subprocess.DEVNULL,
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env,
                                    start_new_session=True)
        except OSError as exc:
            raise InfrastructureError(f"cannot run {self.binary}: {exc}; {INSTALL_HINT}") from exc
        try:
            out, err = proc.communicate(stdin, timeout=timeout)
        except subprocess.TimeoutExpired:
            _kill_group(proc)
            out, err = _drain(proc)
            raise InfrastructureError(
                f"`{self.describe(args)}` did not finish within {timeout:g} s: the device or the adb server "
                f"is stuck (killed; partial output: {(out + err).decode('utf-8', 'replace').strip()[:300]!r})"
            ) from None
        return AdbResult(tuple(argv), proc.returncode, out, err, time.monotonic() - t0)

    def checked(self, *args: str, timeout: float = DEFAULT_TIMEOUT, what: str | None = None) -> AdbResult:
        """`call`, raising InfrastructureError with adb's own words when it fails."""
        r = self.call(*args, timeout=timeout)
        if r.returncode != 0:
            raise InfrastructureError(f"{what or '`' + self.describe(args) + '`'} failed "
                                      f"(exit {r.returncode}): {r.message}")
        return r

    # -- server --------------------------------------------------------------------------------------------------
    def ensure_server(self) -> None:
        """Start our adb server on 127.0.0.1:<port> unless this process already did (bounded in time)."""
        key = (self.binary, self.port)
        if key in _started:
            return
        with _start_lock:
            if key in _started:
                return
            r = self.call("start-server", timeout=SERVER_START_TIMEOUT, ensure_server=False)
            if r.returncode != 0:
                raise InfrastructureError(f"cannot start the adb server on 127.0.0.1:{self.port} "
                                          f"(`{self.describe(('start-server',))}`: {r.message}); is the port "
                                          "taken by another program? set JARVIS_ADB_SERVER_PORT to a free one")
            _started.add(key)

    def kill_server(self, timeout: float = 10.0) -> None:
        """Stop our adb server (the one on `self.port`)."""
        self.call("kill-server", timeout=timeout, ensure_server=False)
        _started.discard((self.binary, self.port))

    def devices(self, timeout: float = 10.0) -> dict[str, str]:
        """serial → state (`device`, `offline`, `unauthorized`, ...) of every device our server knows."""
        r = Adb(port=self.port, binary=self.binary).checked("devices", timeout=timeout)
        return parse_devices(r.out)

    # -- transports ----------------------------------------------------------------------------------------------
    def connect(self, address: str, timeout: float = 15.0) -> None:
        """`adb connect host:port`; an InfrastructureError naming adb's reason when it does not connect (adb
        itself exits 0 even then), and the half-made transport is dropped."""
        server = Adb(port=self.port, binary=self.binary)
        try:
            r = server.call("connect", address, timeout=timeout)
        except InfrastructureError as exc:
            server.call("disconnect", address, timeout=5)
            raise InfrastructureError(f"adb could not connect to {address}: {exc}") from None
        text = r.message
        if r.returncode != 0 or not re.search(r"\b(already )?connected to\b", text) or "failed" in text:
            server.call("disconnect", address, timeout=5)
            raise InfrastructureError(f"adb could not connect to {address}: {text}")

    def disconnect(self, address: str | None = None, timeout: float = 10.0) -> None:
        target = address or self.serial
        if target:
            Adb(port=self.port, binary=self.binary).call("disconnect", target, timeout=timeout)

    def state(self, timeout: float = 10.0) -> str:
        """`get-state` of this device: device | offline | bootloader | unauthorized | missing (unknown)."""
        r = self.call("get-state", timeout=timeout)
        if r.returncode == 0:
            return r.out.strip()
        text = r.message
        for word in ("unauthorized", "offline", "authorizing"):
            if word in text:
                return word
        return "missing"

    def wait_online(self, timeout: float, *, reconnect: bool = True) -> None:
        """Until this device is in state `device` (reconnecting TCP serials): else InfrastructureError."""
        deadline = time.monotonic() + timeout
        last = "not checked"
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise InfrastructureError(f"android device {self.serial} not online after {timeout:.0f} s "
                                          f"(last state: {last}){_state_hint(last)}")
            try:
                last = self.state(timeout=min(5.0, remaining))
                if last == "device":
                    return
                if reconnect and is_tcp_serial(self.serial) and last in ("missing", "offline"):
                    try:
                        self.connect(self.serial, timeout=min(10.0, max(1.0, remaining)))
                    except InfrastructureError as exc:
                        last = f"{last}; {exc}"
            except InfrastructureError as exc:
                last = str(exc)
            time.sleep(min(0.5, max(0.0, deadline - time.monotonic())))

    def features(self) -> set[str]:
        """The adb features both ends support (`shell_v2` keeps exit status and stderr apart)."""
        if self._features is None:
            r = self.call("features", timeout=10)
            self._features = set(r.out.split()) if r.returncode == 0 else set()
        return self._features

    # -- commands on the device ----------------------------------------------------------------------------------
    def shell(self, command: str, timeout: float = 60.0) -> ShellResult:
        """Run `command` with the device's `sh`; its exit status is kept even where adb loses it (devices
        without shell protocol v2 always exit 0): the command runs in a subshell followed by a marker that
        carries `$?`, which is cut from the output again. A device that is gone raises InfrastructureError."""
        mark = f"__JARVIS_RC_{secrets.token_hex(6)}__"
        r = self.call("shell", wrap_shell(command, mark), timeout=timeout)
        raw = r.stdout
        code, body = unwrap_shell(raw, mark)
        if code is None and _looks_like_transport_error(r.message) and (r.returncode != 0 or not r.stdout):
            raise InfrastructureError(f"android device {self.serial}: `adb shell` failed: {r.message}")
        v2 = "shell_v2" in self.features()
        if code is None:
            # the shell itself stopped early (a syntax error in `command`, `exec`, a killed shell): the
            # command failed, and adb's own status (0 on devices without shell v2) is no evidence otherwise
            out = raw.decode("utf-8", "replace")
            return ShellResult(r.returncode or 255, out if v2 else out.replace("\r\n", "\n"), r.err)
        out = body.decode("utf-8", "replace")
        err = r.err
        if not v2:  # legacy shell: a pty turns \n into \r\n and merges stderr into stdout
            out, err = out.replace("\r\n", "\n"), err.replace("\r\n", "\n")
        return ShellResult(code, out, err)

    def exec_out(self, command: str, timeout: float = 60.0) -> bytes:
        """`adb exec-out command`: raw bytes, no pty, no newline translation (for screencap and file contents).
        stdout and stderr arrive merged on this channel, so commands here send stderr to /dev/null."""
        r = self.call("exec-out", command, timeout=timeout)
        if r.returncode != 0 and _looks_like_transport_error(r.message):
            raise InfrastructureError(f"android device {self.serial}: `adb exec-out {command}` failed: "
                                      f"{r.message}")
        return r.stdout

    def push(self, local: str | Path, remote: str, timeout: float = 120.0) -> None:
        self.checked("push", str(local), remote, timeout=timeout,
                     what=f"copying {local} to {remote} on android device {self.serial}")

    def pull(self, remote: str, local: str | Path, timeout: float = 120.0) -> None:
        self.checked("pull", remote, str(local), timeout=timeout,
                     what=f"copying {remote} from android device {self.serial}")

    def reverse(self, device_port: int, host_port: int, timeout: float = 10.0) -> None:
        """Make the device's 127.0.0.1:device_port reach this machine's 127.0.0.1:host_port."""
        self.checked("reverse", f"tcp:{device_port}", f"tcp:{host_port}", timeout=timeout)

    def root(self, timeout: float = 60.0) -> bool:
        """Restart adbd as root where the build allows it (userdebug/eng, e.g. google_apis emulator images);
        False on production builds. Waits until the device is back."""
        r = self.call("root", timeout=timeout)
        text = r.message.lower()
        if "cannot run as root" in text or "production builds" in text:
            return False
        if r.returncode != 0 and "already running as root" not in text:
            raise InfrastructureError(f"`adb root` on {self.serial} failed: {r.message}")
        if "already running as root" not in text:
            time.sleep(1.0)  # adbd restarts: the transport drops and comes back
            self.wait_online(timeout)
        self._features = None
        return True

    def getprop(self, name: str, timeout: float = 10.0) -> str:
        return self.shell(f"getprop {name}", timeout=timeout).stdout.strip()


def wrap_shell(command: str, mark: str) -> str:
    """`command` in a subshell, then `mark` and its exit status (an `exit` in `command` ends the subshell only)."""
    return f"( :; {command}\n) ; printf '%s%s' '{mark}' \"$?\""


def unwrap_shell(raw: bytes, mark: str) -> tuple[int | None, bytes]:
    """(exit status or None when the marker is missing, the command's own output) of a wrapped command."""
    at = raw.rfind(mark.encode())
    if at < 0:
        return None, raw
    tail = raw[at + len(mark):].strip()
    return (int(tail) if tail.isdigit() else None), raw[:at]


def parse_devices(text: str) -> dict[str, str]:
    """`adb devices` output → serial → state."""
    out: dict[str, str] = {}
    for line in text.splitlines():
        line = line.strip()
        if not line or line.startswith(("List of devices", "*", "adb ")):
            continue
        parts = line.split()
        if len(parts) >= 2:
            out[parts[0]] = parts[1]
    return out


def is_tcp_serial(serial: str | None) -> bool:
    """A serial that adb reaches over TCP (`host:port`), not USB or a local `emulator-5554`."""
    return bool(serial) and re.fullmatch(r"[^\s:]+:\d{1,5}", serial or "") is not None


def _looks_like_transport_error(text: str) -> bool:
    low = text.lower()
    return low.startswith(("error:", "adb: error", "adb:")) or any(e in low for e in _DEVICE_ERRORS)


def _state_hint(state: str) -> str:
    if "unauthorized" in state:
        return ": accept the USB debugging prompt on the device (this machine's key is ~/.android/adbkey.pub)"
    if "missing" in state or "not found" in state:
        return ": is the serial right (`adb devices`) and the device reachable?"
    return ""


def _kill_group(proc: subprocess.Popen) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        try:
            proc.kill()
        except ProcessLookupError:
            pass


def _drain(proc: subprocess.Popen) -> tuple[bytes, bytes]:
    try:
        out, err = proc.communicate(timeout=2)
        return out or b"", err or b""
    except subprocess.TimeoutExpired:
        return b"", b""
