"""The Windows file, Recycle Bin, Command Prompt and Task Manager evaluators (`evaluators/windows_files.py`), run on
host files (no container): a host folder stands in for the device's drives (`C:\\x` is `<tmp>/C/x`), the probe's
own file code (`PROBE`'s `entry` and `tree`) reads it, and processes, windows and Recycle Bin records are given as
the probe reports them. For each template the result a careful person (or the application) leaves passes, and
each near-miss state of the template's `negatives` fails with a reason naming what is wrong. Instances come from
the templates themselves (rendered with fixed slot values)."""

from __future__ import annotations

import base64
import hashlib
import json
import os
import shutil
from pathlib import Path

import pytest

from jarvis_pytest.devices.base import CommandResult
from jarvis_pytest.evaluators import get_evaluator, windows_files as W
from jarvis_pytest.evaluators.state import FinalState
from jarvis_pytest.generators import generate
from jarvis_pytest.tasks.instances import materialise
from jarvis_pytest.tasks.model import Subtask, TaskTemplate

LIBRARY = Path(__file__).resolve().parents[1] / "tasks" / "windows"
PROBE_NS: dict = {"__name__": "probe"}
exec(compile(W.PROBE, "probe.py", "exec"), PROBE_NS)  # the probe's own functions, run on host paths


class WinHost:
    """A Windows device whose drives are folders of the host; `processes`, `windows` and `trash` are what the
    probe would report. Commands: the evaluator's scratch run of a batch file (its `mkdir` lines) and `rmdir`."""

    platform = "windows"

    def __init__(self, root: Path):
        self.root = root
        self.processes: list[dict] = []
        self.windows: list[dict] = []
        self.trash: dict = {"xdg": [], "recycle": [], "prefix": "/root/.wine"}
        self.commands: list[str] = []

    def host(self, path: str) -> Path:
        drive, rest = path[0].upper(), path[2:].replace("\\", "/").strip("/")
        return self.root / drive / rest

    def upload(self, path: str, data: bytes) -> None:
        target = self.host(path)
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(data)

    def download(self, path: str) -> bytes:
        return self.host(path).read_bytes()

    def exists(self, path: str) -> bool:
        return os.path.lexists(self.host(path))

    def run(self, command: str, *, timeout: float = 60.0, user: str | None = None) -> CommandResult:
        self.commands.append(command)
        if command.startswith("mkdir ") and "call" in command:  # mkdir "S" && cd /d "S" && call "BAT" <nul
            parts = command.split('"')
            scratch, bat = self.host(parts[1]), parts[5]
            scratch.mkdir(parents=True)
            for line in self.download(bat).decode().splitlines():
                words = line.strip().split()
                if words and words[0].lower() == "mkdir":
                    for name in words[1:]:
                        name = name.strip('"')
                        (self.host(name) if ":" in name else scratch / name).mkdir(parents=True, exist_ok=True)
            return CommandResult(0, "", "")
        if command.startswith("rmdir /s /q"):
            shutil.rmtree(self.host(command.split('"')[1]), ignore_errors=True)
            return CommandResult(0, "", "")
        raise AssertionError(f"unexpected command {command!r}")

    def probe(self, state, *, entries=None, trees=None, processes=False, windows=False, trash=False, platform=None):
        out = {"entries": {p: PROBE_NS["entry"](str(self.host(p))) for p in entries or []},
               "trees": {r: PROBE_NS["tree"](str(self.host(r))) if self.host(r).is_dir() else None
                         for r in trees or []}}
        if processes:
            out["processes"] = self.processes
        if windows:
            out["windows"] = self.windows
        if trash:
            out["trash"] = self.trash
        return out


@pytest.fixture
def dev(tmp_path, monkeypatch) -> WinHost:
    device = WinHost(tmp_path)
    monkeypatch.setattr(W, "probe", device.probe)
    return device


