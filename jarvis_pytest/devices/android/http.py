"""Shell commands with which an Android device itself uploads a file to, or downloads one from, the task's drive.

What an Android image has (AOSP `system/core/shell_and_utilities/README.md`): `mksh` as `/system/bin/sh` and
toybox, whose `nc`/`netcat` ships from Android 10 (Q) on; there is no `wget`, and `curl` is not among the
system partition's packages (`build/make/target/product/base_system.mk`). So the commands speak HTTP/1.0 through
`nc` themselves (a request line, the drive's `PW:` header, `Content-Length`, `Connection: close`), check the
status line, and for a download strip the response headers with the shell's `read` (which consumes a pipe byte
by byte, so the body that follows is copied unchanged by `cat`). Only a device without `nc` (Android 9 and
older) falls back to a `curl` where one exists (some vendor images, Termux).

The drive's host is tried as 127.0.0.1 first (an attached phone reaches the drive through `adb reverse
tcp:5244 tcp:<the drive's port on this machine>`), then by its name on the task network (`transfer`, which the
emulator resolves through its virtual DNS 10.0.2.3, i.e. the container's resolver), then, on an emulator only
(`ro.boot.qemu`/`ro.kernel.qemu`), as 10.0.2.2, the container's loopback, where `socat` relays to the drive;
the last attempt by name runs again with its error shown.
"""

from __future__ import annotations

import shlex
from urllib.parse import urlsplit

LOCAL_HOST = "127.0.0.1"
EMULATOR_HOST = "10.0.2.2"   # the emulator's alias of its host (the container's loopback: socat to the drive)


def _attempts(host: str) -> str:
    """Try 127.0.0.1 (adb reverse), then the drive's name, then, on an emulator only, 10.0.2.2."""
    on_emulator = "case \"$(getprop ro.boot.qemu)$(getprop ro.kernel.qemu)\" in *1*) true;; *) false;; esac"
    return (f"req {LOCAL_HOST} 2>/dev/null || req {shlex.quote(host)} 2>/dev/null || "
            f"{{ {on_emulator} 2>/dev/null && req {EMULATOR_HOST}; }} || req {shlex.quote(host)}")


def _parts(url: str) -> tuple[str, int, str]:
    u = urlsplit(url)
    if u.scheme != "http" or not u.hostname:
        raise ValueError(f"only http://host[:port]/path URLs are supported on Android, not {url!r}")
    path = u.path or "/"
    if u.query:
        path += "?" + u.query
    return u.hostname, u.port or 80, path


def _request_function(method: str, url: str, password: str, ok: str) -> str:
    """`req HOST`: send the request (body from `$f` for PUT) with nc, check the status, then run `$body`."""
    host, port, path = _parts(url)
    q = shlex.quote
    head = f"{method} %s HTTP/1.0\\r\\nHost: %s:%s\\r\\nPW: %s\\r\\n"
    if method == "PUT":
        send = (f"{{ printf '{head}Content-Length: %s\\r\\nConnection: close\\r\\n\\r\\n' {q(path)} \"$1\" "
                f"{port} {q(password)} \"$n\" && cat \"$f\"; }}")
    else:
        send = f"printf '{head}Connection: close\\r\\n\\r\\n' {q(path)} \"$1\" {port} {q(password)}"
    check = (f"IFS= read -r s; case \"$s\" in \"HTTP/1.\"[01]\" {ok}\"*) ;; *) echo \"{method} {path}: "
             f"${{s:-no answer}}\" >&2; cat >/dev/null; exit 1;; esac")
    return f"req() {{ {send} | nc \"$1\" {port} | {{ {check}; body; }}; }}"


def put_command(path: str, url: str, password: str) -> str:
    """A command that uploads the device file `path` to `url` (HTTP PUT with the drive's `PW:` header)."""
    host, port, _ = _parts(url)
    q = shlex.quote
    curl = f"curl -fsS -H {q('PW: ' + password)} -T \"$f\" {q(url)}"
    return (f"f={q(path)}; if command -v nc >/dev/null 2>&1; then "
            f"n=$(stat -c %s \"$f\") || exit 1; body() {{ cat >/dev/null; }}; "
            f"{_request_function('PUT', url, password, '2')}; "
            f"{_attempts(host)}; else {curl}; fi")


def get_command(url: str, path: str, password: str) -> str:
    """A command that downloads `url` into the device file `path` (HTTP GET with the drive's `PW:` header)."""
    host, port, _ = _parts(url)
    q = shlex.quote
    curl = f"curl -fsS -H {q('PW: ' + password)} -o \"$o\" {q(url)}"
    skip_headers = ("cr=$(printf '\\r'); while IFS= read -r l; do case \"$l\" in \"\"|\"$cr\") break;; esac; "
                    "done; cat > \"$o\"")
    return (f"o={q(path)}; if command -v nc >/dev/null 2>&1; then "
            f"body() {{ {skip_headers}; }}; "
            f"{_request_function('GET', url, password, '200')}; "
            f"{_attempts(host)}; else {curl}; fi")
