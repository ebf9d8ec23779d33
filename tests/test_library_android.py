"""The Android task library (`tasks/android/`): it validates, renders, composes with the Ubuntu and Windows
libraries, its shell commands are valid for Android's shell, and it passes the quality gate offline against a
simulated device (`tests/android_sim.py`: the commands run for real in mksh with toybox; the platform's tools and
providers are simulated from their AOSP semantics).

None of this ran on an Android device: none can run on the machine this was written on. The live gate is
`test_live_quality_gate` (`make test-android`), skipped here with the reason and what would run it.
"""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest

from jarvis_pytest.tasks.compose import compose
from jarvis_pytest.tasks.graph import task_problems
from jarvis_pytest.tasks.instances import atomic_instances
from jarvis_pytest.tasks.library import Library, load_library, negative_problems
from jarvis_pytest.tasks.templating import has_placeholder

REPO = Path(__file__).resolve().parents[1]
TASKS = REPO / "tasks"
ANDROID = TASKS / "android"
MKSH, DASH, TOYBOX = shutil.which("mksh"), shutil.which("dash") or shutil.which("sh"), shutil.which("toybox")


@pytest.fixture(scope="module")
def android_library(tmp_path_factory) -> Library:
    """The Android templates alone (a library folder holding only tasks/android)."""
    root = tmp_path_factory.mktemp("lib")
    (root / "android").symlink_to(ANDROID)
    shutil.copy(TASKS / "types.json", root / "types.json")
    return load_library(root)


def template_ids() -> list[str]:
    return sorted(json.loads(p.read_text())["id"] for p in ANDROID.glob("*.json"))


# -- the library ------------------------------------------------------------------------------------------------
def test_at_least_24_templates_over_at_least_10_apps(android_library):
    templates = android_library.by_platform("android")
    apps = Counter(t.app for t in templates)
    assert len(templates) >= 24 and len(apps) >= 10, apps
    assert [t.id for t in templates] == template_ids()
    for path in ANDROID.glob("*.json"):
        tpl = json.loads(path.read_text())
        assert path.name == "{}_{}.json".format(*tpl["id"].split("-", 2)[1:]), path.name


def test_every_template_has_both_kinds_of_negative_and_cites_its_storage(android_library):
    for tpl in android_library.templates:
        assert negative_problems(tpl) == [], tpl.id
        assert len(tpl.negatives) >= 2, tpl.id
        text = tpl.description
        assert "Storage" in text or "evaluator" in text, tpl.id
        assert any(s in text for s in ("content://", "Settings.", "/sdcard", "/data/data", "dumpsys", "AOSP")), tpl.id


def test_two_instances_of_every_template_render(android_library):
    tasks = atomic_instances(android_library, seeds_per_template=2)
    assert len(tasks) == 2 * len(android_library.templates)
    for task in tasks:
        assert task_problems(task, android_library.types) == []
        assert not has_placeholder(task.to_json())
        sub = task.formatted_subtasks[0]
        assert sub.platform == "android" and sub.negatives


def commands(sub) -> list[tuple[str, str]]:
    out = [("config", c.command) for c in sub.config if c.type == "command"]
    out += [("solution", s.command) for s in sub.solution if s.command]
    out += [(f"negative {i}", s.command) for i, n in enumerate(sub.negatives or []) for s in n.steps if s.command]
    return out


@pytest.mark.parametrize("shell", [pytest.param(MKSH, id="mksh"), pytest.param(DASH, id="sh")])
def test_every_command_is_valid_for_the_device_shell(android_library, shell):
    """Set-up, oracle and negative commands parse in mksh (Android's /system/bin/sh) and a POSIX sh."""
    if not shell:
        pytest.skip("shell not installed: apt-get install mksh")
    bad = []
    for task in atomic_instances(android_library, seeds_per_template=2):
        for where, cmd in commands(task.formatted_subtasks[0]):
            res = subprocess.run([shell, "-n", "-c", cmd], capture_output=True, text=True)
            if res.returncode:
                bad.append(f"{task.id} {where}: {res.stderr.strip()}")
    assert not bad, "\n".join(bad)


