"""The real Windows backend (`--windows-backend kvm`), which cannot boot here (no Windows image can be had): its
container specification, its first-boot (OEM) scripts and bundle, when it says it cannot run, and how tasks
written for it are skipped on this machine."""

from __future__ import annotations

import io
import json
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from jarvis_pytest.devices.backend import backend_for
from jarvis_pytest.devices.windows import real
from jarvis_pytest.errors import InfrastructureError

REPO = Path(__file__).resolve().parents[1]


def test_task_container_runs_a_vm_from_an_overlay_of_the_golden_disk():
    opts = real.task_container_options("vol-1")
    assert opts["devices"] == ["/dev/kvm"] and "NET_ADMIN" in opts["cap_add"]
    env = opts["environment"]
    assert env["USER_PORTS"] == "5000"  # the control server's port is forwarded into the VM
    assert env["USERNAME"] == "user" and env["VERSION"] and env["DISK_FMT"] == "qcow2"
    assert opts["volumes"][str(real.GOLDEN)] == {"bind": "/golden", "mode": "ro"}  # never written by a task
    assert opts["volumes"]["vol-1"] == {"bind": "/storage", "mode": "rw"}
    shell = opts["entrypoint"]
    assert shell[:2] == ["/bin/sh", "-c"]
    create, _, start = shell[2].partition(" && ")
    assert create.split() == ["qemu-img", "create", "-q", "-f", "qcow2", "-F", "qcow2", "-b", "/golden/data.qcow2",
                              "/storage/data.qcow2"]
    assert start.startswith("exec ")  # dockur's own entry takes over as PID 1


@pytest.mark.parametrize("ram, mb", [(None, 4096), ("6G", 6144), ("6144M", 6144), ("8gb", 8192),
                                      (str(3 * 2**30), 3072), ("lots", 4096)])
def test_a_pre_warm_of_the_vm_needs_its_ram_free(monkeypatch, ram, mb):
    if ram is None:
        monkeypatch.delenv("JARVIS_WINDOWS_RAM", raising=False)
    else:
        monkeypatch.setenv("JARVIS_WINDOWS_RAM", ram)
    assert real.ram_mb() == mb  # what RAM_SIZE gives the VM; the pool keeps it (and QEMU's own) free to pre-warm


def test_backend_says_why_it_cannot_run(monkeypatch, tmp_path):
    kvm = backend_for("windows", "kvm")
    assert kvm.image_kind == "prepared" and not kvm.stand_in and kvm.label == "windows (kvm)"
    assert backend_for("windows", "real") is kvm  # the name for it
    monkeypatch.setattr(real, "READY_MARK", tmp_path / "golden" / "READY")
    assert "no prepared Windows disk" in (kvm.unavailable() or "")
    (tmp_path / "golden").mkdir()
    (tmp_path / "golden" / "READY").write_text("x")
    assert kvm.unavailable() is None or "/dev/kvm" in kvm.unavailable()
    monkeypatch.setattr(real.os.path, "exists", lambda p: False)
    assert "no /dev/kvm" in kvm.unavailable()
    assert "jarvis images build --only windows-real" in kvm.how_to_run
    # auto picks the first backend that can run: here the Wine stand-in
    monkeypatch.setattr(real, "READY_MARK", tmp_path / "nothing")
    auto = backend_for("windows")
    assert auto.name == "wine" and auto.stand_in and auto.label == "windows (wine)"


def test_first_boot_scripts_install_python_and_the_server_and_start_them_at_logon():
    install = (real.OEM_DIR / "install.bat").read_bytes()
    start = (real.OEM_DIR / "start.bat").read_bytes()
    for script in (install, start):
        assert b"\r\n" in script and b"\n" not in script.replace(b"\r\n", b"")  # cmd wants CRLF
    text = install.decode()
    assert "python-embed.zip" in text and "server.zip" in text and r"C:\jarvis" in text
    assert "localport=5000" in text and r"CurrentVersion\Run" in text and "start.bat" in text
    assert "python313._pth" in text
    run = start.decode()
    assert "net use S: http://transfer:5244/" in run and "agentPassword" in run
    assert r"python.exe -m jarvis_pytest.devices.windows.server --port 5000" in run