def instance(name: str, **values) -> Subtask:
    tpl = TaskTemplate.model_validate(json.loads((LIBRARY / f"{name}.json").read_text()))
    return materialise(tpl, values)


def set_up(dev: WinHost, sub: Subtask) -> dict[str, bytes]:
    """The template's upload steps applied to the host device; the baselines its `baseline` paths get."""
    for step in sub.config:
        if step.type == "upload_file":
            data = step.content.encode() if step.content is not None else generate(step.generator, step.args)
            dev.upload(step.path, data)
    return {p: dev.download(p) for p in sub.baseline if dev.exists(p)}


def check(dev: WinHost, sub: Subtask, baselines: dict[str, bytes]) -> list:
    state = FinalState(platform="windows", devices={"windows": dev},
                       baselines={("windows", p): b for p, b in baselines.items()})
    return [get_evaluator(spec.func)(state, **spec.args) for spec in sub.evaluate]


def passed(verdicts) -> bool:
    return all(v.passed for v in verdicts)


def reasons(verdicts) -> str:
    return " | ".join(v.reason for v in verdicts if not v.passed)


# -- pure helpers ---------------------------------------------------------------------------------------------
def test_recycle_bin_records_of_both_versions_and_trashinfo_paths():
    path = "C:\\Users\\user\\Downloads\\old invoice.txt"
    v2 = (2).to_bytes(8, "little") + (123).to_bytes(8, "little") + bytes(8) + \
        (len(path) + 1).to_bytes(4, "little") + (path + "\0").encode("utf-16-le")
    v1 = (1).to_bytes(8, "little") + (123).to_bytes(8, "little") + bytes(8) + \
        (path + "\0").encode("utf-16-le").ljust(520, b"\0")
    assert W.recycle_record_path(v2) == path == W.recycle_record_path(v1)
    assert W.recycle_record_path(b"junk") is None and W.recycle_record_path((9).to_bytes(8, "little") * 4) is None
    info = "[Trash Info]\nPath=/root/.wine/dosdevices/c:/users/user/Documents/my%20notes.txt\nDeletionDate=x\n"
    assert W.trashinfo_path(info, "/root/.wine") == "C:\\users\\user\\Documents\\my notes.txt"
    assert W.trashinfo_path("[Trash Info]\nPath=/tmp/a.txt\n", "/root/.wine") == "Z:\\tmp\\a.txt"
    assert W.trashinfo_path("[Trash Info]\n", "/root/.wine") is None


def test_decode_text_and_numbers_and_listings():
    assert W.decode_text("é\r\n".encode("utf-16")) == "é\r\n"
    assert W.decode_text(b"\xef\xbb\xbf42") == "42" and W.decode_text(b"caf\xe9") == "café"
    assert W.check_number(" 1234\r\n", 1234).passed
    assert not W.check_number("1234 items", 1234).passed and not W.check_number("", 5).passed
    assert "an empty file" in W.check_number("", 5).reason
    ok = W.check_listing("a.txt\r\nB.csv\r\n\r\n", ["A.TXT", "b.csv"], "F")
    assert ok.passed
    bad = W.check_listing("a.txt\r\na.txt\r\nold\r\n", ["a.txt", "b.csv"], "F")
    assert not bad.passed and "missing ['b.csv']" in bad.reason and "'old'" in bad.reason and "twice" in bad.reason


