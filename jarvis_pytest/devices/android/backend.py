"""The Android backends: `emulator` (Google's emulator in a container with /dev/kvm) and `attach` (any adb serial).

emulator: one container per task from the prepared image (`image.py`; option `android.image`, default
`jarvis/android:latest`, or $JARVIS_ANDROID_IMAGE), running API 33 google_apis x86_64 headless (`-no-window -no-audio
-no-boot-anim -gpu swiftshader_indirect`) from its golden snapshot with `-read-only -no-snapshot-save`. The
emulator's adb port listens on the container's loopback; `socat` offers it on port 5556, which is published on
127.0.0.1 only, and our adb server `adb connect`s to it. The container joins the task network; the guest's
traffic leaves through the emulator's user-mode NAT (10.0.2.x) from the container, so it reaches exactly what the
container reaches: the drive as `transfer:5244` (the guest's DNS 10.0.2.3 forwards to the container's resolver),
and as `10.0.2.2:5244` (the container's loopback, where `socat` relays to `transfer:5244`).

attach: a device the user names by serial (option `android.serial`, or $JARVIS_ANDROID_SERIAL): a phone, redroid,
an emulator already running. Nothing is created or removed; a TCP serial (`host:port`) is `adb connect`ed; one
task at a time holds the device (a lock per serial, across processes); the task's set-up resets the apps it uses.
"""

from __future__ import annotations

import fcntl
import os
import re
import tempfile
import threading
import time
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from jarvis_pytest.devices.android.adb import Adb, adb_binary, is_tcp_serial
from jarvis_pytest.devices.android.device import AdbDevice
from jarvis_pytest.devices.android.image import IMAGE_NAME, image_state, kvm_problem
from jarvis_pytest.devices.backend import Backend, BackendOption, token
from jarvis_pytest.errors import InfrastructureError

if TYPE_CHECKING:
    from jarvis_pytest.infra.containers import BootedDevice, BootRequest

SERIAL_ENV = "JARVIS_ANDROID_SERIAL"
IMAGE_ENV = "JARVIS_ANDROID_IMAGE"
ADB_FORWARD_PORT = 5556          # in the emulator container: socat → the emulator's adb port 127.0.0.1:5555
ATTACH_WAIT = 7200.0             # seconds a task waits for an attached device another task holds
DEFAULT_IMAGE = f"jarvis/{IMAGE_NAME}:latest"  # `infra.images.image_tag(IMAGE_NAME)`
SERIAL_HINT = "--backend-option android.serial=SERIAL (or --android-serial SERIAL)"
_held: dict[str, int] = {}       # serial → fd of its lock file, while a task holds the device
_held_lock = threading.Lock()


def serial_of(url: str) -> str:
    """The adb serial of a device URL: `adb://<serial>`, or `http://127.0.0.1:<port>` (a published port)."""
    if url.startswith("adb://"):
        return url[len("adb://"):]
    m = re.fullmatch(r"https?://([^/:]+):(\d+)/?", url)
    return f"{m.group(1)}:{m.group(2)}" if m else url


def connect(url: str) -> AdbDevice:
    return AdbDevice(serial_of(url))


def wait_ready(url: str, timeout: float) -> None:
    """One readiness check of at most ~`timeout` s (called repeatedly while the container is watched): the
    device is online for adb and Android reports `sys.boot_completed=1`; else InfrastructureError."""
    serial = serial_of(url)
    adb = Adb(serial=serial)
    budget = max(2.0, timeout)
    if adb.state(timeout=budget) != "device":
        if not is_tcp_serial(serial):
            raise InfrastructureError(f"android device {serial} is not online")
        adb.connect(serial, timeout=budget)
        if adb.state(timeout=budget) != "device":
            raise InfrastructureError(f"android device {serial} connected but not online yet")
    booted = adb.shell("getprop sys.boot_completed", timeout=budget).stdout.strip()
    if booted != "1":
        raise InfrastructureError(f"android device {serial} is still booting (sys.boot_completed={booted!r})")


def _adb_problem() -> str | None:
    try:
        adb_binary()
    except InfrastructureError as exc:
        return str(exc)
    return None


def emulator_unavailable(ref: str = DEFAULT_IMAGE) -> str | None:
    """Why the emulator backend with image `ref` cannot run here (None: it can)."""
    problem = _adb_problem() or kvm_problem()
    if problem:
        return problem
    try:
        from jarvis_pytest.infra.engine import client

        missing = image_state(client(timeout=10), ref)
    except InfrastructureError as exc:
        return str(exc)
    if missing:
        return (f"{missing}: no /dev/kvm-capable Android emulator image prepared; run `jarvis images build --only "
                f"android` on a machine with KVM and internet (dl.google.com), or name one with --backend-option android.image=IMAGE")
    return None


def attach_unavailable(serial: str | None = None) -> str | None:
    """Why the attach backend with `serial` cannot run here (None: it can)."""
    problem = _adb_problem()
    if problem:
        return problem
    if not serial:
        return (f"no adb serial given: {SERIAL_HINT} (a phone, redroid or a running emulator; `adb devices` lists "
                "them; host:port serials are `adb connect`ed)")
    return None


def describe(device: AdbDevice) -> str:
    """What the device is, as Android says: e.g. `Android 13 (API 33), sdk_gphone64_x86_64, build
    google/sdk_gphone64_x86_64/emu64xa:13/TE1A.220922.034/10940250:userdebug/dev-keys` (its build fingerprint, where
    it has one)."""
    out = device.run("getprop ro.build.version.release; getprop ro.build.version.sdk; getprop ro.product.model; "
                     "getprop ro.build.fingerprint", timeout=20).stdout.splitlines()
    release, sdk, model, fingerprint = (out + ["", "", "", ""])[:4]
    text = f"Android {release.strip() or '?'} (API {sdk.strip() or '?'}), {model.strip() or 'unknown model'}"
    return text + (f", build {fingerprint.strip()}" if fingerprint.strip() else "")