def test_commands_use_only_what_an_android_image_has(android_library):
    """No bash, curl, wget, python or GNU-only options: the device has mksh and toybox
    (AOSP system/core/shell_and_utilities/README.md)."""
    forbidden = ("bash", "curl ", "wget", "python", "sed -i -e", "0,/", "readlink -f", "xargs -0 -r", "sha256sum -c")
    for task in atomic_instances(android_library, seeds_per_template=1):
        for where, cmd in commands(task.formatted_subtasks[0]):
            hits = [f for f in forbidden if f in cmd]
            assert not hits, f"{task.id} {where}: {hits}"


def test_provider_values_reach_the_tools_as_single_arguments(tmp_path):
    """A contact's name with a space, an SMS body with commas and a `?` arrive at `content` as one argument each
    (recorded by a stand-in `content` on PATH, in mksh)."""
    if not MKSH:
        pytest.skip("mksh not installed: apt-get install mksh")
    tpl = json.loads((ANDROID / "contacts_add_contact.json").read_text())
    record = tmp_path / "content"
    record.write_text("#!/bin/sh\nfor a in \"$@\"; do printf '%s\\n' \"$a\"; done >> \"$LOG\"\n"
                      "case \"$1\" in query) echo 'Row: 0 _id=7';; esac\n")
    record.chmod(0o755)
    cmd = tpl["solution"][0]["command"].replace("{{contact_name}}", "Grace Liu").replace(
        "{{phone}}", "+1 555 347 5919").replace("{{email}}", "meadow.54@example.com")
    env = {"PATH": f"{tmp_path}:/usr/bin:/bin", "LOG": str(tmp_path / "log")}
    res = subprocess.run([MKSH, "-c", cmd], env=env, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    argv = (tmp_path / "log").read_text().splitlines()
    assert "data1:s:Grace Liu" in argv and "data1:s:+1 555 347 5919" in argv and "raw_contact_id:i:7" in argv


# -- composition ------------------------------------------------------------------------------------------------
def test_composes_with_the_ubuntu_and_windows_libraries():
    """`jarvis compose` over tasks/ gives MI and MD tasks with Android subtasks, files crossing in both directions
    through the transfer task."""
    lib = load_library(TASKS)
    platforms = {t.platform for t in lib.templates}
    assert {"android", "ubuntu"} <= platforms
    tasks = compose(lib, seed=0, count=60, max_subtasks=4, balanced=True)
    with_android = [t for t in tasks if "android" in t.devices]
    cats = Counter(t.category for t in with_android)
    assert cats["mi"] and cats["md"], cats
    md = [t for t in with_android if t.category == "md"]
    transfers = {s.template for t in md for s in t.formatted_subtasks if s.template.startswith("transfer-")}
    assert any(x.startswith("transfer-android-to-") for x in transfers), transfers
    for task in tasks:
        assert task_problems(task, lib.types) == []
    if "windows" in platforms:
        assert any({"android", "windows"} <= set(t.devices) for t in tasks), "no task pairs Android with Windows"


def test_cli_compose_over_tasks(tmp_path):
    out = tmp_path / "d.json"
    res = subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "compose", "--library", str(TASKS), "--seed",
                          "1", "--count", "30", "--balanced", "--max-subtasks", "3", "--out", str(out)],
                         cwd=REPO, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    data = json.loads(out.read_text())
    assert any("android" in t["devices"] and t["category"] in ("mi", "md") for t in data["tasks"])


# -- the quality gate against the simulated device --------------------------------------------------------------
def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def gate(sub, root: Path, steps=None):
    """Set `sub` up on a fresh simulated device under `root`, apply `steps` (oracle or negative), evaluate."""
    sys.path.insert(0, str(Path(__file__).parent))
    from android_sim import SimAndroid

    from jarvis_pytest.harness.evaluation import capture_baselines, evaluate_subtasks
    from jarvis_pytest.harness.negatives import apply_steps
    from jarvis_pytest.harness.setup_steps import run_setup

    device = SimAndroid(root, {8080: _free_port(), 8081: _free_port()})
    devices = {"android": device}
    try:
        run_setup([sub], devices)
        baselines = capture_baselines([sub], devices)
        error = apply_steps(steps, devices, "android") if steps else None
        return error, (None if error else evaluate_subtasks([sub], devices, None, baselines)[0])
    finally:
        device.close()