def test_check_programs_and_started_by():
    procs = [{"pid": 4, "ppid": 0, "name": "explorer.exe"}, {"pid": 10, "ppid": 4, "name": "taskmgr.exe"},
             {"pid": 11, "ppid": 10, "name": "notepad.exe"}, {"pid": 12, "ppid": 4, "name": "notepad.exe"},
             {"pid": 13, "ppid": 4, "name": "regedit.exe"}]
    wins = [{"title": "a.txt - Notepad", "pid": 11, "visible": True}, {"title": "b.txt - Notepad", "pid": 12,
                                                                        "visible": False},
            {"title": "Registry Editor", "pid": 13, "visible": True}]
    v = W.check_programs(procs, wins, ["b.txt - Notepad"], ["a.txt - Notepad", "Registry Editor"],
                         {"notepad.exe": 1})
    assert not v.passed and "its window hidden" in v.reason and "2 notepad.exe" in v.reason
    v = W.check_programs(procs[:3] + procs[4:], [wins[0], wins[2]], ["B.TXT - Notepad"],
                         ["a.txt - Notepad", "Registry Editor"], {"notepad.exe": 1, "regedit.exe": 1})
    assert v.passed, v.reason
    assert W.check_started_by(procs, wins, ["a.txt - Notepad"], "notepad.exe", "taskmgr.exe").passed
    v = W.check_started_by(procs, wins[1:], ["Registry Editor"], "regedit.exe", "taskmgr.exe")
    assert not v.passed and "started by explorer.exe" in v.reason
    assert "no such window" in W.check_started_by(procs, wins, ["x - Notepad"], "notepad.exe", "taskmgr.exe").reason
    orphan = [p for p in procs if p["pid"] != 10]
    assert "no longer running" in W.check_started_by(orphan, wins, ["a.txt - Notepad"], "notepad.exe",
                                                     "taskmgr.exe").reason


def test_the_probe_reads_files_folders_links_and_hard_links(tmp_path):
    (tmp_path / "d" / "e").mkdir(parents=True)
    (tmp_path / "d" / "f.txt").write_bytes(b"abc")
    os.link(tmp_path / "d" / "f.txt", tmp_path / "d" / "g.txt")
    os.symlink(tmp_path / "d" / "f.txt", tmp_path / "d" / "h.txt")
    tree = PROBE_NS["tree"](str(tmp_path / "d"))
    assert tree["f.txt"]["sha256"] == hashlib.sha256(b"abc").hexdigest() and tree["f.txt"]["nlink"] == 2
    assert tree["e"]["dir"] and tree["h.txt"]["link"] and PROBE_NS["entry"](str(tmp_path / "x")) == {"exists": False}
    assert "hard link" in W.check_regular_file(tree["g.txt"], None, "copy")
    assert "a link" in W.check_regular_file(tree["h.txt"], None, "copy")


def test_the_probe_script_runs_and_writes_its_answer(tmp_path):
    """The probe as the device runs it (here with the host's Python: files only, no ctypes calls)."""
    import subprocess
    import sys

    (tmp_path / "probe.py").write_text(W.PROBE)
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "x.txt").write_text("x")
    (tmp_path / "req.json").write_text(json.dumps({"entries": [str(tmp_path / "a" / "x.txt")],
                                                   "trees": [str(tmp_path / "a"), str(tmp_path / "none")]}))
    subprocess.run([sys.executable, "-I", str(tmp_path / "probe.py"), str(tmp_path / "req.json"),
                    str(tmp_path / "out.json")], check=True)
    out = json.loads((tmp_path / "out.json").read_text())
    assert out["entries"][str(tmp_path / "a" / "x.txt")]["size"] == 1
    assert list(out["trees"][str(tmp_path / "a")]) == ["x.txt"] and out["trees"][str(tmp_path / "none")] is None
    (tmp_path / "req.json").write_text(json.dumps({"processes": True}))  # no Windows API here: reported, not raised
    subprocess.run([sys.executable, "-I", str(tmp_path / "probe.py"), str(tmp_path / "req.json"),
                    str(tmp_path / "out.json")], check=True)
    assert "Traceback" in json.loads((tmp_path / "out.json").read_text())["error"]


