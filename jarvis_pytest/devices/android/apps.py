"""The Android platform's apps: which the library's templates need, what the emulator image installs and sets up
(`fixtures/images/android/manifest.json`, one file for both), and whether a device has them.

The manifest pins every download of the image (the emulator, the system image, the APKs: version, URLs,
SHA-256) and lists, per app the library uses, what its first run needs before the golden snapshot (runtime
permissions, app ops, commands, the labels tapped on its first launch). `check_pins` refuses a manifest with a
download it cannot verify; `build_args` hands the pins to `android.Dockerfile`.

A template needs the apps its set-up launches (`launch` steps). On an attached device (a phone, redroid, another
emulator) a task whose app is missing is skipped, with the reason and how to install it, never failed:
`attach_skip_reason`, asked by the attach backend where a run decides what it can run.
"""

from __future__ import annotations

import json
import re
import shlex
import threading
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from jarvis_pytest.errors import ConfigError, InfrastructureError
from jarvis_pytest.paths import IMAGES_DIR


MANIFEST = IMAGES_DIR / "android" / "manifest.json"
PIN_ARGS = {"emulator": "PIN_EMULATOR", "system_image": "PIN_SYSTEM_IMAGE"}  # manifest key → build argument
APKS_ARG = "PIN_APKS"
PACKAGES_TTL = 60.0          # seconds a device's package list is trusted (a run asks once per task)
_SHA256 = re.compile(r"[0-9a-f]{64}")
_PACKAGE = re.compile(r"[A-Za-z][A-Za-z0-9_]*(\.[A-Za-z][A-Za-z0-9_]*)+")
_installed: dict[str, tuple[float, frozenset[str]]] = {}   # serial → (when read, packages)
_installed_lock = threading.Lock()


# -- the manifest ---------------------------------------------------------------------------------------------------
def load_manifest(path: Path | None = None) -> dict[str, Any]:
    """The manifest (default `MANIFEST`), its shape checked: one ConfigError naming the file, the field and the fix
    otherwise."""
    path = Path(path) if path else MANIFEST
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError(f"cannot read it: {exc.strerror}", path=path, fix="restore it from git") from None
    except json.JSONDecodeError as exc:
        raise ConfigError(f"not JSON: {exc}", path=path, fix="repair the JSON") from None
    if not isinstance(data, dict):
        raise ConfigError("not a JSON object", path=path, fix="restore it from git")
    for key in ("emulator", "system_image"):
        _download(data.get(key), path, key)
    apks = data.get("apks")
    if not isinstance(apks, list):
        raise ConfigError("missing or not a list", path=path, field="apks", fix="list the APKs the image installs")
    for i, apk in enumerate(apks):
        _download(apk, path, f"apks[{i}]")
        _package(apk.get("package"), path, f"apks[{i}].package")
        code = apk.get("version_code")
        if code is not None and (not isinstance(code, int) or isinstance(code, bool) or code < 1):
            raise ConfigError(f"{code!r} is not a versionCode", path=path, field=f"apks[{i}].version_code",
                              fix="the APK's versionCode (F-Droid names the file <package>_<versionCode>.apk), "
                                  "or null")
    for key in ("preinstalled",):
        if not isinstance(data.get(key), list):
            raise ConfigError("missing or not a list", path=path, field=key,
                              fix="list the packages of the system image the library uses")
        for i, package in enumerate(data[key]):
            _package(package, path, f"{key}[{i}]")
    runs = data.get("first_run")
    if not isinstance(runs, list):
        raise ConfigError("missing or not a list", path=path, field="first_run",
                          fix="one entry per app the library uses")
    for i, entry in enumerate(runs):
        where = f"first_run[{i}]"
        if not isinstance(entry, dict):
            raise ConfigError("not an object", path=path, field=where, fix='{"package": "...", "name": "..."}')
        _package(entry.get("package"), path, f"{where}.package")
        for key in ("grant", "appops", "commands", "tap", "not_after"):
            value = entry.get(key, [])
            if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
                raise ConfigError("not a list of non-empty strings", path=path, field=f"{where}.{key}",
                                  fix='e.g. ["android.permission.POST_NOTIFICATIONS"]')
        if entry.get("launch", True) not in (True, False):
            raise ConfigError("not true or false", path=path, field=f"{where}.launch",
                              fix="false for an app that is never launched at preparation")
    return data


def _download(entry: Any, path: Path, where: str) -> None:
    if not isinstance(entry, dict):
        raise ConfigError("missing or not an object", path=path, field=where,
                          fix='{"urls": ["https://..."], "sha256": "..."}')
    urls = entry.get("urls")
    if not isinstance(urls, list) or not urls or not all(isinstance(u, str) and u.startswith("https://")
                                                         for u in urls):
        raise ConfigError(f"{urls!r} is not a list of https URLs", path=path, field=f"{where}.urls",
                          fix="list where the file is published, https only")


def _package(value: Any, path: Path, where: str) -> None:
    if not isinstance(value, str) or not _PACKAGE.fullmatch(value):
        raise ConfigError(f"{value!r} is not an Android package name", path=path, field=where,
                          fix="e.g. net.gsantner.markor")