def test_oem_bundle_carries_the_official_python_with_its_licence_and_the_server(tmp_path):
    folder = real.oem_bundle(tmp_path / "oem")
    assert sorted(p.name for p in folder.iterdir()) == ["install.bat", "python-embed.zip", "server.zip", "start.bat"]
    py = zipfile.ZipFile(folder / "python-embed.zip")
    names = set(py.namelist())
    assert {"python.exe", "LICENSE.txt", "python313.zip", "_ctypes.pyd", "_socket.pyd"} <= names
    assert py.read("python.exe")[:2] == b"MZ"  # a Windows executable
    server = zipfile.ZipFile(io.BytesIO((folder / "server.zip").read_bytes()))
    names = server.namelist()
    assert {"jarvis_pytest/devices/windows/server/__main__.py", "jarvis_pytest/devices/control_http.py",
            "jarvis_pytest/devices/pyautogui_compat.py", "jarvis_pytest/devices/windows/__init__.py",
            "jarvis_pytest/devices/png.py", "jarvis_pytest/devices/windows/server/screen.py"} <= set(names)
    # the package imports nothing beyond the standard library on the device: no pydantic, no httpx
    for name in names:
        text = server.read(name).decode()
        assert "import pydantic" not in text and "from pydantic" not in text and "import httpx" not in text, name


def test_a_template_for_the_real_backend_is_skipped_here_with_its_reason(tmp_path):
    """An application only a real Windows has (Paint): on this machine (Wine) the instance is skipped, with the
    reason and the command that would run it, counted apart — never failed, nothing booted."""
    tpl = {
        "id": "windows-paint-save_png", "platform": "windows", "app": "Paint", "backends": ["kvm"],
        "instruction": "Save {{image}} as PNG.",
        "inputs": {"image": {"type": "image_file", "choices": ["C:\\Users\\user\\Pictures\\a.bmp"]}},
        "config": [{"type": "upload_file", "path": "{{image}}", "content": "x"}],
        "evaluate": [{"func": "file_exists", "args": {"path": "{{image}}"}}],
    }
    lib = tmp_path / "lib"
    (lib / "windows").mkdir(parents=True)
    (lib / "windows" / "paint.json").write_text(json.dumps(tpl))
    run = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist", "-rs",
                           str(REPO / "tasks" / "test_atomic.py"), "--library", str(lib), "--instances", "1",
                           "--agent", "noop", "--results-dir", str(run)],
                          cwd=REPO, capture_output=True, text=True, timeout=300)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0 and "1 skipped" in out, out[-3000:]
    assert "needs the windows backend kvm" in out and "jarvis images build --only windows-real" in out
    summary = json.loads((run / "summary.json").read_text())
    assert summary["skipped"]["atomic"] == 1 and summary["atomic"]["overall"]["n"] == 0
    assert "Skipped: no device here" in (run / "summary.md").read_text()


def test_preparing_downloads_nothing_unless_asked(monkeypatch):
    """`jarvis images build --only windows-real` pulls an image and downloads Windows: without the opt-in it stops
    before any of that, saying how to allow it (no Docker call, no packet)."""
    monkeypatch.delenv(real.DOWNLOAD_ENV, raising=False)
    monkeypatch.setattr(real.os.path, "exists", lambda p: True)  # as on a machine with /dev/kvm
    import jarvis_pytest.infra.engine as engine

    monkeypatch.setattr(engine, "client", lambda **kw: pytest.fail("no Docker call without the opt-in"))
    with pytest.raises(InfrastructureError, match=f"{real.DOWNLOAD_ENV}=1"):
        real.prepare()
