"""The Android emulator image and the apps it must have, without Android (none can run on this machine: no binder,
no system image, no KVM image): the manifest's pins and their checks, `fetch.sh` downloading (file:// URLs, real
curl and sha256sum), the Dockerfile and AVD against the manifest, `entrypoint.sh` run for real in bash against a
stand-in `emulator` and `adb` that keep a device's state (apps, first-run screens as uiautomator XML, the focused
window), and the attach backend skipping a template whose app the device lacks.

What the stand-ins cannot tell: how the real emulator, Android and the apps behave; that is the first-run checklist
of fixtures/images/android/README.md, on a machine with /dev/kvm.
"""

from __future__ import annotations

import copy
import json
import os
import re
import shutil
import subprocess
import sys
import textwrap
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from jarvis_pytest.devices.android import apps
from jarvis_pytest.devices.android import image as I
from jarvis_pytest.devices.android import outputs
from jarvis_pytest.errors import ConfigError, InfrastructureError

REPO = Path(__file__).resolve().parents[1]
FOLDER = REPO / "fixtures" / "images" / "android"
ENTRY = FOLDER / "entrypoint.sh"
DATA = Path(__file__).parent / "data" / "android"
MANIFEST = apps.load_manifest()
LAUNCHER = "com.google.android.apps.nexuslauncher/com.android.launcher3.Launcher"


# -- the manifest ----------------------------------------------------------------------------------------------------
def test_every_download_is_pinned_to_one_version_and_its_sha256():
    apps.check_pins(MANIFEST)
    emulator, system = MANIFEST["emulator"], MANIFEST["system_image"]
    assert (emulator["version"], emulator["build"]) == ("33.1.22", "11078245")
    assert emulator["urls"] == [f"https://dl.google.com/android/repository/emulator-linux_x64-{emulator['build']}.zip"]
    assert (system["package"], system["revision"]) == ("system-images;android-33;google_apis;x86_64", "10")
    assert system["urls"] == ["https://dl.google.com/android/repository/sys-img/google_apis/x86_64-33_r10.zip"]
    apks = {a["package"]: a for a in MANIFEST["apks"]}
    assert set(apks) == {"com.android.adbkeyboard", "net.gsantner.markor", "ws.xsoh.etar"}
    for package in ("net.gsantner.markor", "ws.xsoh.etar"):   # F-Droid names a build by its versionCode
        code = apks[package]["version_code"]
        assert isinstance(code, int) and apks[package]["urls"] == [
            f"https://f-droid.org/repo/{package}_{code}.apk", f"https://f-droid.org/archive/{package}_{code}.apk"]
    commit = re.search(r"/([0-9a-f]{40})/", apks["com.android.adbkeyboard"]["urls"][0])
    assert commit and all(commit.group(1) in u for u in apks["com.android.adbkeyboard"]["urls"])  # a commit, not a tag
    for where, entry in apps.downloads(MANIFEST):
        assert re.fullmatch(r"[0-9a-f]{64}", entry["sha256"]), where
        assert not any(w in u for u in entry["urls"] for w in ("latest", "/master/", "/main/")), where


@pytest.mark.parametrize("field", ["emulator", "system_image", "apks[1]"])
@pytest.mark.parametrize("value", [None, "", "3F9F", "sha256-P58mDcPjKhKBy4gD7qb5Ju74l1efaKXTX5IlI5dLhLk="])
def test_a_download_without_its_sha256_stops_the_build_naming_the_field(tmp_path, monkeypatch, field, value):
    data = copy.deepcopy(MANIFEST)
    entry = data["apks"][1] if field == "apks[1]" else data[field]
    entry["sha256"] = value
    path = tmp_path / "manifest.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ConfigError) as err:
        apps.check_pins(apps.load_manifest(path), path)
    assert err.value.field == f"{field}.sha256" and err.value.path == str(path)
    assert "sha256sum" in err.value.fix and entry["urls"][0] in err.value.fix
    # the build stops on it before anything else: no Docker, no download, whatever the machine has
    monkeypatch.setattr(apps, "MANIFEST", path)
    monkeypatch.setattr(I, "build_blocker", lambda: pytest.fail("the machine was asked before the pins"))
    with pytest.raises(ConfigError, match=re.escape(f"{path}: field '{field}.sha256'")):
        I.build()