# -- File Explorer ----------------------------------------------------------------------------------------------
def test_rename_file(dev):
    sub = instance("explorer_rename_file", source_file="C:\\Users\\user\\Desktop\\ideas.txt",
                   new_stem="final_version")
    base = set_up(dev, sub)
    src, dest = dev.host(sub.input["source_file"].value), dev.host(sub.output["renamed_file"].value)
    agenda = src.parent / "agenda.txt"
    assert not passed(check(dev, sub, base))
    shutil.copy(src, dest)  # negative: copied under the new name
    assert "copied, not moved" in reasons(check(dev, sub, base))
    os.remove(src)
    assert passed(check(dev, sub, base))  # Explorer's rename
    assert passed(check(dev, sub, {}))  # fed input: no baseline, the move itself
    dest.write_bytes(b"")  # negative: an empty file with the new name
    assert "other content" in reasons(check(dev, sub, base))
    os.rename(dest, src.parent / "final_version")  # negative: no extension
    assert "no file at the new place" in reasons(check(dev, sub, base))
    os.rename(src.parent / "final_version", dest)
    dest.write_bytes(base[sub.input["source_file"].value])
    assert passed(check(dev, sub, base))
    os.remove(agenda)  # negative: the other file deleted
    assert "agenda.txt: gone" in reasons(check(dev, sub, base))


def trash_entry(dev: WinHost, path: str, data: bytes | None, record: str = "xdg") -> None:
    """What Wine's Explorer (a freedesktop.org .trashinfo) or Windows (a $I record) leaves for `path`."""
    blob = dev.root / "trash" / f"{len(dev.trash[record])}"
    if data is not None:
        blob.parent.mkdir(exist_ok=True)
        blob.write_bytes(data)
    facts = PROBE_NS["entry"](str(blob))
    if record == "xdg":
        unix = "/root/.wine/dosdevices/" + path[0].lower() + ":" + path[2:].replace("\\", "/")
        dev.trash["xdg"].append({"name": "x.trashinfo", "info": f"[Trash Info]\nPath={unix}\n", "data": facts})
    else:
        rec = (2).to_bytes(8, "little") + bytes(16) + (len(path) + 1).to_bytes(4, "little") + \
            (path + "\0").encode("utf-16-le")
        dev.trash["recycle"].append({"name": "$IABC.txt", "info_b64": base64.b64encode(rec).decode(), "data": facts})


@pytest.mark.parametrize("record", ["xdg", "recycle"])
def test_trash_file(dev, record):
    sub = instance("explorer_trash_file", doomed="C:\\Users\\user\\Downloads\\old_invoice.txt", token="owl-1234")
    base = set_up(dev, sub)
    doomed = sub.input["doomed"].value
    original = dev.download(doomed)
    budget = dev.host(doomed).parent / "budget.txt"
    assert "it still there" in reasons(check(dev, sub, base))
    os.remove(dev.host(doomed))  # negative: deleted for good
    assert "Recycle Bin entries none" in reasons(check(dev, sub, base))
    trash_entry(dev, "C:\\Users\\user\\Downloads\\other.txt", original, record)  # another file's entry
    assert "Recycle Bin entries" in reasons(check(dev, sub, base))
    trash_entry(dev, doomed.upper(), b"", record)  # an entry naming it, holding other data
    assert "holds other content" in reasons(check(dev, sub, base))
    trash_entry(dev, doomed, original, record)  # Explorer's delete to the bin
    assert passed(check(dev, sub, base))
    budget.write_bytes(b"")  # negative: the work done, the other file emptied
    assert "budget.txt: it holds other content" in reasons(check(dev, sub, base))


def test_trash_file_hand_moved_data_without_a_record_fails(dev):
    sub = instance("explorer_trash_file", doomed="C:\\Users\\user\\Desktop\\temp_list.csv", token="owl-1")
    base = set_up(dev, sub)
    os.remove(dev.host(sub.input["doomed"].value))
    dev.trash["xdg"].append({"name": "junk.trashinfo", "info": "no path here", "data": {"exists": True}})
    assert "Recycle Bin entries none" in reasons(check(dev, sub, base))