@pytest.mark.parametrize("template", template_ids())
def test_quality_gate_on_the_simulated_device(android_library, template, tmp_path, monkeypatch):
    """Every evaluator fails on the freshly set-up device, every negative fails (with a reason), and the oracle
    passes — on the first instance; the second instance's oracle passes too."""
    if not (MKSH and TOYBOX):
        pytest.skip("the simulated device needs mksh and toybox (Android's shell and tools): "
                    "apt-get install mksh toybox (`make host-packages`)")
    from jarvis_pytest.evaluators import android as A

    monkeypatch.setattr(A, "SETTLE_SECONDS", 0.0)
    tasks = [t for t in atomic_instances(android_library, seeds_per_template=2) if t.id.startswith(template + "[")]
    for n, task in enumerate(tasks):
        sub = task.formatted_subtasks[0]
        if n == 0:
            error, fresh = gate(sub, tmp_path / f"{n}-fresh")
            assert error is None
            held = [e for e in fresh.evaluators if e.passed]
            assert not held, f"{task.id}: passes untouched: {[e.reason for e in held]}"
            for i, neg in enumerate(sub.negatives):
                error, verdict = gate(sub, tmp_path / f"{n}-neg{i}", neg.steps)
                assert error is None, f"{task.id} negative {i} ({neg.note}) cannot be applied: {error}"
                assert not verdict.passed, f"{task.id} negative {i} ({neg.kind}: {neg.note}) passes"
                assert all(e.reason.startswith("expected ") for e in verdict.evaluators)
        error, after = gate(sub, tmp_path / f"{n}-oracle", sub.solution)
        assert error is None, f"{task.id}: the oracle cannot be applied: {error}"
        assert after.passed, f"{task.id}: the oracle fails: {[e.reason for e in after.evaluators]}"


# -- the live gate ------------------------------------------------------------------------------------------------
def run_live_gate(extra: list[str], results: Path) -> subprocess.CompletedProcess:
    """`jarvis qc --platform android` with `extra` pytest arguments; prints its table (every instance: fresh device,
    negatives, oracle, the gate, and the first reason of a failure or a skip) and where the results are, so that
    one paste of the output reports the run."""
    res = subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "qc", "--platform", "android", "--instances",
                          os.environ.get("JARVIS_ANDROID_INSTANCES", "1"), "-n", "1", "--results-dir", str(results),
                          "--", *extra], cwd=REPO, capture_output=True, text=True, timeout=4 * 3600)
    table = results / "qc.md"
    report = table.read_text() if table.exists() else res.stdout[-4000:]
    print(f"\n-- jarvis qc --platform android ({' '.join(extra)}): exit {res.returncode} --\n{report}")
    if res.returncode != 0:
        print(res.stderr[-2000:])
    print(f"results: {results}")
    return res


@pytest.mark.android_live
def test_live_quality_gate(tmp_path, capsys):
    """`jarvis qc --platform android` on a real device: an attached one (JARVIS_ANDROID_SERIAL) or the prepared
    emulator image; its table goes to the terminal whether it passes or not. Skipped, with what would run it, where
    there is neither (as on the machine this was written on: the Android library has not been run live)."""
    from jarvis_pytest.devices.backend import backend_for
    from jarvis_pytest.errors import JarvisError

    try:
        backend = backend_for("android")
    except JarvisError as exc:
        pytest.skip(f"no Android device here ({exc}); with a device: JARVIS_ANDROID_SERIAL=<serial> make "
                    "test-android, or after `JARVIS_ANDROID_DOWNLOAD=1 jarvis images build --only android` on a "
                    "machine with /dev/kvm: make test-android")
    extra = ["--android-backend", backend.name]
    if backend.name == "attach":
        extra += ["--android-serial", os.environ.get("JARVIS_ANDROID_SERIAL", "")]
    with capsys.disabled():
        res = run_live_gate(extra, tmp_path / "qc")
    table = tmp_path / "qc" / "qc.md"
    report = table.read_text() if table.exists() else res.stdout[-4000:]
    assert res.returncode == 0, report + res.stderr[-2000:]
    gated = {line.split("|")[1].strip().split("[")[0] for line in report.splitlines() if line.startswith("| android-")}
    assert gated == set(template_ids()), sorted(set(template_ids()) - gated)