@pytest.mark.parametrize("change, field", [
    (lambda d: d["emulator"].update(urls=["http://dl.google.com/x.zip"]), "emulator.urls"),
    (lambda d: d["system_image"].pop("urls"), "system_image.urls"),
    (lambda d: d["apks"][0].update(package="ADB Keyboard"), "apks[0].package"),
    (lambda d: d["apks"][1].update(version_code="163"), "apks[1].version_code"),
    (lambda d: d.update(apks={}), "apks"),
    (lambda d: d["first_run"][0].update(tap="NEXT"), "first_run[0].tap"),
    (lambda d: d["first_run"][2].update(launch="no"), "first_run[2].launch"),
    (lambda d: d.pop("preinstalled"), "preinstalled"),
])
def test_a_bad_manifest_is_one_clear_error(tmp_path, change, field):
    data = copy.deepcopy(MANIFEST)
    change(data)
    path = tmp_path / "manifest.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ConfigError) as err:
        apps.load_manifest(path)
    assert err.value.field == field and err.value.fix and str(path) in str(err.value)
    path.write_text("{not json")
    with pytest.raises(ConfigError, match="not JSON"):
        apps.load_manifest(path)


def test_every_app_the_library_launches_is_on_the_image_and_set_up_before_the_snapshot():
    """Each package a template launches is in the system image or installed from the manifest, and has a first-run
    entry; each installed app is launched by some template (or is the IME)."""
    from jarvis_pytest.tasks.model import TaskTemplate

    needed: dict[str, list[str]] = {}
    for path in sorted((REPO / "tasks" / "android").glob("*.json")):
        tpl = TaskTemplate.model_validate(json.loads(path.read_text()))
        for package in apps.packages_needed(tpl):
            needed.setdefault(package, []).append(tpl.id)
    installed = {a["package"] for a in MANIFEST["apks"]}
    set_up = {e["package"] for e in MANIFEST["first_run"]}
    assert not set(needed) - set(MANIFEST["preinstalled"]) - installed, "launched but not on the image"
    assert not set(needed) - set_up, "launched but its first run is not set up"
    assert installed - set(needed) == {"com.android.adbkeyboard"}
    assert needed["net.gsantner.markor"] and needed["ws.xsoh.etar"] and needed["com.android.camera2"]
    assert len([p for t in needed.values() for p in t]) >= 20


# -- fetch.sh: downloads kept only with their pinned bytes --------------------------------------------------------------
def _fetch(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["bash", str(FOLDER / "fetch.sh"), *args], capture_output=True, text=True, timeout=60)


def test_fetch_keeps_a_file_only_with_its_pinned_sha256(tmp_path):
    good, bad = tmp_path / "good.zip", tmp_path / "bad.zip"
    good.write_bytes(b"the pinned bytes")
    bad.write_bytes(b"other bytes")
    import hashlib

    sha = hashlib.sha256(good.read_bytes()).hexdigest()
    dest = tmp_path / "out" / "emulator.zip"
    dest.parent.mkdir()
    pin = {"name": "Android Emulator", "urls": [f"file://{bad}", f"file://{tmp_path}/gone.zip", f"file://{good}"],
           "sha256": sha}
    r = _fetch("one", json.dumps(pin), str(dest))
    assert r.returncode == 0, r.stderr
    assert dest.read_bytes() == good.read_bytes() and f"from file://{good}" in r.stdout
    assert not list(dest.parent.glob("*.part"))
    dest.unlink()
    pin["urls"] = [f"file://{bad}", f"file://{tmp_path}/gone.zip"]
    r = _fetch("one", json.dumps(pin), str(dest))
    assert r.returncode == 1 and not dest.exists()
    assert f"file://{bad}: sha256 {hashlib.sha256(b'other bytes').hexdigest()}, not the pinned one" in r.stderr
    assert f"file://{tmp_path}/gone.zip: the download failed" in r.stderr
    for sha in (None, "", "abc"):
        r = _fetch("one", json.dumps({"name": "Markor", "urls": [f"file://{good}"], "sha256": sha}), str(dest))
        assert r.returncode == 2 and not dest.exists()
        assert "manifest.json: Markor: field 'sha256'" in r.stderr and "sha256sum FILE" in r.stderr


def test_fetch_apks_names_each_file_by_its_package(tmp_path):
    import hashlib

    pins = []
    for package in ("net.gsantner.markor", "ws.xsoh.etar"):
        src = tmp_path / f"{package}_1.apk"
        src.write_bytes(package.encode())
        pins.append({"package": package, "urls": [f"file://{src}"], "sha256": hashlib.sha256(src.read_bytes()).hexdigest()})
    r = _fetch("apks", json.dumps(pins), str(tmp_path / "apks"))
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in (tmp_path / "apks").iterdir()) == ["net.gsantner.markor.apk", "ws.xsoh.etar.apk"]
    pins[1]["package"] = "../../etc/passwd"
    r = _fetch("apks", json.dumps(pins), str(tmp_path / "apks2"))
    assert r.returncode == 2 and "apks[1]: field 'package'" in r.stderr