# -- Wine's file manager --------------------------------------------------------------------------------------------
def test_copy_to_drive(dev):
    sub = instance("winefile_copy_to_drive", source_file="C:\\Users\\user\\Documents\\meeting_notes.txt",
                   token="owl-42")
    base = set_up(dev, sub)
    src, copy = dev.host(sub.input["source_file"].value), dev.host(sub.output["shared_file"].value)
    assert sub.output["shared_file"].value == "S:\\data\\meeting_notes.txt"
    assert "no copy" in reasons(check(dev, sub, base))
    copy.parent.mkdir(parents=True)
    shutil.copy(src, copy)
    assert passed(check(dev, sub, base)) and passed(check(dev, sub, {}))
    copy.write_bytes(b"")  # negative: an empty file of that name
    assert "copy holds other content" in reasons(check(dev, sub, base))
    os.remove(copy)
    os.link(src, copy)  # a second name of the original
    assert "hard link" in reasons(check(dev, sub, base))
    os.remove(copy)
    os.rename(src, copy)  # negative: moved instead of copied
    assert "original gone" in reasons(check(dev, sub, base))
    shutil.copy(copy, src)
    src.write_bytes(b"changed")
    assert "original changed" in reasons(check(dev, sub, base))


def test_move_file(dev):
    sub = instance("winefile_move_file", source_file="C:\\Users\\user\\Downloads\\timetable.csv",
                   folder="C:\\Users\\user\\Documents\\Shared", token="owl-7")
    base = set_up(dev, sub)
    src, dest = dev.host(sub.input["source_file"].value), dev.host(sub.output["moved_file"].value)
    assert not passed(check(dev, sub, base))
    os.rename(src, dev.root / "C" / "Users" / "user" / "Documents" / src.name)  # negative: into the parent
    assert "no file at the new place" in reasons(check(dev, sub, base))
    os.rename(dev.root / "C" / "Users" / "user" / "Documents" / src.name, dest)
    assert passed(check(dev, sub, base))
    (dest.parent / "index.txt").unlink()
    assert "index.txt: gone" in reasons(check(dev, sub, base))


def test_sort_by_type(dev):
    sub = instance("winefile_sort_by_type", folder="C:\\Users\\user\\Documents\\inbox", ext=".csv", sub="by_type")
    folder = dev.host(sub.input["folder"].value)
    folder.mkdir(parents=True)
    for n in ("alpha", "beta", "gamma"):  # what the set-up commands make
        (folder / f"{n}.csv").write_bytes(f"{n} of .csv\r\n".encode())
    for e in (".png", ".txt", ".pdf"):
        (folder / f"other{e}").write_bytes(f"other {e}\r\n".encode())
    base = {p: dev.download(p) for p in sub.baseline if dev.exists(p)}
    assert "no folder by_type" in reasons(check(dev, sub, base))
    (folder / "by_type").mkdir()
    for n in ("alpha", "beta", "gamma"):
        shutil.copy(folder / f"{n}.csv", folder / "by_type")
    assert "alpha.csv still in the folder" in reasons(check(dev, sub, base))  # copied, not moved
    for n in ("alpha", "beta", "gamma"):
        (folder / f"{n}.csv").unlink()
    assert passed(check(dev, sub, base))  # the file manager's moves
    os.rename(folder / "other.png", folder / "by_type" / "other.png")  # negative: other files moved too
    assert "other.png gone from the folder" in reasons(check(dev, sub, base))
    assert "put in by_type too" in reasons(check(dev, sub, base))
    os.rename(folder / "by_type" / "other.png", folder / "other.png")
    (folder / "by_type" / "beta.csv").write_bytes(b"")  # negative: empty files of the names
    assert "beta.csv in by_type holds other content" in reasons(check(dev, sub, base))
    (folder / "by_type" / "beta.csv").write_bytes(b"beta of .csv\r\n")
    (folder / "by_type" / "stray.txt").write_bytes(b"x")
    assert "also holds ['stray.txt']" in reasons(check(dev, sub, base))


