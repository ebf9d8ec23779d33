"""The drive's wipe (`fixtures/images/transfer/drive.py`), run on the host against folders of a temporary
directory: what a task left goes, /data is left empty with mode 755, and a device that makes /data as the drive
wipes (the Windows device does, mounting the same volume) does not end the drive."""

from __future__ import annotations

import importlib.util
import shutil
from pathlib import Path

import pytest

DRIVE_SCRIPT = Path(__file__).resolve().parents[1] / "fixtures" / "images" / "transfer" / "drive.py"


@pytest.fixture
def drive(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(DRIVE_SCRIPT.parent))  # drive.py imports its neighbour ledger.py
    spec = importlib.util.spec_from_file_location("jarvis_drive_script", DRIVE_SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    for name in ("DRIVE", "HISTORY", "CONFIG"):
        folder = tmp_path / name.lower()
        folder.mkdir()
        monkeypatch.setattr(module, name, str(folder))
    return module


def test_wipe_leaves_an_empty_data_folder(drive):
    root = Path(drive.DRIVE)
    (root / "data" / "sub").mkdir(parents=True)
    (root / "data" / "sub" / "left.txt").write_text("left by the last task")
    (root / ".hidden").write_text("x")
    (root / "link").symlink_to(root / "data")
    (Path(drive.HISTORY) / "up2k.snap").write_text("x")
    (Path(drive.CONFIG) / "sessions.db").write_text("x")
    (root / "data").chmod(0o700)
    drive.wipe()
    assert sorted(p.name for p in root.iterdir()) == ["data"] and list((root / "data").iterdir()) == []
    assert (root / "data").stat().st_mode & 0o777 == 0o755
    assert list(Path(drive.HISTORY).iterdir()) == [] and not Path(drive.CONFIG).exists()


def test_a_device_making_data_while_the_drive_wipes_does_not_end_it(drive, monkeypatch):
    root = Path(drive.DRIVE)
    (root / "data").mkdir()
    (root / "data" / "left.txt").write_text("x")
    rmtree = shutil.rmtree

    def then_the_device_makes_data(path, *args, **kwargs):  # `mkdir -p /mnt/drive/data` of the device, meanwhile
        rmtree(path, *args, **kwargs)
        if Path(path) == root / "data":
            (root / "data").mkdir(mode=0o700)

    monkeypatch.setattr(drive.shutil, "rmtree", then_the_device_makes_data)
    drive.wipe()
    assert list((root / "data").iterdir()) == [] and (root / "data").stat().st_mode & 0o777 == 0o755
