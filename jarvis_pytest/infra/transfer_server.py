"""Which server runs a task's transfer drive: its image, container options, host-side client and first-start setup.

Two flavours keep the paper's drive (port 5244, user `agent` / `agentPassword`, folder `/data`):

- ``copyparty`` (default): the offline image `jarvis/transfer` built from `fixtures/images/transfer/`.
- ``alist``: an AList or OpenList image pulled from a registry (``JARVIS_ALIST_IMAGE``, default
  ``xhofe/alist:latest``; ``openlistteam/openlist:latest`` speaks the same API). At first start its admin
  creates the `agent` user and a local storage holding `/data`. Not testable on this machine (no registry).

Choose with ``Lifecycle(..., transfer="alist")`` or the environment variable ``JARVIS_TRANSFER``.
"""

from __future__ import annotations

import json
import os
import secrets
from dataclasses import dataclass, field
from typing import Any, Callable

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.infra.images import image_tag
from jarvis_pytest.infra.transfer import AlistClient, CopypartyClient, TransferClient

TRANSFER_ALIAS = "transfer"        # the drive's name on a task's Docker network
TRANSFER_PORT = 5244               # the paper's AList port
TRANSFER_USER = "agent"
TRANSFER_PASSWORD = "agentPassword"
TRANSFER_FOLDER = "/data"          # the folder agents use on the drive
COPYPARTY_DRIVE_ROOT = "/srv/drive"  # copyparty's volume root inside its container (the drive's `/`)
ALIST_DRIVE_ROOT = "/srv/drive"       # a tmpfs inside the AList container: the drive lives as long as the task
ALIST_PERMISSIONS = 0b11_1111_1011    # AList permission bits 0-9 except 2 (offline downloads): read, write, webdav


@dataclass(frozen=True)
class TransferServer:
    """One flavour of transfer drive."""

    flavour: str
    image: str                                              # a full image reference
    client: Callable[[str, str, str], TransferClient]       # (base URL, user, password) → client
    container_options: dict[str, Any] = field(default_factory=dict)
    provision: Callable[[str], None] | None = None          # base URL → create user and folder; after ready
    built_here: bool = True                                 # built by `jarvis images build` (else pulled)
    port: int = TRANSFER_PORT
    storage: str = COPYPARTY_DRIVE_ROOT   # the drive's root inside its container (`/data` is a folder in it)
    # sent to the drive's PID 1 between tasks: it starts a fresh server on a wiped drive and prints the server's
    # `generation N` on standard output, alone there (`fixtures/images/transfer/drive.py`). None: the flavour
    # cannot be renewed, and each task gets a new container
    renew_signal: str | None = None
    # sent to the drive's PID 1 for a mark in the drive's ledger of what it received and served
    # (`fixtures/images/transfer/ledger.py`, read by `infra/drive_ledger.py`). None: the flavour keeps no ledger
    mark_signal: str | None = None
    booted_memory_mb: int = 64            # about what a started drive holds (copyparty: 37 MB idle)


def _provision_alist(base_url: str, admin_password: str) -> None:
    """As admin: a local storage at `/`, the folder `/data` and the user `agent` with read/write rights."""
    admin = AlistClient(base_url, "admin", admin_password)
    try:
        admin.api("POST", "/api/admin/storage/create", "creating the local storage", json={
            "mount_path": "/", "driver": "Local", "order": 0,
            "addition": json.dumps({"root_folder_path": ALIST_DRIVE_ROOT})})
        admin.api("POST", "/api/admin/user/create", f"creating user {TRANSFER_USER}", json={
            "username": TRANSFER_USER, "password": TRANSFER_PASSWORD, "base_path": "/",
            "permission": ALIST_PERMISSIONS, "disabled": False})
        admin.mkdir(TRANSFER_FOLDER)
    finally:
        admin.close()


def _alist() -> TransferServer:
    admin_password = secrets.token_urlsafe(12)
    return TransferServer(
        flavour="alist", image=os.environ.get("JARVIS_ALIST_IMAGE", "xhofe/alist:latest"), client=AlistClient,
        container_options={"environment": {"ALIST_ADMIN_PASSWORD": admin_password,
                                           "OPENLIST_ADMIN_PASSWORD": admin_password},
                           "tmpfs": {ALIST_DRIVE_ROOT: "mode=0777"}},
        provision=lambda url: _provision_alist(url, admin_password), built_here=False, storage=ALIST_DRIVE_ROOT)


def _copyparty() -> TransferServer:
    return TransferServer(flavour="copyparty", image=image_tag("transfer"), client=CopypartyClient,
                          renew_signal="SIGUSR1", mark_signal="SIGUSR2")


def drive_said(container: Any) -> tuple[int, int]:
    """(generation, mark) of the drive's last word: `generation N` → (N, 0), the ledger's `mark N M` → (N, M);
    (0, 0) before any. Read from the container's standard output, which the drive's own users cannot write to
    (its servers write to stderr)."""
    last = container.logs(stdout=True, stderr=False, tail=1).decode(errors="replace").split()
    if not all(word.isdigit() for word in last[1:]):
        return 0, 0
    if len(last) == 2 and last[0] == "generation":
        return int(last[1]), 0
    if len(last) == 3 and last[0] == "mark":
        return int(last[1]), int(last[2])
    return 0, 0


def served_generation(container: Any) -> int:
    """How many servers the drive's PID 1 has started (0: none yet); see `drive_said`."""
    return drive_said(container)[0]


FLAVOURS: dict[str, Callable[[], TransferServer]] = {"copyparty": _copyparty, "alist": _alist}


def transfer_server(flavour: str | None = None) -> TransferServer:
    """The server of `flavour` (default: `$JARVIS_TRANSFER`, else copyparty)."""
    name = flavour or os.environ.get("JARVIS_TRANSFER") or "copyparty"
    if name not in FLAVOURS:
        raise ConfigError(f"unknown transfer drive flavour {name!r}", field="JARVIS_TRANSFER",
                          fix=f"choose one of {sorted(FLAVOURS)}")
    return FLAVOURS[name]()
