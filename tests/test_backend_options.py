"""Backends resolved once and given their options: a backend declares its options (`BackendOption`) and is made
from their values (`Backend.configure`); a run resolves every platform's backend once (`resolve_backends`), from
`--PLATFORM-backend` and `--backend-option PLATFORM.KEY=VALUE`, hands that to everything that boots, skips or
lists images, gives its xdist workers the same choice, and records it in run.json. Bad input is one usage error.
Every result says what its device really is (read inside it): the ubuntu platform's device is Debian 12 with
XFCE, and `--base` (an Ubuntu base never built) is gone."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from jarvis_pytest.devices import backend as B
from jarvis_pytest.devices.backend import Backend, BackendOption, Backends, positive_int, resolve_backends
from jarvis_pytest.errors import ConfigError, InfrastructureError

REPO = Path(__file__).resolve().parents[1]
USAGE = 4


def _backend(name: str, why: str | None = None, calls: list | None = None, **fields) -> Backend:
    def unavailable():
        if calls is not None:
            calls.append(name)
        return why
    return Backend(platform="acme", name=name, image="transfer", port=8000, connect=lambda url: url,
                   wait_ready=lambda url, t: None, unavailable=unavailable, **fields)


def _options() -> tuple[BackendOption, ...]:
    return (BackendOption("size", "the screen size", default="1920x1080", example="1280x720"),
            BackendOption("cores", "the cores", default=2, parse=positive_int, env="ACME_CORES", example="4"))


@pytest.fixture
def acme(monkeypatch):
    """A platform "acme" with two registered backends: `slow` (first; cannot run here) and `fast` (takes options,
    its memory follows from `cores`)."""
    calls: list[str] = []
    monkeypatch.delenv("ACME_CORES", raising=False)
    slow = _backend("slow", "no slow machine here", calls)
    fast = _backend("fast", None, calls, options=_options(),
                    derive=lambda v: {"memory": f"{v['cores']}g", "booted_memory_mb": 100 * v["cores"]})
    monkeypatch.setitem(B._REGISTERED, "acme", {"slow": slow, "fast": fast})
    return calls


# -- a backend's options ----------------------------------------------------------------------------------------
def test_a_backend_is_made_from_its_options_the_env_and_the_defaults(acme, monkeypatch):
    fast = B._REGISTERED["acme"]["fast"]
    assert fast.values == {"size": "1920x1080", "cores": 2} and fast.memory == "2g"  # defaults, fields derived
    assert fast.configure({}) is fast  # nothing changes: the same backend
    made = fast.configure({"cores": "4", "size": "800x600"})
    assert made.values == {"size": "800x600", "cores": 4} and (made.memory, made.booted_memory_mb) == ("4g", 400)
    assert fast.values["cores"] == 2  # the defined backend is untouched
    monkeypatch.setenv("ACME_CORES", "3")  # the older variable, when the option is not given ...
    assert fast.configure({}).values["cores"] == 3
    assert fast.configure({"cores": "5"}).values["cores"] == 5  # ... and the option wins over it
    monkeypatch.setenv("ACME_CORES", "none")
    with pytest.raises(ConfigError, match=r"\$ACME_CORES.*'none' is not valid"):
        fast.configure({})


def test_bad_keys_and_values_are_one_error_naming_the_option_and_the_valid_keys(acme):
    cases = [
        ({"acme": {"colour": "red"}}, {}, ["--backend-option acme.colour", "valid keys: acme.size, acme.cores"]),
        ({"acme": {"cores": "0"}}, {}, ["--backend-option acme.cores", "'0'", "give 1 or more",
                                        "e.g. acme.cores=4"]),
        ({"amiga": {"x": "1"}}, {}, ["--backend-option amiga.x", "no platform 'amiga'", "acme", "acme.size"]),
        ({}, {"acme": "vax"}, ["--acme-backend", "no acme backend 'vax'", "auto, slow, fast"]),
        ({"acme": {"size": "1x1"}}, {"acme": "slow"}, ["acme.size is an option of the fast backend, not of slow",
                                                       "--acme-backend fast"]),
    ]
    for given, choices, words in cases:
        with pytest.raises(ConfigError) as err:
            resolve_backends(choices, given)
        for word in words:
            assert word in str(err.value), (word, str(err.value))


def test_auto_takes_the_first_backend_that_runs_here_and_says_what_it_passed_over(acme):
    found = resolve_backends(given={"acme": {"cores": "4"}}, only=("acme",))
    assert found["acme"].name == "fast" and found["acme"].values["cores"] == 4
    assert acme == ["slow", "fast"]  # asked once each, at resolution
    record = found.record()["acme"]
    assert record == {"asked": "auto", "given": {"cores": "4"}, "backend": "fast", "label": "acme (fast)",
                      "options": {"size": "1920x1080", "cores": 4}, "passed_over": ["slow: no slow machine here"]}
    json.dumps(found.record())  # run.json takes it as it is
    found.backend("acme")
    assert acme == ["slow", "fast"]  # using it asks nothing again


def test_a_platform_without_a_backend_that_runs_says_why(acme, monkeypatch):
    monkeypatch.setitem(B._REGISTERED, "acme", {"slow": B._REGISTERED["acme"]["slow"]})
    found = resolve_backends(only=("acme",))
    assert "acme" not in found and found.why_missing("acme") == "slow: no slow machine here"
    with pytest.raises(InfrastructureError, match="no acme backend can run on this machine .slow: no slow"):
        found.backend("acme")
    assert found.record()["acme"]["unavailable"] == "slow: no slow machine here"


def test_a_worker_runs_what_its_controller_chose_without_asking_the_machine_again(acme):
    controller = resolve_backends(given={"acme": {"size": "800x600"}}, only=("acme",))
    decided = json.loads(json.dumps(controller.decided()))  # as xdist hands it over
    acme.clear()
    B._REGISTERED["acme"]["fast"] = _backend("fast", "gone by now", acme, options=_options())  # the machine changed
    worker = resolve_backends(given={"acme": {"size": "800x600"}}, decided=decided, only=("acme",))
    assert worker["acme"].name == "fast" and worker["acme"].values["size"] == "800x600" and acme == []
    missing = resolve_backends(decided={"chosen": {}, "missing": {"acme": "none here"}}, only=("acme",))
    assert missing.why_missing("acme") == "none here" and acme == []


def test_lifecycle_uses_the_backends_it_is_given(device_images, monkeypatch):
    from jarvis_pytest.environments.lifecycle import Lifecycle

    mine = _backend("mine")
    monkeypatch.setattr(B, "resolve_backends", lambda *a, **k: pytest.fail("resolved again"))
    lc = Lifecycle("test-given-backends", "test", backends=Backends({"acme": mine}))
    try:
        assert lc.backend("acme") is mine
        assert lc.booted_memory_mb(("acme",)) == mine.booted_memory_mb + lc.server.booted_memory_mb
        with pytest.raises(InfrastructureError, match="no device backend for platform 'ubuntu'"):
            lc.backend("ubuntu")  # a run's backends are all there is: nothing is chosen again
    finally:
        lc.close()


def test_the_windows_vm_takes_its_settings_as_options(monkeypatch):
    from jarvis_pytest.devices.windows import backend as W

    for var in W.real.ENV.values():
        monkeypatch.delenv(var, raising=False)
    assert {"version", "ram", "cpus", "image", "disks"} <= set(B.option_keys("windows"))
    kvm = W.KVM.configure({"version": "10l", "ram": "8G", "cpus": "4", "disks": "/srv/win"})
    s = kvm.settings  # what dockur installs the golden with, and the runner restores its tasks with
    env = W.real.environment(s)
    assert (env["VERSION"], env["RAM_SIZE"], env["CPU_CORES"]) == ("10l", "8G", "4")
    assert W.real.ram_mb(s) == 8192 and s.golden == Path("/srv/win/golden")
    assert kvm.booted_memory_mb == 8192 + 160 and kvm.memory == f"{8192 + 512}m"  # a pre-warm keeps the VM's RAM free
    why = kvm.unavailable()
    assert "/srv/win/golden" in why or "/dev/kvm" in why, why  # the golden it looks for is the option's
    monkeypatch.setenv("JARVIS_WINDOWS_VERSION", "10l")
    assert W.KVM.configure({}).values["version"] == "10l"  # the older variable still counts
    with pytest.raises(ConfigError, match=r"--backend-option windows.version.*'11'.*WordPad.*fix: use 10"):
        W.KVM.configure({"version": "11"})
    with pytest.raises(ConfigError, match=r"--backend-option windows.ram.*'lots'"):
        W.KVM.configure({"ram": "lots"})


# -- the command line -------------------------------------------------------------------------------------------
def run_pytest(*args: str, env: dict | None = None, xdist: bool = False) -> subprocess.CompletedProcess:
    """A pytest run of its own; it inherits no xdist worker's variables from the test that runs it (under
    `make test`'s -n 2 the inner run's controller would otherwise see PYTEST_XDIST_WORKER and take itself for a
    worker)."""
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", *([] if xdist else ["-p", "no:xdist"]), *args]
    inherited = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST_XDIST_")}
    return subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=600, env={**inherited, **(env or {})})


BAD = {
    "unknown key": (["--backend-option", "windows.verison=10"],
                    ["--backend-option windows.verison", "valid keys:", "windows.version", "windows.ram"]),
    "unknown platform": (["--backend-option", "macos.version=14"], ["no platform 'macos'", "ubuntu, windows, android",
                                                                    "android.serial"]),
    "bad value": (["--backend-option", "windows.ram=lots"], ["--backend-option windows.ram", "'lots'", "4G"]),
    "not KEY=VALUE": (["--backend-option", "windows"], ["--backend-option", "PLATFORM.KEY=VALUE"]),
    "option of another backend": (["--windows-backend", "wine", "--backend-option", "windows.version=10"],
                                  ["option of the kvm backend, not of wine"]),
    "alias and option disagree": (["--android-serial", "a", "--backend-option", "android.serial=b"],
                                  ["android.serial is given twice"]),
    "bad variable": (["--windows-backend", "kvm"], ["$JARVIS_WINDOWS_VERSION", "'11'", "WordPad"]),
}


@pytest.mark.parametrize("name", sorted(BAD))
def test_bad_backend_options_are_one_usage_error(name, tmp_path):
    args, words = BAD[name]
    env = {"JARVIS_WINDOWS_VERSION": "11"} if name == "bad variable" else {}
    proc = run_pytest("tasks", "--agent", "noop", "--results-dir", str(tmp_path / "out"), "-k", "no_task_is_named_so",
                      *args, env=env)  # start-up checks every option whatever is selected; were one let through, no
    out = proc.stdout + proc.stderr  # task would run (exit 5)
    assert proc.returncode == USAGE, out[-3000:]
    assert "Traceback" not in out and "INTERNALERROR" not in out, out[-3000:]
    for word in words:
        assert word in out, f"{word!r} not in:\n{out[-3000:]}"
    assert not (tmp_path / "out" / "tasks").exists()


def _library(root: Path, *templates: str) -> Path:
    for name in templates:
        platform, _, file = name.partition("/")
        (root / platform).mkdir(parents=True, exist_ok=True)
        shutil.copy(REPO / "tasks" / platform / f"{file}.json", root / platform / f"{file}.json")
    return root


def test_run_json_records_the_backends_asked_for_and_chosen(tmp_path):
    """An Android task on a machine without an Android device: skipped (nothing boots); run.json says what the
    run asked for (the option, via the older flag too) and what it got, per platform."""
    lib = _library(tmp_path / "lib", "android/calendar_add_event")
    run = tmp_path / "run"
    proc = run_pytest(str(REPO / "tasks" / "test_atomic.py"), "--library", str(lib), "--instances", "1",
                      "--agent", "noop", "--results-dir", str(run), "--android-image", "example/none:1",
                      env={"JARVIS_ANDROID_SERIAL": ""})
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0 and "1 skipped" in out, out[-3000:]
    record = json.loads((run / "run.json").read_text())["backends"]
    assert record["android"]["given"] == {"image": "example/none:1"} and record["android"]["backend"] is None
    assert "example/none:1" in record["android"]["unavailable"]
    assert record["ubuntu"] == {"asked": "auto", "given": {}, "backend": "docker", "label": "ubuntu (docker)",
                                "options": {}}
    assert record["windows"]["asked"] == "auto" and record["windows"]["backend"] in ("wine", "kvm")
    (result,) = [json.loads(p.read_text()) for p in run.glob("tasks/*/result.json")]
    assert result["status"] == "skipped" and "example/none:1" in result["error"]


PLUGIN = '''
"""An ubuntu backend that can run in the controller only (as if the machine changed under the run); booting it
only says it was booted."""
import os
from jarvis_pytest.devices.backend import Backend, register_backend
from jarvis_pytest.errors import InfrastructureError

class ControllerOnly(Backend):
    def boot(self, request):
        raise InfrastructureError("the controller_only backend was booted")

def unavailable():
    return "a worker" if os.environ.get("PYTEST_XDIST_WORKER") else None

register_backend(ControllerOnly(platform="ubuntu", name="controller_only", image="transfer", port=8000,
                                connect=lambda url: url, wait_ready=lambda url, t: None, unavailable=unavailable))
'''


def test_xdist_workers_run_the_backends_the_controller_chose(tmp_path):
    """A worker's own look at the machine would pick another backend here (the first one runs in the controller
    only, as if the machine changed): it runs the one its controller chose, which the run recorded."""
    (tmp_path / "acme_plugin.py").write_text(textwrap.dedent(PLUGIN))
    lib = _library(tmp_path / "lib", "ubuntu/mousepad_append_line")
    run = tmp_path / "run"
    proc = run_pytest("-n", "1", "-p", "acme_plugin", str(REPO / "tasks" / "test_atomic.py"), "--library", str(lib),
                      "--instances", "1", "--agent", "noop", "--results-dir", str(run),
                      env={"PYTHONPATH": f"{tmp_path}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}, xdist=True)
    out = proc.stdout + proc.stderr
    assert json.loads((run / "run.json").read_text())["backends"]["ubuntu"]["backend"] == "controller_only", out
    (result,) = [json.loads(p.read_text()) for p in run.glob("tasks/*/result.json")]
    assert result["status"] == "error" and "the controller_only backend was booted" in result["error"], result


# -- what the device really is ----------------------------------------------------------------------------------
class _Said:
    """A device that answers `run` with the given output."""

    def __init__(self, stdout: str, returncode: int = 0):
        self.stdout, self.returncode, self.commands = stdout, returncode, []

    def run(self, command, timeout=60.0, user=None):
        from jarvis_pytest.devices.base import CommandResult

        self.commands.append(command)
        return CommandResult(self.returncode, self.stdout, "")


OS_RELEASE = ('PRETTY_NAME="Debian GNU/Linux 12 (bookworm)"\nNAME="Debian GNU/Linux"\nVERSION_ID="12"\n'
              'VERSION="12 (bookworm)"\nID=debian\n')


def test_each_backend_says_what_its_device_is():
    from jarvis_pytest.devices.android import backend as A
    from jarvis_pytest.devices.ubuntu import backend as U
    from jarvis_pytest.devices.windows import backend as W

    assert U.describe(_Said(OS_RELEASE + "xfce4-session 4.18.1 (Xfce 4.18)\n")) == \
        "Debian GNU/Linux 12 (bookworm), XFCE 4.18"
    assert U.describe(_Said('NAME="Ubuntu"\nVERSION="24.04 LTS (Noble Numbat)"\n')) == "Ubuntu 24.04 LTS (Noble Numbat)"
    assert W.describe_wine(_Said("10.0.18362\r\n8.0\r\n" + OS_RELEASE.replace("\n", "\r\n"))) == \
        "Wine 8.0 on Debian GNU/Linux 12 (bookworm), reporting Windows 10.0.18362"
    assert W.describe_wine(_Said("10.0.19045\r\n\r\n\r\n")) == "Windows 10.0.19045 (not Wine)"
    with pytest.raises(InfrastructureError, match="could not say"):
        W.describe_wine(_Said("", returncode=1))
    vm = ("\r\nMicrosoft Windows [Version 10.0.19045.3803]\r\n\r\nHKEY_LOCAL_MACHINE\\SOFTWARE\\Microsoft\\Windows NT"
          "\\CurrentVersion\r\n    ProductName    REG_SZ    Windows 10 Pro\r\n    EditionID    REG_SZ    Professional"
          "\r\n    DisplayVersion    REG_SZ    22H2\r\n    CurrentBuild    REG_SZ    19045\r\n    UBR    REG_DWORD    "
          "0xedb\r\n")
    assert W.describe_vm(_Said(vm)) == "Windows 10 Professional 22H2 (build 19045.3803)"
    assert A.describe(_Said("13\n33\nsdk_gphone64_x86_64\n")) == "Android 13 (API 33), sdk_gphone64_x86_64"
    fingerprint = "google/sdk_gphone64_x86_64/emu64xa:13/TE1A.220922.034/10940250:userdebug/dev-keys"
    assert A.describe(_Said(f"13\n33\nsdk_gphone64_x86_64\n{fingerprint}\n")) == \
        f"Android 13 (API 33), sdk_gphone64_x86_64, build {fingerprint}"
    for backend in (U.BACKEND, W.WINE, W.KVM, A.EMULATOR, A.ATTACH):
        assert backend.describe is not None, backend.label


def test_a_device_is_asked_once_per_image_and_never_fails_a_task():
    from jarvis_pytest.devices.ubuntu import backend as U
    from jarvis_pytest.environments.lifecycle import describe_device

    said = _Said(OS_RELEASE)
    key = f"sha256:test-{os.getpid()}-{id(said)}"
    assert describe_device(U.BACKEND, said, key) == "Debian GNU/Linux 12 (bookworm)"
    assert describe_device(U.BACKEND, said, key) == "Debian GNU/Linux 12 (bookworm)" and len(said.commands) == 1

    class Broken:
        def run(self, *a, **k):
            raise InfrastructureError("device gone")

    assert describe_device(U.BACKEND, Broken(), key + "-b") == "unknown (InfrastructureError: device gone)"


def test_the_summary_says_what_each_platform_ran_on():
    from jarvis_pytest.report.rollup import render_markdown, render_terminal, rollup
    from jarvis_pytest.results.model import SubtaskVerdict, TaskResult

    def result(tid: str, platform: str, system: str) -> TaskResult:
        return TaskResult(task_id=tid, category="atomic", platforms=[platform], instruction="x", status="passed",
                          subtasks=[SubtaskVerdict(index=0, template="t", platform=platform, passed=True)],
                          device_os={platform: system})

    s = rollup([result("u", "ubuntu", "Debian GNU/Linux 12 (bookworm), XFCE 4.18"),
                result("w", "windows", "Wine 8.0 on Debian GNU/Linux 12 (bookworm), reporting Windows 10.0.18362")])
    line = ("ubuntu platform: Debian GNU/Linux 12 (bookworm), XFCE 4.18; windows platform: Wine 8.0 on Debian "
            "GNU/Linux 12 (bookworm), reporting Windows 10.0.18362")
    assert f"**Devices:** {line}." in render_markdown(s) and f"devices: {line}" in render_terminal(s)


def test_results_carry_the_real_system_of_each_device(device_images, tmp_path):
    """A real run on this machine's devices: the ubuntu platform's device says it is Debian 12 with XFCE, the
    Windows stand-in that it is Wine on Debian; the results and the summary say so."""
    lib = _library(tmp_path / "lib", "ubuntu/mousepad_append_line", "windows/cmd_list_files")
    run = tmp_path / "run"
    proc = run_pytest(str(REPO / "tasks" / "test_atomic.py"), "--library", str(lib), "--instances", "1",
                      "--agent", "noop", "--results-dir", str(run), "--windows-backend", "wine")
    out = proc.stdout + proc.stderr
    results = {r["platforms"][0]: r for r in (json.loads(p.read_text()) for p in run.glob("tasks/*/result.json"))}
    assert set(results) == {"ubuntu", "windows"} and all(r["status"] == "failed" for r in results.values()), out
    assert results["ubuntu"]["device_os"] == {"ubuntu": "Debian GNU/Linux 12 (bookworm), XFCE 4.18"}
    assert results["windows"]["device_os"]["windows"].startswith("Wine 8.0 on Debian GNU/Linux 12 (bookworm)")
    summary = (run / "summary.md").read_text()
    assert "ubuntu platform: Debian GNU/Linux 12 (bookworm), XFCE 4.18" in summary
    assert "ubuntu platform: Debian GNU/Linux 12 (bookworm), XFCE 4.18" in out  # the terminal's tables too


def test_images_build_on_debian_only_and_base_is_gone():
    proc = subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "images", "build", "--base", "ubuntu:24.04"],
                          cwd=REPO, capture_output=True, text=True, timeout=120)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 2 and "Traceback" not in out, out
    assert "--base is gone" in out and "Debian 12 (bookworm)" in out and "Debian 12 with XFCE" in out
    from jarvis_pytest.infra import images

    assert "base" not in images.build_all.__code__.co_varnames[:images.build_all.__code__.co_argcount]