# -- the Dockerfile and the AVD agree with the manifest -------------------------------------------------------------
def test_the_image_is_made_only_from_pinned_files():
    docker = (FOLDER / I.DOCKERFILE).read_text()
    lines = [line for line in docker.splitlines() if not line.lstrip().startswith("#")]
    code = "\n".join(lines)
    assert "sdkmanager" not in code and "avdmanager" not in code   # they install whatever is newest
    declared = set(re.findall(r"^ARG (\w+)", code, re.M)) - {"BASE"}
    assert declared == set(apps.build_args(MANIFEST))
    for arg in declared:   # each pin is declared just before the one step that uses it (the cache is per file)
        block = code.split(f"ARG {arg}\n", 1)[1].split("\nARG ", 1)[0]
        assert re.search(rf'^RUN /opt/jarvis/fetch (one|apks) "\${arg}"', block, re.M), arg
    assert "curl" not in code.split("COPY fetch.sh", 1)[1].replace("/opt/jarvis/fetch", "")  # no other download
    config = dict(line.split("=", 1) for line in (FOLDER / "avd" / "config.ini").read_text().splitlines() if "=" in line)
    assert config["hw.camera.back"] == "emulated"             # the camera template takes a photo
    sysdir = config["image.sysdir.1"].rstrip("/")
    assert f"unzip -q /tmp/system-image.zip -d /opt/android-sdk/{sysdir.rsplit('/', 1)[0]}" in code
    assert (config["abi.type"], config["tag.id"]) == tuple(MANIFEST["system_image"]["package"].split(";")[3:1:-1])
    assert "COPY avd/config.ini /root/.android/avd/jarvis.avd/config.ini" in code
    ini = (FOLDER / "avd" / "jarvis.ini").read_text()
    assert "path=/root/.android/avd/jarvis.avd" in ini and "target=android-33" in ini
    entry = ENTRY.read_text()
    assert "-camera-back emulated" in entry and "-camera-back none" not in entry


def test_the_build_hands_the_pins_to_docker(monkeypatch):
    """`image.build` passes every pin as its build argument (what fetch.sh verifies) and says each download."""
    from jarvis_pytest.infra import images

    seen = {}

    class Api:
        def build(self, **kwargs):
            seen.update(kwargs)
            return iter([{"stream": "Step 5/20 : RUN /opt/jarvis/fetch one\n"},
                         {"stream": "fetch: Android Emulator from https://dl.google.com/x (sha256 ...)\n"}])

    class Client:
        api = Api()

    said = []
    monkeypatch.setattr(I, "build_blocker", lambda: None)
    monkeypatch.setattr(images, "ensure_base", lambda client: "jarvis/base:bookworm")
    monkeypatch.setattr(images, "_progress", said.append)
    monkeypatch.setattr("jarvis_pytest.infra.engine.client", lambda timeout=0: Client())
    monkeypatch.setattr(I, "prepare", lambda client, tag: tag)
    assert I.build() == images.image_tag("android")
    args = seen["buildargs"]
    assert args["BASE"] == "jarvis/base:bookworm" and seen["dockerfile"] == I.DOCKERFILE
    assert json.loads(args["PIN_EMULATOR"])["sha256"] == MANIFEST["emulator"]["sha256"]
    assert json.loads(args["PIN_SYSTEM_IMAGE"])["urls"] == MANIFEST["system_image"]["urls"]
    assert [a["sha256"] for a in json.loads(args["PIN_APKS"])] == [a["sha256"] for a in MANIFEST["apks"]]
    assert "source" not in args["PIN_APKS"]   # a changed note downloads nothing again
    assert any(s.startswith("android: fetch: Android Emulator") for s in said), said