# -- Command Prompt ---------------------------------------------------------------------------------------------
def test_run_batch(dev):
    sub = instance("cmd_run_batch", bat="C:\\Users\\user\\Desktop\\setup_folders.bat", a="src", b="build",
                   c="logs")
    bat = sub.input["bat"].value
    folder = dev.host(bat).parent
    folder.mkdir(parents=True)
    assert "no batch file" in reasons(check(dev, sub, {}))
    dev.upload(bat, b"@echo off\r\nmkdir src\r\nmkdir build\r\nmkdir logs\r\n")
    assert "not run there" in reasons(check(dev, sub, {}))
    for n in ("src", "build", "logs"):
        (folder / n).mkdir()
    assert passed(check(dev, sub, {})), reasons(check(dev, sub, {}))
    assert not (dev.root / "C" / "temp" / "jarvis-probe").exists() or not any(
        (dev.root / "C" / "temp" / "jarvis-probe").iterdir())  # the scratch folder removed
    dev.upload(bat, b"rem creates src build logs\r\n")  # negative: folders by hand, the batch file a comment
    assert "the batch file left" in reasons(check(dev, sub, {})) and "not a folder" in reasons(check(dev, sub, {}))
    dev.upload(bat, b"mkdir src build\r\n")  # negative: only two of them
    assert "logs is nothing, not a folder" in reasons(check(dev, sub, {}))
    dev.upload(bat, f'mkdir "{bat[:-18]}\\src" "{bat[:-18]}\\build" "{bat[:-18]}\\logs"\r\n'.encode())
    assert "src is nothing" in reasons(check(dev, sub, {}))  # negative: fixed paths, not where it runs


def test_list_files(dev):
    sub = instance("cmd_list_files", folder="C:\\Users\\user\\Documents\\invoices", stem="owl", n=123)
    set_up(dev, sub)
    listing = sub.output["listing"].value
    assert listing == "C:\\Users\\user\\Documents\\invoices_files.txt"
    assert "no file" in reasons(check(dev, sub, {}))
    dev.upload(listing, b"IMG_123.png\r\nnotes_owl.md\r\nowl_1.txt\r\nowl_2.csv\r\n")  # dir /b /a-d
    assert passed(check(dev, sub, {}))
    dev.upload(listing, "IMG_123.png\r\nnotes_owl.md\r\nowl_1.txt\r\nowl_2.csv\r\n".encode("utf-16"))
    assert passed(check(dev, sub, {}))  # a UTF-16 listing (cmd /u) reads the same
    dev.upload(listing, b"IMG_123.png\r\nnotes_owl.md\r\nold\r\nowl_1.txt\r\nowl_2.csv\r\n")  # negative: dir /b
    assert "other lines ['old']" in reasons(check(dev, sub, {}))
    dev.upload(listing, b"owl_1.txt\r\n")  # negative: only the .txt files
    assert "missing" in reasons(check(dev, sub, {}))
    dev.upload(listing, b" Volume in drive C has no label.\r\n Directory of C:\\x\r\n"
               b"11/24/2026  5:42 AM  3 owl_1.txt\r\n")
    assert "missing" in reasons(check(dev, sub, {}))  # negative: the full dir output


def test_sum_numbers(dev):
    values = dict(n1=12, n2=30, n3=7, n4=100, n5=250, n6=999)
    sub = instance("cmd_sum_numbers", numbers="C:\\Users\\user\\Documents\\scores.txt", **values)
    base = set_up(dev, sub)
    answer = sub.output["answer"].value
    assert dev.download(sub.input["numbers"].value) == b"12\r\n30\r\n7\r\n100\r\n250\r\n999\r\n"
    assert "no file" in reasons(check(dev, sub, base))
    dev.upload(answer, b"1398\r\n")  # `>answer echo %s%`
    assert passed(check(dev, sub, base))
    dev.upload(answer, b"6\r\n")  # negative: the lines counted
    assert "found '6'" in reasons(check(dev, sub, base))
    dev.upload(answer, b"399\r\n")  # negative: the last number missed
    assert "just the number 1398" in reasons(check(dev, sub, base))
    dev.upload(answer, dev.download(sub.input["numbers"].value))  # negative: the numbers file copied
    assert not passed(check(dev, sub, base))
    dev.upload(answer, b"1398\r\n")
    dev.upload(sub.input["numbers"].value, b"")  # negative: right sum, the numbers file emptied
    assert "scores.txt: it holds other content" in reasons(check(dev, sub, base))