def downloads(manifest: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    """(manifest field, entry) of every download of the image."""
    out = [(key, manifest[key]) for key in PIN_ARGS]
    return out + [(f"apks[{i}]", apk) for i, apk in enumerate(manifest["apks"])]


def check_pins(manifest: dict[str, Any], path: Path | None = None) -> None:
    """Every download has a SHA-256 to be verified against; else one ConfigError naming the file (default
    `MANIFEST`), the field and how to fill it (nothing is downloaded without one)."""
    path = path or MANIFEST
    for where, entry in downloads(manifest):
        sha = entry.get("sha256")
        if not isinstance(sha, str) or not _SHA256.fullmatch(sha):
            shown = "missing" if sha in (None, "") else f"{sha!r}, not a SHA-256 (64 lowercase hex digits)"
            raise ConfigError(
                f"{entry.get('name') or entry.get('package') or where}: {shown}; the image build verifies every "
                "download against its SHA-256 and refuses one it cannot verify", path=path, field=f"{where}.sha256",
                fix=f"download {entry['urls'][0]}, check it against what its publisher lists, and write the output "
                    f"of `sha256sum FILE` here")


def build_args(manifest: dict[str, Any]) -> dict[str, str]:
    """The build arguments of `android.Dockerfile`: each pin as compact JSON (read there by fetch.sh), only what
    the download needs, so that a changed note does not download anything again."""
    def pin(entry: dict[str, Any]) -> dict[str, Any]:
        return {k: entry[k] for k in ("name", "package", "urls", "sha256") if k in entry}

    args = {arg: json.dumps(pin(manifest[key]), separators=(",", ":")) for key, arg in PIN_ARGS.items()}
    args[APKS_ARG] = json.dumps([pin(a) for a in manifest["apks"]], separators=(",", ":"))
    return args


def app_names(manifest: dict[str, Any] | None = None) -> dict[str, str]:
    """package → the app's name, as the manifest calls it."""
    manifest = manifest if manifest is not None else load_manifest()
    out = {e["package"]: e.get("name") or e["package"] for e in manifest["first_run"]}
    return out | {a["package"]: a.get("name") or a["package"] for a in manifest["apks"]}


# -- what a template needs, what a device has -----------------------------------------------------------------------
def packages_needed(subtask: Any) -> list[str]:
    """The packages a template or subtask launches on Android (its `launch` steps, held-back ones included),
    sorted."""
    platform = getattr(subtask, "platform", "android")
    steps = list(getattr(subtask, "config", None) or []) + list(getattr(subtask, "opens", None) or [])
    found = {step.app.split("/", 1)[0] for step in steps
             if getattr(step, "type", None) == "launch" and (step.platform or platform) == "android"}
    return sorted(found)


def parse_packages(output: str) -> frozenset[str]:
    """`pm list packages` output (`package:<name>` lines) → the names."""
    return frozenset(line.strip()[len("package:"):] for line in output.splitlines()
                     if line.strip().startswith("package:"))


def installed_packages(device: Any) -> frozenset[str]:
    """The packages installed on `device` (anything with `run`, e.g. an AdbDevice)."""
    r = device.run("pm list packages", timeout=30)
    found = parse_packages(r.stdout)
    if r.returncode != 0 or not found:
        raise InfrastructureError(f"android device: `pm list packages` failed (exit {r.returncode}): "
                                  f"{(r.stdout + r.stderr).strip()[:300]}")
    return found


def missing_apps(device_or_serial: Any, subtask: Any) -> list[str]:
    """The packages `subtask` (a template or a task's subtask) launches that the device lacks, sorted. A device is
    an adb serial or a device object with `run`."""
    device = _device(device_or_serial)
    have = installed_packages(device)
    return [p for p in packages_needed(subtask) if p not in have]


def _device(device_or_serial: Any) -> Any:
    if isinstance(device_or_serial, str):
        from jarvis_pytest.devices.android.device import AdbDevice

        return AdbDevice(device_or_serial)
    return device_or_serial


def _cached_packages(serial: str) -> frozenset[str]:
    now = time.monotonic()
    with _installed_lock:
        hit = _installed.get(serial)
        if hit and now - hit[0] < PACKAGES_TTL:
            return hit[1]
    found = installed_packages(_device(serial))
    with _installed_lock:
        _installed[serial] = (now, found)
    return found


def attach_skip_reason(serial: str | None, subtask: Any) -> str | None:
    """Why `subtask` cannot run on the attached device `serial` (an app it launches is not installed there), with
    how to install it or where else it runs; None when it can, or when the device cannot be asked now (its boot
    then reports that)."""
    needed = packages_needed(subtask)
    if not serial or not needed:
        return None
    try:
        have = _cached_packages(serial)
    except InfrastructureError:
        return None
    missing = [p for p in needed if p not in have]
    if not missing:
        return None
    return missing_reason(serial, subtask, missing)


def missing_reason(serial: str, subtask: Any, missing: Iterable[str], manifest: dict[str, Any] | None = None) -> str:
    """The skip reason for apps `missing` on device `serial`: which, and the commands that would run the task."""
    try:
        manifest = manifest if manifest is not None else load_manifest()
    except ConfigError:
        manifest = {"apks": [], "first_run": [], "preinstalled": []}
    names = app_names(manifest)
    apks = {a["package"]: a for a in manifest["apks"]}
    missing = list(missing)
    shown = ", ".join(f"{p} ({names[p]})" if p in names else p for p in missing)
    fixes = []
    for package in missing:
        apk = apks.get(package)
        if apk:
            fixes.append(f"curl -fL -o {package}.apk {apk['urls'][0]} && adb -s {shlex.quote(serial)} install -r -g "
                         f"{package}.apk")
    template = getattr(subtask, "template", None) or getattr(subtask, "id", "this template")
    how = "; ".join(fixes) + ("; " if fixes else "")
    return (f"{template} needs {shown}, which the attached device {serial} does not have (`pm list packages`); "
            f"to run it: {how}or run it on the prepared emulator image with --android-backend emulator "
            f"(it has every app the Android library uses)")