# -- entrypoint.sh in a real shell, against a stand-in emulator and adb ------------------------------------------
ADB_STUB = r'''
import json, os, sys, time
from xml.sax.saxutils import quoteattr
state_path = os.environ["STUB_STATE"]
state = json.load(open(state_path))
args = sys.argv[1:]
with open(os.environ["STUB_LOG"], "a") as log:
    log.write(json.dumps(args) + "\n")
def save():
    json.dump(state, open(state_path, "w"))
def node(label, bounds):
    text = quoteattr(label, {"'": "&apos;"})
    return (f'<node index="0" text={text} resource-id="" class="android.widget.Button" '
            f'package="{state["current"].split("/")[0]}" content-desc="" checkable="false" checked="false" '
            f'clickable="true" enabled="true" bounds="{bounds}" />')
cmd, rest = args[0], args[1:]
if cmd == "wait-for-device":
    sys.exit(0)
if cmd == "install":
    package = os.path.basename(rest[-1])[:-4]
    state["installed"][package] = state["codes"].get(package, 1)
    save(); print("Success"); sys.exit(0)
if cmd == "exec-out":
    labels = state["screens"].get(state["current"].split("/")[0], [])
    body = node(labels[0], "[100,200][300,260]") if labels else ""
    print('<?xml version="1.0" encoding="UTF-8" standalone="yes"?><hierarchy rotation="0">'
          '<node index="0" text="" resource-id="" class="android.widget.FrameLayout" package="x" content-desc="" '
          f'bounds="[0,0][1080,2400]">{body}</node></hierarchy>', end="")
    sys.exit(0)
if cmd == "emu":
    if rest[:3] == ["avd", "snapshot", "save"]:
        os.makedirs(os.path.join(os.environ["AVD_DIR"], "snapshots", rest[3]))
    if rest == ["kill"]:
        os.kill(int(open(os.environ["STUB_EMU_PID"]).read()), 15)
    sys.exit(0)
if cmd != "shell":
    sys.exit(0)
line = " ".join(rest)
package = state["current"].split("/")[0]
if line == "getprop sys.boot_completed":
    print("1")
elif line.startswith("dumpsys package "):
    code = state["installed"].get(rest[-1])
    print(f"    versionCode={code} minSdk=23 targetSdk=33" if code else "")
elif line.startswith("pm grant "):
    sys.exit(0 if rest[-1] not in state["ungrantable"] else 255)
elif line.startswith("monkey -p "):
    pkg = rest[2]
    if pkg not in state["installed"] and pkg not in state["preinstalled"]:
        sys.exit(252)
    intro = state["intro"].get(pkg) if state["screens"].get(pkg) else None
    state["current"] = f"{pkg}/{intro or pkg + '.Main'}"
    save()
elif line.startswith("input tap "):
    labels = state["screens"].get(package, [])
    if labels and rest[2:] == ["200", "230"]:   # the centre of the node's bounds
        labels.pop(0)
        if not labels and package in state["intro"]:
            state["current"] = f"{package}/{package}.Main"
    save()
elif line == "input keyevent KEYCODE_HOME":
    state["current"] = os.environ["STUB_LAUNCHER"]
    save()
elif line.startswith("dumpsys window"):
    print(f"  mCurrentFocus=Window{{4f1c2e0 u0 {state['current']}}}")
    print(f"  mFocusedApp=ActivityRecord{{9a8b7c6 u0 {state['current']} t12}}")
'''

EMULATOR_STUB = """#!/bin/bash
# the emulator as far as a preparation sees it: it boots (adb answers), and at exit it saves a quick-boot snapshot
# unless it runs with -no-snapshot-save (STUB_SAVES_ANYWAY: an emulator that saves one all the same)
if [ "$1" = -version ]; then echo "Android emulator version 33.1.22.0 (build_id 11078245) (CL:N/A)"; exit 0; fi
printf '%s\\n' "$@" > "$STUB_EMU_ARGS"
echo $$ > "$STUB_EMU_PID"
save=1
for a; do [ "$a" != -no-snapshot-save ] || save=0; done
[ -z "${STUB_SAVES_ANYWAY:-}" ] || save=1
trap 'kill $! 2>/dev/null; [ $save = 0 ] || mkdir -p "$AVD_DIR/snapshots/default_boot"; exit 0' TERM
sleep "${STUB_EMU_SLEEP:-120}" </dev/null >/dev/null 2>&1 &
wait $!
"""