def test_rename_extension(dev):
    sub = instance("cmd_rename_extension", folder="C:\\Users\\user\\Documents\\logs", old_ext=".log",
                   new_ext=".txt", token="owl-5")
    base = set_up(dev, sub)
    folder = dev.host(sub.input["folder"].value)
    assert not passed(check(dev, sub, base))
    os.rename(folder / "alpha.log", folder / "alpha.txt")  # negative: only alpha
    assert "no beta.txt" in reasons(check(dev, sub, base)) and "beta.log still there" in reasons(check(dev, sub, base))
    for n in ("beta", "gamma"):
        os.rename(folder / f"{n}.log", folder / f"{n}.txt")
    assert passed(check(dev, sub, base))  # ren *.log *.txt
    shutil.copy(folder / "alpha.txt", folder / "alpha.log")  # negative: copies, the old files kept
    assert "alpha.log still there" in reasons(check(dev, sub, base))
    os.remove(folder / "alpha.log")
    os.rename(folder / "summary.csv", folder / "summary.txt")  # negative: every file renamed
    assert "no summary.csv" in reasons(check(dev, sub, base)) and "summary.txt" in reasons(check(dev, sub, base))


def test_copy_tree(dev):
    sub = instance("cmd_copy_tree", source="C:\\Users\\user\\Documents\\clients",
                   target="C:\\Users\\user\\Desktop\\skeleton", a="finance", b="q1", c="scans")
    base = set_up(dev, sub)
    src, dst = dev.host(sub.input["source"].value), dev.host(sub.input["target"].value)
    (src / "finance" / "q1" / "final").mkdir()
    (src / "scans" / "old").mkdir()
    assert "no folder" in reasons(check(dev, sub, base))
    dst.mkdir(parents=True)  # negative: the target, empty
    assert "finance is nothing, not a folder" in reasons(check(dev, sub, base))
    for d in ("finance/q1/final", "scans/old"):  # xcopy /t /e
        (dst / d).mkdir(parents=True)
    assert passed(check(dev, sub, base)), reasons(check(dev, sub, base))
    (dst / "finance" / "index.txt").write_bytes(b"x")  # negative: the files copied too
    assert "also ['finance\\\\index.txt']" in reasons(check(dev, sub, base))
    (dst / "finance" / "index.txt").unlink()
    (src / "overview.txt").unlink()  # negative: the source's files deleted
    assert "no overview.txt" in reasons(check(dev, sub, base))


# -- Task Manager -------------------------------------------------------------------------------------------------
def test_end_program(dev):
    sub = instance("taskmgr_end_program", target_doc="C:\\Users\\user\\Documents\\budget.txt",
                   keep_doc="C:\\Users\\user\\Documents\\plans.txt")
    dev.processes = [{"pid": 5, "ppid": 1, "name": "notepad.exe"}, {"pid": 6, "ppid": 1, "name": "notepad.exe"},
                     {"pid": 7, "ppid": 1, "name": "regedit.exe"}, {"pid": 8, "ppid": 1, "name": "taskmgr.exe"}]
    target = {"title": "budget.txt - Notepad", "pid": 5, "visible": True}
    keep = {"title": "plans.txt - Notepad", "pid": 6, "visible": True}
    reg = {"title": "Registry Editor", "pid": 7, "visible": True}
    dev.windows = [target, keep, reg]
    assert "'budget.txt - Notepad' still running" in reasons(check(dev, sub, {}))
    target["visible"] = False  # negative: its window hidden
    assert "its window hidden" in reasons(check(dev, sub, {}))
    dev.windows, dev.processes = [keep, reg], dev.processes[1:]  # End Task
    assert passed(check(dev, sub, {}))
    dev.windows, dev.processes = [target | {"visible": True}, reg], [dev.processes[0] | {"pid": 5}] + dev.processes[1:]
    assert "'plans.txt - Notepad' no longer running" in reasons(check(dev, sub, {}))  # negative: the wrong one
    dev.windows, dev.processes = [reg], dev.processes[1:]  # negative: every Notepad ended
    assert "0 notepad.exe" in reasons(check(dev, sub, {}))