class EmulatorBackend(Backend):
    """The emulator in a container of the prepared image (the default container boot, then adb)."""

    def boot(self, request: "BootRequest") -> "BootedDevice":
        booted = super().boot(request)          # container on the task network, waited for with `wait_ready`
        serial = serial_of(booted.url)
        AdbDevice(serial).prepare()
        booted.url = f"adb://{serial}"
        return booted

    def close(self, booted: "BootedDevice") -> list[str]:
        try:
            Adb().disconnect(serial_of(booted.url), timeout=5)
        except InfrastructureError:
            pass
        return super().close(booted)


class AttachBackend(Backend):
    """A device the user names by serial: nothing to create or remove; one task at a time."""

    def subtask_unavailable(self, sub) -> str | None:
        """Why `sub` cannot run on the attached device: an app it launches is not installed there (`apps.py`)."""
        from jarvis_pytest.devices.android.apps import attach_skip_reason

        return attach_skip_reason(self.values.get("serial"), sub)

    def boot(self, request: "BootRequest") -> "BootedDevice":
        from jarvis_pytest.infra.containers import BootedDevice

        serial = self.values.get("serial")
        if not serial:
            raise InfrastructureError(attach_unavailable() or "no adb serial given")
        _acquire(serial, request.stop, max(request.ready_timeout, ATTACH_WAIT))
        try:
            adb = Adb(serial=serial)
            adb.wait_online(request.ready_timeout)
            deadline = time.monotonic() + request.ready_timeout
            while adb.shell("getprop sys.boot_completed", timeout=20).stdout.strip() != "1":
                if time.monotonic() > deadline:
                    raise InfrastructureError(f"android device {serial} did not finish booting within "
                                              f"{request.ready_timeout:.0f} s")
                time.sleep(1)
            device = AdbDevice(serial)
            device.prepare()
            device.go_home()
        except BaseException:
            _release(serial)
            raise
        return BootedDevice(container=None, url=f"adb://{serial}", backend=self)

    def close(self, booted: "BootedDevice") -> list[str]:
        _release(serial_of(booted.url))
        return []


def _lock_path(serial: str) -> str:
    return os.path.join(tempfile.gettempdir(), "jarvis-android-" + re.sub(r"[^A-Za-z0-9_.-]", "_", serial) + ".lock")


def _acquire(serial: str, stop: threading.Event, timeout: float) -> None:
    """Hold the device for this task: an exclusive flock on a file of its own open (so two tasks of one process
    exclude each other too); waits while another task holds it."""
    fd = os.open(_lock_path(serial), os.O_CREAT | os.O_RDWR, 0o666)
    deadline = time.monotonic() + timeout
    while True:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            break
        except BlockingIOError:
            if stop.is_set() or time.monotonic() > deadline:
                os.close(fd)
                raise InfrastructureError(f"android device {serial} stays busy with another task "
                                          f"(lock {_lock_path(serial)})") from None
            time.sleep(0.5)
    with _held_lock:
        _held[serial] = fd


def _release(serial: str) -> None:
    with _held_lock:
        fd = _held.pop(serial, None)
    if fd is not None:
        try:
            fcntl.flock(fd, fcntl.LOCK_UN)
        finally:
            os.close(fd)


def _emulator(values: Mapping[str, Any]) -> dict[str, Any]:
    image = values["image"]
    return {"image": image, "unavailable": lambda: emulator_unavailable(image)}


def _attach(values: Mapping[str, Any]) -> dict[str, Any]:
    serial = values["serial"]
    return {"unavailable": lambda: attach_unavailable(serial)}


EMULATOR = EmulatorBackend(
    platform="android",
    name="emulator",
    image=DEFAULT_IMAGE,
    connect=connect,
    wait_ready=wait_ready,
    port=ADB_FORWARD_PORT,
    container_options={"devices": ["/dev/kvm:/dev/kvm:rwm"], "shm_size": "512m"},
    image_kind="prepared",
    ready_timeout=240.0,          # 2.5-4 s from the snapshot; a cold boot (snapshot refused by this CPU) ~60 s
    memory="6g",
    booted_memory_mb=2048 + 512,  # the AVD's RAM (hw.ramSize), and the emulator
    cpus=None,
    how_to_run=("on a machine with /dev/kvm and internet: JARVIS_ANDROID_DOWNLOAD=1 jarvis images build --only "
                "android, then run with --android-backend emulator"),
    describe=describe,
    options=(BackendOption("image", "the prepared emulator image to run (a local tag or a registry reference)",
                           default=DEFAULT_IMAGE, parse=token, env=IMAGE_ENV, example="myregistry/android:33"),),
    derive=_emulator,
)

ATTACH = AttachBackend(
    platform="android",
    name="attach",
    image="",
    connect=connect,
    wait_ready=wait_ready,
    port=0,
    image_kind="prepared",
    ready_timeout=120.0,
    memory=None,
    booted_memory_mb=0,  # the device exists already: nothing boots here
    cpus=None,
    how_to_run=f"connect a device (`adb devices` lists it), then run with --android-backend attach {SERIAL_HINT}",
    describe=describe,
    options=(BackendOption("serial", "the adb serial of the device to use (`adb devices` lists them; host:port "
                           "serials are connected)", parse=token, env=SERIAL_ENV, example="emulator-5554"),),
    derive=_attach,
)