@pytest.fixture
def stand_in(tmp_path):
    """A stand-in device: `adb` (a Python script keeping the device's state in a JSON file) and `emulator`."""
    bin_ = tmp_path / "bin"
    bin_.mkdir()
    adb = bin_ / "adb"
    adb.write_text(f"#!{sys.executable} -S\n" + ADB_STUB)
    adb.chmod(0o755)
    emu = bin_ / "emulator"
    emu.write_text(EMULATOR_STUB)
    emu.chmod(0o755)
    apk_dir = tmp_path / "apks"
    apk_dir.mkdir()
    for apk in MANIFEST["apks"]:
        (apk_dir / f"{apk['package']}.apk").write_bytes(b"PK")
    state = {
        "current": LAUNCHER, "installed": {}, "preinstalled": MANIFEST["preinstalled"], "ungrantable": [],
        "codes": {a["package"]: a["version_code"] or 1 for a in MANIFEST["apks"]},
        # what each app shows on its first launch, as uiautomator would dump it (in order)
        "screens": {"net.gsantner.markor": ["NEXT", "NEXT", "NEXT", "NEXT", "DONE", "OK"],
                    "com.android.camera2": ["NEXT"], "com.google.android.contacts": ["Skip", "Don't allow"],
                    "com.android.chrome": ["Accept & continue"]},
        "intro": {"net.gsantner.markor": "net.gsantner.markor.activity.IntroActivity"},
    }
    env = dict(os.environ, EMULATOR=str(emu), ADB=str(adb), AVD_DIR=str(tmp_path / "avd"), MANIFEST=str(apps.MANIFEST),
               APK_DIR=str(apk_dir), REPORT=str(tmp_path / "first-run.txt"), BOOT_WAIT="5", TAP_WAIT="0",
               STEP_PAUSE="0", SETTLE="0", FOCUS_WAIT="0", STUB_STATE=str(tmp_path / "state.json"),
               STUB_LOG=str(tmp_path / "adb.log"), STUB_EMU_ARGS=str(tmp_path / "emulator.args"),
               STUB_EMU_PID=str(tmp_path / "emulator.pid"), STUB_LAUNCHER=LAUNCHER,
               PATH=f"{bin_}:{os.environ['PATH']}")
    (tmp_path / "avd").mkdir()

    class StandIn:
        path = tmp_path

        def set(self, **changes):
            state.update(changes)

        def run(self, *args: str, timeout: float = 120, extra: dict[str, str] | None = None):
            (tmp_path / "state.json").write_text(json.dumps(state))
            return subprocess.run(["bash", str(ENTRY), *args], env=env | (extra or {}), capture_output=True,
                                  text=True, timeout=timeout)

        def source(self, script: str, extra: dict[str, str] | None = None):
            (tmp_path / "state.json").write_text(json.dumps(state))
            return subprocess.run(["bash", "-c", f"source {ENTRY}; {script}"], env=env | (extra or {}),
                                  capture_output=True, text=True, timeout=60)

        def calls(self) -> list[list[str]]:
            log = tmp_path / "adb.log"
            return [json.loads(line) for line in log.read_text().splitlines()] if log.exists() else []

        def shell_lines(self) -> list[str]:
            return [" ".join(c[1:]) for c in self.calls() if c[0] == "shell"]

        def emulator_args(self) -> list[str]:
            return (tmp_path / "emulator.args").read_text().splitlines()

        def state(self) -> dict:
            return json.loads((tmp_path / "state.json").read_text())

    yield StandIn()
    pid = tmp_path / "emulator.pid"
    if pid.exists():   # a stand-in emulator left by a preparation that stopped: only that one
        try:
            os.kill(int(pid.read_text()), 15)
        except (ProcessLookupError, ValueError):
            pass


