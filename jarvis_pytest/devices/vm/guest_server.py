"""A minimal control server for a Linux guest without a desktop (the VM runner's test guest): the part of the
protocol of `devices/desktop.py` such a guest can serve, so `DesktopDevice` drives it unchanged.

  GET  /health                     `desktop` true as soon as the server answers (there is no desktop to wait for)
  POST /run       RunRequest       RunResponse (returncode 124 on timeout), as root
  PUT  /files?path=/abs            written (parents made)
  GET  /files?path=/abs            application/octet-stream
  GET  /exists?path=/abs           PathInfo

The endpoints but /health are the Ubuntu server's own (`ubuntu/server/app.py`, whose imports are the standard
library's until a screen or input is used): it runs on the guest's Debian python3.
`python3 -m jarvis_pytest.devices.vm.guest_server --port 5000`.
"""

from __future__ import annotations

import argparse

from jarvis_pytest.devices.control_http import ControlServer
from jarvis_pytest.devices.ubuntu.server.app import Handler as UbuntuHandler


class Handler(UbuntuHandler):
    server_version = "jarvis-vm-guest/1"

    def health(self) -> None:
        self._health_wait()  # a bad `wait` is still a 400, as on every platform
        self._json(200, {"ok": True, "desktop": True, "details": {"ready": True}})


Handler.routes = {
    ("GET", "/health"): Handler.health,
    ("POST", "/run"): Handler.run,
    ("PUT", "/files"): Handler.put_file,
    ("GET", "/files"): Handler.get_file,
    ("GET", "/exists"): Handler.exists,
}


def main() -> None:
    parser = argparse.ArgumentParser(prog="jarvis-vm-guest-server")
    parser.add_argument("--host", default="0.0.0.0", help="inside the guest; the runner forwards one port to it")
    parser.add_argument("--port", type=int, default=5000)
    args = parser.parse_args()
    ControlServer((args.host, args.port), Handler).serve_forever()


if __name__ == "__main__":
    main()