def test_new_task(dev):
    sub = instance("taskmgr_new_task", doc="C:\\Users\\user\\Desktop\\readme.txt", token="owl-3")
    base = set_up(dev, sub)
    dev.processes = [{"pid": 8, "ppid": 1, "name": "taskmgr.exe"}, {"pid": 9, "ppid": 8, "name": "notepad.exe"},
                     {"pid": 3, "ppid": 2, "name": "cmd.exe"}, {"pid": 10, "ppid": 3, "name": "notepad.exe"}]
    assert "no such window" in reasons(check(dev, sub, base))
    dev.windows = [{"title": "readme.txt - Notepad", "pid": 10, "visible": True}]  # negative: from a prompt
    assert "started by cmd.exe" in reasons(check(dev, sub, base))
    dev.windows = [{"title": "Untitled - Notepad", "pid": 9, "visible": True}]  # negative: without the file
    assert "no such window" in reasons(check(dev, sub, base))
    dev.windows = [{"title": "readme.txt - Notepad", "pid": 9, "visible": True}]  # Task Manager's New Task
    assert passed(check(dev, sub, base))
    dev.windows = [{"title": "readme - Notepad", "pid": 9, "visible": True}]  # Windows with extensions hidden
    assert passed(check(dev, sub, base))
    dev.upload(sub.input["doc"].value, b"edited")
    assert "it holds other content" in reasons(check(dev, sub, base))


# -- the probe's round trip through the device API ----------------------------------------------------------------
class ProbeHost(WinHost):
    """Runs the probe as the device would: the uploaded script, with the host's Python, its answer downloaded."""

    def run(self, command: str, *, timeout: float = 60.0, user: str | None = None) -> CommandResult:
        import subprocess
        import sys

        self.commands.append(command)
        if "probe.py" in command:
            paths = [str(self.host(p)) for p in command.split('"')[3::2]]  # probe.py, request.json, out.json
            res = subprocess.run([sys.executable, "-I", *paths], capture_output=True, text=True, timeout=timeout)
            return CommandResult(res.returncode, res.stdout, res.stderr)
        return super().run(command)


def test_probe_round_trip_cleans_up_and_reports_failures(tmp_path):
    from jarvis_pytest.errors import InfrastructureError

    dev = ProbeHost(tmp_path / "drives")
    state = FinalState(platform="windows", devices={"windows": dev})
    target = tmp_path / "files"
    (target / "sub").mkdir(parents=True)
    (target / "a.txt").write_bytes(b"abc")
    out = W.probe(state, entries=[str(target / "a.txt")], trees=[str(target)])
    assert out["entries"][str(target / "a.txt")]["sha256"] == hashlib.sha256(b"abc").hexdigest()
    assert set(out["trees"][str(target)]) == {"a.txt", "sub"}
    assert dev.commands[0].startswith(f'"{W.PYTHON}" -I "{W.PROBE_DIR}\\') and dev.commands[1].startswith("rmdir")
    probe_root = dev.host(W.PROBE_DIR)
    assert not any(probe_root.iterdir())  # its folder removed
    with pytest.raises(InfrastructureError, match="probe failed on the device"):
        W.probe(state, processes=True)  # no Windows API on this host: the probe's own error, reported
    assert not any(probe_root.iterdir())