def test_prepare_installs_the_pins_dismisses_every_first_run_then_saves_only_golden(stand_in):
    """One preparation against the stand-in device. It also grants a permission Camera does not ask for (said,
    not failed), and its emulator saves a quick-boot snapshot despite -no-snapshot-save (never kept)."""
    stand_in.set(ungrantable=["android.permission.WRITE_EXTERNAL_STORAGE"])
    r = stand_in.run("prepare", extra={"STUB_SAVES_ANYWAY": "1"})
    assert r.returncode == 0, r.stderr[-3000:]
    args = stand_in.emulator_args()
    assert "-no-snapshot-load" in args and "-no-snapshot-save" in args and "-read-only" not in args
    assert args[args.index("-camera-back") + 1] == "emulated"
    calls, lines = stand_in.calls(), stand_in.shell_lines()
    installs = [c for c in calls if c[0] == "install"]
    assert [c[:3] for c in installs] == [["install", "-r", "-g"]] * 3       # runtime permissions granted at install
    assert {Path(c[-1]).name for c in installs} == {f"{a['package']}.apk" for a in MANIFEST["apks"]}
    for key in ("window_animation_scale", "transition_animation_scale", "animator_duration_scale"):
        assert f"settings put global {key} 0" in lines
    assert "ime set com.android.adbkeyboard/.AdbIME" in lines
    assert "pm grant com.android.camera2 android.permission.ACCESS_COARSE_LOCATION" in lines
    assert "appops set --uid net.gsantner.markor MANAGE_EXTERNAL_STORAGE allow" in lines
    assert "appops set --uid ws.xsoh.etar SCHEDULE_EXACT_ALARM allow" in lines
    # the app op is set before Markor's first launch (else it asks for all-files access)
    assert lines.index("appops set --uid net.gsantner.markor MANAGE_EXTERNAL_STORAGE allow") < \
        lines.index("monkey -p net.gsantner.markor -c android.intent.category.LAUNCHER 1")
    state = stand_in.state()
    assert all(not labels for labels in state["screens"].values()), state["screens"]   # every label tapped
    report = (stand_in.path / "first-run.txt").read_text()
    for entry in MANIFEST["first_run"]:
        if entry.get("launch", True):
            assert f"first run done: {entry['package']}" in report, entry["package"]
    assert "com.google.android.contacts: tapped 'Don't allow'" in report
    assert "com.android.chrome: tapped 'Accept & continue'" in report
    assert "com.android.chrome: 'No thanks' did not show" in report     # said, not an error
    save = calls.index(["emu", "avd", "snapshot", "save", "golden"])
    assert save > max(i for i, c in enumerate(calls) if c[:2] == ["shell", "monkey"])   # after every first run
    assert calls[save + 1] == ["emu", "kill"]
    assert (stand_in.path / "avd" / "snapshots" / "golden").is_dir()
    assert not (stand_in.path / "avd" / "snapshots" / "default_boot").exists()
    assert "removing a quick-boot snapshot the emulator saved anyway" in r.stderr
    assert "com.android.camera2: not granted android.permission.WRITE_EXTERNAL_STORAGE" in report
    said = I.first_run_lines(r.stderr)
    assert any("installed: net.gsantner.markor (versionCode 163" in s for s in said)
    assert sum("first run done" in s for s in said) == sum(e.get("launch", True) for e in MANIFEST["first_run"])


def test_prepare_saves_no_snapshot_while_a_first_run_screen_stays(stand_in):
    """Markor shows a screen the manifest does not know: its intro is still there when it is launched again, so the
    preparation stops without a snapshot and says which app and what it shows."""
    stand_in.set(screens={"net.gsantner.markor": ["LATER"]})
    r = stand_in.run("prepare")
    assert r.returncode == 1
    assert "FIRST RUN NOT DONE: net.gsantner.markor: launched again, it shows " \
           "net.gsantner.markor.activity.IntroActivity again" in r.stderr
    assert ["emu", "avd", "snapshot", "save", "golden"] not in stand_in.calls()
    assert not (stand_in.path / "avd" / "snapshots").exists()


def test_prepare_refuses_an_apk_that_is_not_the_pinned_version(stand_in):
    stand_in.set(codes={"net.gsantner.markor": 140, "ws.xsoh.etar": 57, "com.android.adbkeyboard": 2})
    r = stand_in.run("prepare")
    assert r.returncode != 0
    assert "net.gsantner.markor: installed versionCode 140, manifest.json pins 163" in r.stderr
    assert ["emu", "avd", "snapshot", "save", "golden"] not in stand_in.calls()


def test_run_starts_from_the_snapshot_read_only(stand_in, tmp_path):
    socat = tmp_path / "bin" / "socat"
    socat.write_text("#!/bin/sh\nexit 0\n")
    socat.chmod(0o755)
    (tmp_path / "avd" / "snapshots" / "golden").mkdir(parents=True)
    r = stand_in.run("run", timeout=30, extra={"STUB_EMU_SLEEP": "0"})
    assert r.returncode == 0, r.stderr
    args = stand_in.emulator_args()
    assert args[args.index("-snapshot") + 1] == "golden"
    assert "-read-only" in args and "-no-snapshot-save" in args
    assert args[args.index("-camera-back") + 1] == "emulated"
    shutil.rmtree(tmp_path / "avd" / "snapshots")
    r = stand_in.run("run", timeout=30, extra={"STUB_EMU_SLEEP": "0"})
    assert "-no-snapshot-load" in stand_in.emulator_args() and "cold boot" in r.stderr


@pytest.mark.parametrize("dump, label", [("launcher_api27.xml", "chrome"), ("launcher_api27.xml", "Sunday, May 19"),
                                         ("messages_720x1536.xml", "RCS chat with A")])
