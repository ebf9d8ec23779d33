"""The small Linux guest that proves the runner under TCG (`fixtures/images/vm-guest/`): its machine profile and
its golden, prepared once per machine and guest image in `$JARVIS_VM_CACHE` (default `~/.cache/jarvis/vm`), in a
folder keyed by the image's content hash and the commands run before its snapshot.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tarfile
import tempfile
from pathlib import Path
from typing import Any, Sequence

from jarvis_pytest.devices.vm import golden as golden_files
from jarvis_pytest.devices.vm.prepare import prepare_snapshot
from jarvis_pytest.devices.vm.profile import Profile
from jarvis_pytest.errors import ConfigError, InfrastructureError

GUEST_IMAGE = "vm-guest"
CACHE_ENV = "JARVIS_VM_CACHE"
PROFILE = Profile(
    name="linux-test", machine="q35", accel="tcg", cpu="qemu64", smp="1", memory_mb=256,
    kernel="vmlinuz", initrd="initrd.img",
    append="console=ttyS0 root=/dev/vda rw init=/sbin/jarvis-init panic=-1 net.ifnames=0",
    extra=("-no-reboot",),  # a guest that panics ends QEMU (and the runner says so) instead of rebooting
)


def cache_dir() -> Path:
    return Path(os.environ.get(CACHE_ENV) or Path.home() / ".cache" / "jarvis" / "vm")


def golden_dir(image_hash: str, commands: Sequence[str]) -> Path:
    key = hashlib.sha256(json.dumps([image_hash, list(commands)]).encode()).hexdigest()[:16]
    return cache_dir() / f"{PROFILE.name}-{key}"


def _extract(docker: Any, image: str, target: Path) -> None:
    """The image's /guest files (disk, kernel, initrd) into `target`, through a created (never started)
    container."""
    container = docker.containers.create(image, command=["true"])
    with tempfile.TemporaryFile(dir=target) as archive:
        try:
            stream, _ = container.get_archive("/guest/.")
            for chunk in stream:
                archive.write(chunk)
        finally:
            container.remove(force=True)
        archive.seek(0)
        with tarfile.open(fileobj=archive) as tar:
            for member in tar.getmembers():
                name = Path(member.name).name
                if member.isfile() and name in PROFILE.files():
                    with tar.extractfile(member) as src, (target / name).open("wb") as dst:
                        shutil.copyfileobj(src, dst, 1 << 20)
    missing = [f for f in PROFILE.files() if not (target / f).is_file()]
    if missing:
        raise InfrastructureError(f"image {image} lacks /guest/{missing[0]}: rebuild it (`jarvis images build "
                                  f"--only {GUEST_IMAGE}`)")


def ensure_golden(docker: Any = None, commands: Sequence[str] = ()) -> tuple[Path, golden_files.Record, bool]:
    """The test guest's golden for the current `vm-guest` image, prepared (with `commands` run before its
    snapshot) unless a ready one is cached; (folder, record, whether it was prepared now). Goldens of other
    images or commands are removed. One preparer at a time (a lock in the cache folder)."""
    from filelock import FileLock

    from jarvis_pytest.infra.engine import client
    from jarvis_pytest.infra.images import HASH_LABEL, image_tag

    docker = docker or client(timeout=600)
    tag = image_tag(GUEST_IMAGE)
    try:
        image = docker.images.get(tag)
    except Exception as exc:
        raise InfrastructureError(f"image {tag} is not built ({exc.__class__.__name__}): run `jarvis images build "
                                  f"--only {GUEST_IMAGE}`") from None
    image_hash = (image.labels or {}).get(HASH_LABEL, image.id)
    folder = golden_dir(image_hash, commands)
    folder.parent.mkdir(parents=True, exist_ok=True)
    with FileLock(str(folder.parent / f"{folder.name}.lock")):
        try:
            return folder, golden_files.check(folder, PROFILE), False
        except ConfigError:
            pass  # not prepared (or damaged): prepare it
        for old in folder.parent.glob(f"{PROFILE.name}-*"):
            if old.is_dir() and old != folder:
                shutil.rmtree(old, ignore_errors=True)
        if folder.exists():
            shutil.rmtree(folder)
        folder.mkdir()
        _extract(docker, tag, folder)
        record = prepare_snapshot(folder, PROFILE, commands=commands, docker=docker,
                                  source={"image": tag, "id": image.id, "hash": image_hash})
        return folder, record, True