def test_a_label_is_found_and_tapped_at_its_centre_in_recorded_dumps(stand_in, tmp_path, dump, label):
    """The first-run walker reads real `uiautomator dump` output (one line, or indented), any case, text or
    content-desc, and taps the centre of that node's bounds."""
    root = ET.parse(DATA / "uiautomator" / dump).getroot()
    node = next(n for n in root.iter("node") if label.lower() in (n.get("text", "").lower(),
                                                                   n.get("content-desc", "").lower()))
    x1, y1, x2, y2 = map(int, re.findall(r"\d+", node.get("bounds")))
    fake = tmp_path / "bin" / "adb"
    fake.write_text(f"#!/bin/sh\ncase \"$1\" in exec-out) cat {DATA / 'uiautomator' / dump};; "
                    f"shell) echo \"$*\" >> {tmp_path}/taps;; esac\n")
    r = stand_in.source(f"tap_label {json.dumps(label)}")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "taps").read_text().splitlines()[-1] == f"shell input tap {(x1 + x2) // 2} {(y1 + y2) // 2}"
    r = stand_in.source("tap_label 'No such button'")
    assert r.returncode == 1 and "input tap" not in (tmp_path / "taps").read_text().splitlines()[-1]


def test_the_focused_window_is_read_as_the_harness_reads_it(stand_in, tmp_path):
    text = (DATA / "dumpsys" / "window_windows_android4.txt").read_text()
    current = "  mCurrentFocus=Window{4f1c2e0 u0 com.android.settings/com.android.settings.Settings}\n"
    record = "  mFocusedApp=ActivityRecord{9a8b7c6 u0 com.google.android.deskclock/com.android.deskclock.DeskClock t3}\n"
    for sample in (text, current + record, record, "  mCurrentFocus=Window{1 u0 NotificationShade}\n" + record):
        (tmp_path / "window.txt").write_text(sample)
        (tmp_path / "bin" / "adb").write_text(f"#!/bin/sh\ncat {tmp_path}/window.txt\n")
        r = stand_in.source("focused")
        want = outputs.focused_activity(sample)
        assert r.stdout.strip() == "/".join(want), sample


# -- the attach backend: a template whose app the device lacks is skipped, with how to run it ---------------------------
class Device:
    """A device answering `pm list packages` (and counting how often it was asked)."""

    def __init__(self, packages, code=0):
        self.packages, self.code, self.asked = packages, code, 0

    def run(self, command, timeout=60.0):
        from jarvis_pytest.devices.base import CommandResult

        assert command == "pm list packages"
        self.asked += 1
        return CommandResult(self.code, "".join(f"package:{p}\n" for p in self.packages), "")


def _template(name):
    from jarvis_pytest.tasks.model import TaskTemplate

    return TaskTemplate.model_validate(json.loads((REPO / "tasks" / "android" / f"{name}.json").read_text()))


PHONE = ["com.android.settings", "com.google.android.contacts", "com.android.chrome", "com.sec.android.app.camera"]


def test_missing_apps_are_what_the_template_launches_and_the_device_lacks():
    phone = Device(PHONE)
    assert apps.missing_apps(phone, _template("markor_create_note")) == ["net.gsantner.markor"]
    assert apps.missing_apps(phone, _template("camera_take_photo")) == ["com.android.camera2"]
    assert apps.missing_apps(phone, _template("settings_brightness")) == []
    assert apps.missing_apps(phone, _template("files_rename_photo")) == []   # opens a folder: any Files app will do
    assert apps.parse_packages("package:a.b\r\npackage:c.d\nnoise\n") == {"a.b", "c.d"}
    with pytest.raises(InfrastructureError, match="pm list packages"):
        apps.installed_packages(Device([], code=1))


def test_attach_skip_reason_names_the_app_and_the_commands_that_run_it(monkeypatch):
    phone = Device(PHONE)
    monkeypatch.setattr(apps, "_device", lambda serial: phone)
    monkeypatch.setattr(apps, "_installed", {})
    why = apps.attach_skip_reason("R58M123", _template("markor_create_note"))
    assert why.startswith("android-markor-create_note needs net.gsantner.markor (Markor), which the attached device "
                          "R58M123 does not have (`pm list packages`)")
    assert "curl -fL -o net.gsantner.markor.apk https://f-droid.org/repo/net.gsantner.markor_163.apk && adb -s " \
           "R58M123 install -r -g net.gsantner.markor.apk" in why
    assert "--android-backend emulator" in why
    assert "com.android.camera2 (Camera)" in apps.attach_skip_reason("R58M123", _template("camera_take_photo"))
    assert apps.attach_skip_reason("R58M123", _template("settings_brightness")) is None
    assert phone.asked == 1                            # one `pm list packages` a minute, however many tasks ask
    assert apps.attach_skip_reason(None, _template("markor_create_note")) is None

    def gone(serial):
        raise InfrastructureError("android device R58M124 is not online")

    monkeypatch.setattr(apps, "installed_packages", gone)
    assert apps.attach_skip_reason("R58M124", _template("markor_create_note")) is None   # its boot will say why


def test_a_benchmark_run_on_a_phone_without_the_app_skips_the_task_and_says_how_to_run_it(tmp_path):
    """The whole path, where the run decides what it can run (`harness/availability.skip_reason` asks the attach
    backend): `pytest tasks/test_atomic.py --android-backend attach` with a stand-in `adb` whose device (shell
    commands run in mksh) lists two packages; the Markor task is skipped, never failed, its result says why and
    the commands that would run it."""
    mksh = shutil.which("mksh")
    if not mksh:
        pytest.skip("needs mksh (Android's shell): apt-get install mksh (`make host-packages`)")
    (tmp_path / "dev").mkdir()
    pm = tmp_path / "dev" / "pm"
    pm.write_text("#!/bin/sh\nprintf 'package:com.android.settings\\npackage:com.android.chrome\\n'\n")
    getprop = tmp_path / "dev" / "getprop"   # booted: a task that is not skipped gets as far as its set-up
    getprop.write_text("#!/bin/sh\necho 1\n")
    adb = tmp_path / "adb"
    adb.write_text(textwrap.dedent(f"""\
        #!/bin/sh
        while [ $# -gt 0 ]; do case "$1" in -P|-s) shift 2;; *) break;; esac; done
        case "$1" in
          shell) shift; PATH={tmp_path}/dev:$PATH exec {mksh} -c "$*";;
          features) echo shell_v2;;
          get-state) echo device;;
        esac
        """))
    for f in (pm, getprop, adb):
        f.chmod(0o755)
    results = tmp_path / "run"
    r = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", str(REPO / "tasks" / "test_atomic.py"),
                        "-q", "-rs", "-k", "android-markor-create_note", "--agent", "noop", "--instances", "1",
                        "--android-backend", "attach", "--android-serial", "R58M123", "--results-dir", str(results)],
                       cwd=REPO, env=dict(os.environ, JARVIS_ADB=str(adb)), capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and "1 skipped" in r.stdout, r.stdout[-3000:] + r.stderr[-2000:]
    (result,) = results.glob("tasks/android-markor-create_note*/result.json")
    data = json.loads(result.read_text())
    assert data["status"] == "skipped"
    assert data["error"].startswith("android-markor-create_note needs net.gsantner.markor (Markor), which the "
                                    "attached device R58M123 does not have")
    assert "adb -s R58M123 install -r -g net.gsantner.markor.apk" in data["error"]


# -- the live gate prints its table ---------------------------------------------------------------------------------
def test_the_live_gate_prints_what_passed_what_failed_and_why(monkeypatch, tmp_path, capsys):
    """`make test-android` (the live gate) shows the quality gate's table — each template's verdicts and the first
    reason of a failure — on the terminal whether the gate passes or not (here: a stand-in `jarvis qc`)."""
    sys.path.insert(0, str(Path(__file__).parent))
    import test_library_android as L

    table = ("| task | fresh device | negatives | after oracle | gate | reason |\n|---|---|---|---|---|---|\n"
             "| android-settings-brightness[0] | fail | 2/2 fail | pass | ok |  |\n"
             "| android-markor-create_note[0] | - | - | - | skipped | android-markor-create_note needs "
             "net.gsantner.markor (Markor) |\n\n1/1 instances pass the quality gate; 1 skipped")
    for rc in (0, 1):
        def fake_run(argv, cwd=None, capture_output=True, text=True, timeout=None):
            out = Path(argv[argv.index("--results-dir") + 1])
            out.mkdir(parents=True, exist_ok=True)
            (out / "qc.md").write_text(table + "\n")
            return subprocess.CompletedProcess(argv, rc, table + "\n", "")

        monkeypatch.setattr(L.subprocess, "run", fake_run)
        printed = L.run_live_gate(["--android-backend", "attach"], tmp_path / str(rc))
        assert printed.returncode == rc
        shown = capsys.readouterr().out
        assert "android-markor-create_note[0] | - | - | - | skipped | android-markor-create_note needs" in shown
        assert "1/1 instances pass the quality gate; 1 skipped" in shown
