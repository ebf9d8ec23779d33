"""The evaluators of the Windows file-manager, Command Prompt and Task Manager templates (`folders.py` and
`text.py` on Windows, `windows_files.py`, `windows_processes.py`), run on host files (no container): a host folder stands in for the
device's drives (`C:\\x` is `<tmp>/C/x`), the probe's own file code (`PROBE`'s `entry` and `tree`) reads it,
hidden and system attributes are given per host path, and processes, windows and Recycle Bin records are given as
the probe reports them. Set-up runs the template's uploads and takes the set-up snapshots its evaluators ask for.
For each template the result a careful person (or the application) leaves passes, and each near-miss state of the
template's `negatives` fails with a reason naming what is wrong. Instances come from the templates themselves
(rendered with fixed slot values)."""

from __future__ import annotations

import base64
import hashlib
import json
import os
import shutil
from pathlib import Path

import pytest

from jarvis_pytest.devices.base import CommandResult
from jarvis_pytest.devices.platforms import PLATFORMS
from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.evaluators import folders as F, get_evaluator, text as T, windows_probe as P
from jarvis_pytest.evaluators import windows_processes as WP, windows_recycle_bin as RB
from jarvis_pytest.evaluators.snapshots import capture_setup_snapshots
from jarvis_pytest.evaluators.state import FinalState
from jarvis_pytest.generators import generate
from jarvis_pytest.tasks.instances import materialise
from jarvis_pytest.tasks.model import Subtask, TaskTemplate

LIBRARY = Path(__file__).resolve().parents[1] / "tasks" / "windows"
WINDOWS = PLATFORMS["windows"]
PROBE_NS: dict = {"__name__": "probe"}
exec(compile(P.PROBE, "probe.py", "exec"), PROBE_NS)  # the probe's own functions, run on host paths
PROBE_NS["HEADS"].update(WINDOWS.shell_files)
HIDDEN, SYSTEM = 0x2, 0x4


class WinHost:
    """A Windows device whose drives are folders of the host; `attrs` the hidden/system attributes of host paths;
    `processes`, `windows` and `trash` are what the probe would report. Commands: the evaluator's scratch run of a
    batch file (its `mkdir` lines) and `rmdir`."""

    platform = "windows"

    def __init__(self, root: Path):
        self.root = root
        self.attrs: dict[Path, int] = {}
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

    def entry(self, host: Path) -> dict:
        """The probe's facts of a host path, with the attributes `attrs` gives it."""
        info = PROBE_NS["entry"](str(host))
        if info["exists"]:
            info.update(hidden=bool(self.attrs.get(host, 0) & HIDDEN), system=bool(self.attrs.get(host, 0) & SYSTEM))
        return info

    def tree(self, root: Path, depth) -> dict:
        return {rel: self.entry(root / rel) for rel in PROBE_NS["tree"](str(root), depth)}

    def probe(self, state, *, entries=None, trees=None, depth=None, processes=False, windows=False, trash=None,
              heads=None, search=None, sizes=None, platform=None):
        out = {"entries": {p: self.entry(self.host(p)) for p in entries or []},
               "trees": {r: self.tree(self.host(r), depth) if self.host(r).is_dir() else None for r in trees or []}}
        if search:  # the probe's own search on the host folders, its finds named by their device paths
            out["found"] = {}
            for root in search:
                for found in PROBE_NS["search"]([str(self.host(root))], sizes or []):
                    rel = os.path.relpath(found, self.host(root)).replace(os.sep, "\\")
                    out["found"][root.rstrip("\\") + "\\" + rel] = self.entry(Path(found))
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
    monkeypatch.setattr(P, "probe", device.probe)
    monkeypatch.setattr(WP, "probe", device.probe)
    return device


def instance(template: str, **values) -> Subtask:
    tpl = TaskTemplate.model_validate(json.loads((LIBRARY / f"{template}.json").read_text()))
    return materialise(tpl, values)


def set_up(dev: WinHost, sub: Subtask) -> dict[str, bytes]:
    """The template's upload steps applied to the host device; the baselines its `baseline` paths get."""
    for step in sub.config:
        if step.type == "upload_file":
            data = step.content.encode() if step.content is not None else generate(step.generator, step.args)
            dev.upload(step.path, data)
    return capture(dev, sub)


def capture(dev: WinHost, sub: Subtask) -> dict[str, bytes]:
    """What the harness keeps right after set-up: the `baseline` files and the evaluators' set-up snapshots."""
    base = {p: dev.download(p) for p in sub.baseline if dev.exists(p)}
    return base | capture_setup_snapshots(FinalState(platform="windows", devices={"windows": dev}), sub.evaluate)


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
    assert RB.recycle_record_path(v2) == path == RB.recycle_record_path(v1)
    assert RB.recycle_record_path(b"junk") is None and RB.recycle_record_path((9).to_bytes(8, "little") * 4) is None
    info = "[Trash Info]\nPath=/root/.wine/dosdevices/c:/users/user/Documents/my%20notes.txt\nDeletionDate=x\n"
    assert RB.trashinfo_path(info, "/root/.wine") == "C:\\users\\user\\Documents\\my notes.txt"
    assert RB.trashinfo_path("[Trash Info]\nPath=/tmp/a.txt\n", "/root/.wine") == "Z:\\tmp\\a.txt"
    assert RB.trashinfo_path("[Trash Info]\n", "/root/.wine") is None


def test_decode_text_and_numbers_and_listings():
    """Answers in text files are read by the one decoder (`text.decode_text`, the platform's code page) and
    compared as the platform compares names (without case on Windows only)."""
    cp = WINDOWS.text_codepage
    assert T.decode_text("é\r\n".encode("utf-16"), cp).text == "é\r\n"
    assert T.decode_text(b"\xef\xbb\xbf42", cp).text == "42" and T.decode_text(b"caf\xe9", cp).text == "café"
    assert T.check_number(" 1234\r\n", 1234).passed
    assert not T.check_number("1234 items", 1234).passed and not T.check_number("", 5).passed
    assert "an empty file" in T.check_number("", 5).reason
    ok = T.check_listing(WINDOWS, "a.txt\r\nB.csv\r\n\r\n", ["A.TXT", "b.csv"], "F")
    assert ok.passed
    bad = T.check_listing(WINDOWS, "a.txt\r\na.txt\r\nold\r\n", ["a.txt", "b.csv"], "F")
    assert not bad.passed and "missing ['b.csv']" in bad.reason and "'old'" in bad.reason and "twice" in bad.reason
    ubuntu = T.check_listing(PLATFORMS["ubuntu"], "a.txt\nb.csv\n", ["A.TXT", "b.csv"], "F")
    assert not ubuntu.passed and "missing ['A.TXT']" in ubuntu.reason  # another name where case counts
    assert T.check_listing(PLATFORMS["ubuntu"], "A.TXT\nb.csv\n", ["A.TXT", "b.csv"], "F").passed


def test_a_listing_or_number_that_is_no_text_fails(dev):
    """Bytes no Windows program writes as text (NUL bytes without a UTF-16 mark) are no answer."""
    sub = instance("cmd_sum_numbers", numbers="C:\\Users\\user\\Documents\\scores.txt", n1=1, n2=2, n3=3, n4=4,
                   n5=5, n6=6)
    base = set_up(dev, sub)
    dev.upload(sub.output["answer"].value, b"21\x00\r\n")
    assert "not a text file" in reasons(check(dev, sub, base))


def programs(procs, wins) -> WP.Programs:
    return WP.Programs([dict(p) for p in procs], [dict(w) for w in wins])


def test_programs_are_the_processes_set_up_started():
    procs = [{"pid": 4, "ppid": 0, "name": "explorer.exe", "started": 1}, {"pid": 11, "ppid": 4,
             "name": "notepad.exe", "started": 5}, {"pid": 12, "ppid": 4, "name": "notepad.exe", "started": 6},
             {"pid": 13, "ppid": 4, "name": "regedit.exe", "started": 7}]
    wins = [{"title": "a.txt - Notepad", "pid": 11, "visible": True}, {"title": "b.txt - Notepad", "pid": 12,
                                                                        "visible": True},
            {"title": "Registry Editor", "pid": 13, "visible": True}]
    setup = programs(procs, wins)
    ended, running = ["B.TXT - Notepad"], ["a.txt - Notepad", "Registry Editor"]
    images = {"notepad.exe": 1, "regedit.exe": 1}
    assert WP.check_programs(setup, programs(procs[:2] + procs[3:], [wins[0], wins[2]]), ended, running,
                             images).passed
    hidden = programs(procs, [wins[0], wins[1] | {"visible": False}, wins[2]])
    v = WP.check_programs(setup, hidden, ended, running, images)
    assert not v.passed and "its window hidden" in v.reason and "2 notepad.exe" in v.reason
    # every Notepad ended and a.txt opened again: the title and the counts are right, the process is not
    again = programs([procs[0], procs[3], {"pid": 20, "ppid": 4, "name": "notepad.exe", "started": 9}],
                     [{"title": "a.txt - Notepad", "pid": 20, "visible": True}, wins[2]])
    v = WP.check_programs(setup, again, ended, running, images)
    assert not v.passed and "set-up's process 11 (notepad.exe) is gone" in v.reason and "started again" in v.reason
    # the same id handed to the new process (Wine reuses ids): its start time tells them apart
    reused = programs([procs[0], procs[3], procs[1] | {"started": 9}], [wins[0], wins[2]])
    assert "no longer running" in WP.check_programs(setup, reused, ended, running, images).reason
    # the ended program's title shown by another process
    other = programs(procs[:2] + procs[3:] + [{"pid": 30, "ppid": 4, "name": "wordpad.exe", "started": 9}],
                     [wins[0], wins[2], {"title": "b.txt - Notepad", "pid": 30, "visible": True}])
    assert "open again, of process 30" in WP.check_programs(setup, other, ended, running, images).reason
    with pytest.raises(InfrastructureError, match="no window was titled"):
        WP.check_programs(programs(procs, wins[:1]), setup, ended, running, images)


def test_started_by_the_task_manager_set_up_started():
    taskmgr = {"pid": 8, "ppid": 1, "name": "taskmgr.exe", "started": 3, "path": "C:\\windows\\system32\\taskmgr.exe"}
    setup = programs([taskmgr], [{"title": "Task Manager", "pid": 8, "visible": True}])
    child = {"pid": 9, "ppid": 8, "name": "notepad.exe", "started": 5}
    win = {"title": "a.txt - Notepad", "pid": 9, "visible": True}
    assert WP.check_started_by(setup, programs([taskmgr, child], [win]), ["a.txt - Notepad"], "notepad.exe",
                               "taskmgr.exe").passed
    # a program named taskmgr.exe that set-up did not start (a renamed copy of another program)
    fake = {"pid": 7, "ppid": 1, "name": "taskmgr.exe", "started": 4, "path": "C:\\temp\\tm\\taskmgr.exe"}
    v = WP.check_started_by(setup, programs([taskmgr, fake, child | {"ppid": 7}], [win]), ["a.txt - Notepad"],
                            "notepad.exe", "taskmgr.exe")
    assert not v.passed and "that set-up did not start" in v.reason and "C:\\temp\\tm" in v.reason
    # set-up's Task Manager ended and its id reused by the program that started Notepad
    v = WP.check_started_by(setup, programs([taskmgr | {"started": 4}, child], [win]), ["a.txt - Notepad"],
                            "notepad.exe", "taskmgr.exe")
    assert not v.passed
    # a Notepad that was already running at set-up
    early = programs([taskmgr, child], [{"title": "Task Manager", "pid": 8, "visible": True}, win])
    v = WP.check_started_by(early, programs([taskmgr, child], [win]), ["a.txt - Notepad"], "notepad.exe",
                            "taskmgr.exe")
    assert not v.passed and "already running at set-up" in v.reason
    v = WP.check_started_by(setup, programs([taskmgr, child | {"ppid": 3}, {"pid": 3, "ppid": 1, "name": "cmd.exe"}],
                                            [win]), ["a.txt - Notepad"], "notepad.exe", "taskmgr.exe")
    assert "started by cmd.exe" in v.reason
    assert "no such window" in WP.check_started_by(setup, programs([taskmgr], []), ["x - Notepad"], "notepad.exe",
                                                   "taskmgr.exe").reason


def test_the_probe_reads_files_folders_links_and_hard_links(tmp_path):
    (tmp_path / "d" / "e").mkdir(parents=True)
    (tmp_path / "d" / "f.txt").write_bytes(b"abc")
    os.link(tmp_path / "d" / "f.txt", tmp_path / "d" / "g.txt")
    os.symlink(tmp_path / "d" / "f.txt", tmp_path / "d" / "h.txt")
    tree = PROBE_NS["tree"](str(tmp_path / "d"))
    assert tree["f.txt"]["sha256"] == hashlib.sha256(b"abc").hexdigest() and tree["f.txt"]["nlink"] == 2
    assert tree["e"]["dir"] and tree["h.txt"]["link"] and PROBE_NS["entry"](str(tmp_path / "x")) == {"exists": False}
    assert "hard link" in F.check_file(WINDOWS, P.as_entry(tree["g.txt"]), None, "copy")
    assert "a link" in F.check_file(WINDOWS, P.as_entry(tree["h.txt"]), None, "copy")


def test_the_probe_script_runs_and_writes_its_answer(tmp_path):
    """The probe as the device runs it (here with the host's Python: files only, no ctypes calls)."""
    import subprocess
    import sys

    (tmp_path / "probe.py").write_text(P.PROBE)
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "x.txt").write_text("x")
    (tmp_path / "req.json").write_text(json.dumps({"entries": [str(tmp_path / "a" / "x.txt")],
                                                   "trees": [str(tmp_path / "a"), str(tmp_path / "none")]}))
    subprocess.run([sys.executable, "-I", str(tmp_path / "probe.py"), str(tmp_path / "req.json"),
                    str(tmp_path / "out.json")], check=True)
    out = json.loads((tmp_path / "out.json").read_text())
    assert out["entries"][str(tmp_path / "a" / "x.txt")]["size"] == 1
    assert list(out["trees"][str(tmp_path / "a")]) == ["x.txt"] and out["trees"][str(tmp_path / "none")] is None
    (tmp_path / "a" / "sub").mkdir()
    (tmp_path / "a" / "sub" / ".y.txt").write_text("y")  # a hidden name, a folder down: found
    (tmp_path / "a" / "z.txt").write_text("zz")  # another size: not hashed, not reported
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "elsewhere" / "w.txt").write_text("w")
    (tmp_path / "a" / "linked").symlink_to(tmp_path / "elsewhere")  # a link below the root: not entered
    (tmp_path / "req.json").write_text(json.dumps({"search": [str(tmp_path / "a"), str(tmp_path / "none")],
                                                   "sizes": [1]}))
    subprocess.run([sys.executable, "-I", str(tmp_path / "probe.py"), str(tmp_path / "req.json"),
                    str(tmp_path / "out.json")], check=True)
    found = json.loads((tmp_path / "out.json").read_text())["found"]
    assert sorted(found) == [str(tmp_path / "a" / "sub" / ".y.txt"), str(tmp_path / "a" / "x.txt")]
    assert found[str(tmp_path / "a" / "x.txt")]["sha256"] == hashlib.sha256(b"x").hexdigest()
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
    assert "trash entries none" in reasons(check(dev, sub, base))
    trash_entry(dev, "C:\\Users\\user\\Downloads\\other.txt", original, record)  # another file's entry
    assert "trash entries" in reasons(check(dev, sub, base))
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
    assert "trash entries none" in reasons(check(dev, sub, base))


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
    dev.attrs[copy] = HIDDEN  # the copy made, but hidden
    assert "copy is hidden" in reasons(check(dev, sub, base))
    dev.attrs.pop(copy)
    dev.attrs[src] = HIDDEN | SYSTEM  # the original hidden after the copy
    assert "original is hidden" in reasons(check(dev, sub, base))
    dev.attrs.pop(src)
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
    os.remove(src)
    os.symlink(copy, src)  # moved, and a link to it left where the original was
    assert "original is a link" in reasons(check(dev, sub, base))


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


# -- Edge's download and PowerShell's hash (kvm-only templates, judged by the neutral evaluators) -----------------
def test_edge_download_is_a_copy_of_the_served_file(dev):
    """edge_download_file: `file_copied` of the file served from the drive, as Chromium's download on Ubuntu."""
    sub = instance("edge_download_file", file_name="contacts.csv", seed=5)
    served = generate("people_table", {"seed": 5, "rows": 6, "format": "csv"})
    dev.upload(r"S:\data\contacts.csv", served)
    base = capture(dev, sub)
    out = dev.host(sub.output["download"].value)
    assert "no copy" in reasons(check(dev, sub, base))
    dev.upload(sub.output["download"].value, served)
    assert passed(check(dev, sub, base)) and passed(check(dev, sub, {}))
    for data in (b"<!doctype html><html>Shared files</html>", b"not,this,one\r\n", served[:60]):  # its negatives
        out.write_bytes(data)
        assert "copy holds other content" in reasons(check(dev, sub, base))
    out.write_bytes(served)
    dev.attrs[out] = HIDDEN  # downloaded, then hidden (a negative)
    assert "copy is hidden" in reasons(check(dev, sub, base))
    dev.attrs.pop(out)
    junk = b"name,value\r\n"  # the same junk over the served file and into Downloads (a negative)
    dev.upload(r"S:\data\contacts.csv", junk)
    out.write_bytes(junk)
    assert "the original changed" in reasons(check(dev, sub, base))


def test_powershell_hash_is_of_the_file_as_set_up_and_the_file_kept(dev):
    """powershell_file_hash: `file_text_is_digest` with `file`, the answer in any encoding PowerShell writes."""
    sub = instance("powershell_file_hash", file=r"C:\Users\user\Documents\orders.csv", seed=17)
    base = set_up(dev, sub)
    src, out = dev.host(sub.input["file"].value), sub.output["out"].value
    data = src.read_bytes()
    digest = hashlib.sha256(data).hexdigest()
    assert "no file" in reasons(check(dev, sub, base))
    dev.upload(out, b"\xff\xfe" + (digest.upper() + "\r\n").encode("utf-16-le"))  # Get-FileHash's Hash | Out-File
    assert passed(check(dev, sub, base))
    dev.upload(out, digest.encode())
    assert passed(check(dev, sub, base))  # lower case, ANSI: the same hash
    assert passed(check(dev, sub, {}))  # fed by an upstream subtask: hashed as it is
    for text, needle in [("orders.csv", "'orders.csv'"), (hashlib.md5(data).hexdigest().upper(), "just the sha256"),
                         (digest[:32], digest[:32]), (digest + " orders.csv", "orders.csv")]:
        dev.upload(out, text.encode())
        assert needle in reasons(check(dev, sub, base)), text
    dev.upload(out, digest.encode("utf-16-le"))  # UTF-16 without its mark: no text a Windows program writes
    assert "not a text file" in reasons(check(dev, sub, base))
    dev.upload(out, digest.encode())
    dev.attrs[src] = HIDDEN  # the hash written, the file hidden (a negative)
    assert "orders.csv: it is hidden" in reasons(check(dev, sub, base))
    dev.attrs.pop(src)
    src.write_bytes(data + b"extra\r\n")  # the hash of the file as given, then the file edited (a negative)
    assert "orders.csv: it holds other content" in reasons(check(dev, sub, base))
    dev.upload(out, hashlib.sha256(data + b"extra\r\n").hexdigest().encode())  # the hash of the edited file
    assert not passed(check(dev, sub, base))


def test_text_answers_in_every_encoding_a_windows_program_writes(dev):
    """`file_text_equals` reads the answer with the platform's decoder (what `text_file_holds` did on Windows)."""
    path = "C:\\Users\\user\\Desktop\\n.txt"
    for data in ("7\r\n".encode("utf-16-le"), b"\xff\xfe" + "7\r\n".encode("utf-16-le"), b"7\r\n",
                 b"\xef\xbb\xbf7\n", b"  7  ", "\u00e9".encode("cp1252")):
        dev.upload(path, data)
        state = FinalState(platform="windows", devices={"windows": dev})
        verdict = get_evaluator("file_text_equals")(state, path=path, expected="\u00e9" if b"\xe9" in data else "7")
        if data.startswith("7".encode("utf-16-le")):  # UTF-16 without a mark is no text a Windows program writes
            assert not verdict.passed and "not a text file" in verdict.reason
        else:
            assert verdict.passed, (data, verdict.reason)


def test_a_deleted_file_leaves_no_copy_hidden_or_not_outside_the_recycle_bin(dev):
    """The neutral `file_deleted` on Windows: the probe's search of the user's places (`PlatformSpec.user_roots`:
    C:\\Users, C:\\temp, the drive S:\\) for its bytes; the Recycle Bin's data is the trash."""
    path = "C:\\Users\\user\\Desktop\\plan.txt"
    kept = "C:\\Users\\user\\Desktop\\keep.txt"
    dev.upload(path, b"the plan\r\n")
    dev.upload(kept, b"keep me\r\n")
    base = {path: b"the plan\r\n", kept: b"keep me\r\n"}
    state = FinalState(platform="windows", devices={"windows": dev},
                       baselines={("windows", p): b for p, b in base.items()})

    def deleted():
        state._files.clear()
        return get_evaluator("file_deleted")(state, path=path, kept=[kept])

    assert "still there (a file of 10 bytes)" in deleted().reason
    dev.attrs[dev.host(path)] = HIDDEN  # "deleted": hidden in place
    assert "still there (a file of 10 bytes (hidden))" in deleted().reason
    bin_data = dev.host("C:\\$Recycle.Bin\\S-1-5-21-1000\\$RAB12CD.txt")
    bin_data.parent.mkdir(parents=True)
    os.rename(dev.host(path), bin_data)  # Explorer's delete: the data in the drive's Recycle Bin
    assert deleted().passed
    for where, attrs in (("C:\\Users\\user\\AppData\\Local\\x.tmp", HIDDEN | SYSTEM), ("S:\\data\\plan.txt", 0),
                         ("C:\\temp\\plan.txt", 0), ("C:\\Users\\Public\\Documents\\plan.txt", 0)):
        dev.upload(where, b"the plan\r\n")
        dev.attrs[dev.host(where)] = attrs
        found = deleted().reason
        assert f"its content still at {where}" in found and "not deleted" in found, found
        os.remove(dev.host(where))
    dev.upload(kept, b"")
    assert f"{kept}: it holds other content" in deleted().reason


# -- hidden and system entries count ----------------------------------------------------------------------------
EXPLORER_INI = "\r\n[.ShellClassInfo]\r\nLocalizedResourceName=@%SystemRoot%\\system32\\shell32.dll,-21770\r\n".encode("utf-16")


def sorted_inbox(dev: WinHost) -> tuple[Subtask, dict, Path]:
    """winefile_sort_by_type set up and sorted as the file manager does."""
    sub = instance("winefile_sort_by_type", folder="C:\\Users\\user\\Documents\\inbox", ext=".csv", sub="by_type")
    folder = dev.host(sub.input["folder"].value)
    folder.mkdir(parents=True)
    for n in ("alpha", "beta", "gamma"):
        (folder / f"{n}.csv").write_bytes(f"{n} of .csv\r\n".encode())
    for e in (".png", ".txt", ".pdf"):
        (folder / f"other{e}").write_bytes(f"other {e}\r\n".encode())
    base = capture(dev, sub)
    (folder / "by_type").mkdir()
    for n in ("alpha", "beta", "gamma"):
        os.rename(folder / f"{n}.csv", folder / "by_type" / f"{n}.csv")
    assert passed(check(dev, sub, base))
    return sub, base, folder


def test_sorting_counts_hidden_leftovers_and_extras(dev):
    sub, base, folder = sorted_inbox(dev)
    shutil.copy(folder / "by_type" / "alpha.csv", folder / "alpha.csv")  # the original kept, hidden
    dev.attrs[folder / "alpha.csv"] = HIDDEN
    assert "alpha.csv (hidden) still in the folder" in reasons(check(dev, sub, base))
    os.rename(folder / "alpha.csv", folder / "~alpha.tmp")  # kept under another name, hidden and system
    dev.attrs[folder / "~alpha.tmp"] = HIDDEN | SYSTEM
    assert "a copy of alpha.csv left at ~alpha.tmp (hidden, system)" in reasons(check(dev, sub, base))
    (folder / "~alpha.tmp").unlink()
    (folder / "by_type" / "notes.txt").write_bytes(b"x")  # a hidden extra file in the sorted folder
    dev.attrs[folder / "by_type" / "notes.txt"] = HIDDEN
    assert "by_type also holds ['notes.txt (hidden)']" in reasons(check(dev, sub, base))
    (folder / "by_type" / "notes.txt").unlink()
    dev.attrs[folder / "by_type" / "beta.csv"] = HIDDEN  # a moved file hidden in its new place
    assert "beta.csv in by_type is hidden" in reasons(check(dev, sub, base))


def test_only_explorers_own_desktop_ini_is_passed_over(dev):
    sub, base, folder = sorted_inbox(dev)
    ini = folder / "by_type" / "desktop.ini"
    ini.write_bytes(EXPLORER_INI)
    dev.attrs[ini] = HIDDEN | SYSTEM
    assert passed(check(dev, sub, base)), reasons(check(dev, sub, base))  # what Explorer writes there
    dev.attrs[ini] = HIDDEN  # not marked system: not Explorer's
    assert "also holds ['desktop.ini (hidden)']" in reasons(check(dev, sub, base))
    ini.write_bytes(b"alpha of .csv\r\n")  # a moved file's bytes under Explorer's name and marks
    dev.attrs[ini] = HIDDEN | SYSTEM
    assert "desktop.ini (hidden, system)" in reasons(check(dev, sub, base))
    ini.write_bytes(b"\x00" * 10)
    (folder / "by_type" / "Thumbs.db").write_bytes(b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1" + bytes(504))
    dev.attrs[folder / "by_type" / "Thumbs.db"] = HIDDEN | SYSTEM
    ini.unlink()
    assert passed(check(dev, sub, base))


def test_moves_and_trash_count_hidden_originals_and_copies(dev):
    sub = instance("explorer_rename_file", source_file="C:\\Users\\user\\Desktop\\ideas.txt",
                   new_stem="final_version")
    base = set_up(dev, sub)
    src, dest = dev.host(sub.input["source_file"].value), dev.host(sub.output["renamed_file"].value)
    shutil.copy(src, dest)  # renamed, and the original kept hidden
    dev.attrs[src] = HIDDEN
    assert "original still at its old place (a file of 94 bytes (hidden))" in reasons(check(dev, sub, base))
    os.rename(src, src.parent / ".ideas.bak")  # ... or kept as a hidden copy under another name
    dev.attrs[src.parent / ".ideas.bak"] = HIDDEN
    assert "a copy of ideas.txt left at .ideas.bak (hidden)" in reasons(check(dev, sub, base))
    (src.parent / "stash").mkdir()
    os.rename(src.parent / ".ideas.bak", src.parent / "stash" / "x.txt")  # ... or in a sub-folder of the old one
    assert "a copy of ideas.txt left at stash\\x.txt" in reasons(check(dev, sub, base))
    (src.parent / "stash" / "x.txt").unlink()
    assert passed(check(dev, sub, base))

    sub = instance("explorer_trash_file", doomed="C:\\Users\\user\\Downloads\\old_invoice.txt", token="owl-1")
    base = set_up(dev, sub)
    doomed = dev.host(sub.input["doomed"].value)
    original = doomed.read_bytes()
    trash_entry(dev, sub.input["doomed"].value, original)
    dev.attrs[doomed] = HIDDEN  # "deleted": an entry in the bin, the file still there, hidden
    assert "it still there (a file of" in reasons(check(dev, sub, base))
    os.rename(doomed, doomed.parent / "old_invoice.tmp")
    assert "a copy of old_invoice.txt left at old_invoice.tmp" in reasons(check(dev, sub, base))


def _logs_to_rename(dev):
    """cmd_rename_extension set up on `dev`: the subtask, its baseline and the host path of its logs folder."""
    sub = instance("cmd_rename_extension", folder="C:\\Users\\user\\Documents\\logs", old_ext=".log",
                   new_ext=".txt", token="owl-5")
    return sub, set_up(dev, sub), dev.host(sub.input["folder"].value)


def test_exact_folders_count_hidden_entries(dev):
    sub, base, folder = _logs_to_rename(dev)
    for n in ("alpha", "beta", "gamma"):
        shutil.copy(folder / f"{n}.log", folder / f"{n}.txt")
        dev.attrs[folder / f"{n}.log"] = HIDDEN  # renamed copies; the old files kept, hidden
    assert "alpha.log (hidden) still there" in reasons(check(dev, sub, base))
    sub = instance("cmd_copy_tree", source="C:\\Users\\user\\Documents\\clients",
                   target="C:\\Users\\user\\Desktop\\skeleton", a="finance", b="q1", c="scans")
    base = set_up(dev, sub)
    src, dst = dev.host(sub.input["source"].value), dev.host(sub.input["target"].value)
    for d in ("finance/q1/final", "scans/old"):
        (src / d).mkdir(parents=True, exist_ok=True)
        (dst / d).mkdir(parents=True)
    assert passed(check(dev, sub, base))
    (dst / "scans" / "list.txt").write_bytes(b"scans\r\n")  # a file copied too, hidden
    dev.attrs[dst / "scans" / "list.txt"] = HIDDEN
    assert "also ['scans\\\\list.txt (hidden)']" in reasons(check(dev, sub, base))
    (dst / "scans" / "list.txt").unlink()
    (src / "scans" / "notes.tmp").write_bytes(b"x")  # something added to the source, hidden
    dev.attrs[src / "scans" / "notes.tmp"] = HIDDEN
    assert "notes.tmp (hidden)" in reasons(check(dev, sub, base))


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
    base = set_up(dev, sub)
    listing = sub.output["listing"].value
    assert listing == "C:\\Users\\user\\Documents\\invoices_files.txt"
    assert "no file" in reasons(check(dev, sub, base))
    dev.upload(listing, b"IMG_123.png\r\nnotes_owl.md\r\nowl_1.txt\r\nowl_2.csv\r\n")  # dir /b /a-d
    assert passed(check(dev, sub, base))
    dev.upload(listing, "IMG_123.png\r\nnotes_owl.md\r\nowl_1.txt\r\nowl_2.csv\r\n".encode("utf-16"))
    assert passed(check(dev, sub, base))  # a UTF-16 listing (cmd /u) reads the same
    with pytest.raises(InfrastructureError, match="no set-up snapshot"):
        check(dev, sub, {})  # the harness always takes it; without it nothing can be said
    dev.upload(listing, b"IMG_123.png\r\nnotes_owl.md\r\nold\r\nowl_1.txt\r\nowl_2.csv\r\n")  # negative: dir /b
    assert "other lines ['old']" in reasons(check(dev, sub, base))
    dev.upload(listing, b"owl_1.txt\r\n")  # negative: only the .txt files
    assert "missing" in reasons(check(dev, sub, base))
    dev.upload(listing, b" Volume in drive C has no label.\r\n Directory of C:\\x\r\n"
               b"11/24/2026  5:42 AM  3 owl_1.txt\r\n")
    assert "missing" in reasons(check(dev, sub, base))  # negative: the full dir output


@pytest.mark.parametrize("change,reason", [
    (lambda d, f: (f / "owl_2.csv").unlink(), "owl_2.csv gone"),
    (lambda d, f: (f / "owl_1.txt").write_bytes(b"edited"), "owl_1.txt changed (content)"),
    (lambda d, f: d.attrs.__setitem__(f / "notes_owl.md", HIDDEN), "notes_owl.md changed (hidden)"),
    (lambda d, f: ((f / "listing.tmp").write_bytes(b"x"), d.attrs.__setitem__(f / "listing.tmp", HIDDEN)),
     "added ['listing.tmp (hidden)']"),
    (lambda d, f: (f / "old" / "hidden_owl.txt").unlink(), "hidden_owl.txt gone"),
])
def test_list_files_leaves_the_listed_folder_as_it_was(dev, change, reason):
    """The listing is right, but the listed folder was changed on the way (class: what a task must not change)."""
    sub = instance("cmd_list_files", folder="C:\\Users\\user\\Documents\\invoices", stem="owl", n=123)
    base = set_up(dev, sub)
    dev.upload(sub.output["listing"].value, b"IMG_123.png\r\nnotes_owl.md\r\nowl_1.txt\r\nowl_2.csv\r\n")
    assert passed(check(dev, sub, base))
    change(dev, dev.host(sub.input["folder"].value))
    assert reason in reasons(check(dev, sub, base))


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


def test_count_files_leaves_the_counted_folder_as_it_was(dev):
    """powershell_count_files (real Windows only; its evaluator runs here): the number PowerShell writes, and the
    folder whose files were counted as the set-up made it."""
    sub = instance("powershell_count_files", folder="C:\\Users\\user\\Desktop\\scans", count=4, name="count")
    folder = dev.host(sub.input["folder"].value)
    (folder / "archive" / "2023").mkdir(parents=True)
    for i in range(1, 5):  # what the set-up command makes
        (folder / f"item_{i}.txt").write_bytes(f"item {i}\r\n".encode())
    (folder / "archive" / "old_1.txt").write_bytes(b"old\r\n")
    (folder / "archive" / "2023" / "older.txt").write_bytes(b"older\r\n")
    base = capture(dev, sub)
    out = sub.output["out"].value
    assert "no file" in reasons(check(dev, sub, base))
    dev.upload(out, "4\r\n".encode("utf-16"))  # Out-File: UTF-16 LE with a byte order mark
    assert passed(check(dev, sub, base)), reasons(check(dev, sub, base))
    dev.upload(out, b"6\r\n")  # negative: the sub-folders' files counted too
    assert "just the number 4" in reasons(check(dev, sub, base))
    dev.upload(out, b"4")
    (folder / "item_2.txt").unlink()  # negative: the right number, then a counted file deleted
    assert "item_2.txt gone" in reasons(check(dev, sub, base))
    (folder / "item_2.txt").write_bytes(b"item 2\r\n")
    dev.attrs[folder / "archive" / "2023" / "older.txt"] = HIDDEN
    assert "older.txt changed (hidden)" in reasons(check(dev, sub, base))


def test_rename_extension(dev):
    sub, base, folder = _logs_to_rename(dev)
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
    notepad_a, notepad_b = {"pid": 5, "ppid": 1, "name": "notepad.exe", "started": 10}, \
        {"pid": 6, "ppid": 1, "name": "notepad.exe", "started": 11}
    regedit, taskmgr = {"pid": 7, "ppid": 1, "name": "regedit.exe", "started": 12}, \
        {"pid": 8, "ppid": 1, "name": "taskmgr.exe", "started": 13}
    dev.processes = [notepad_a, notepad_b, regedit, taskmgr]
    target = {"title": "budget.txt - Notepad", "pid": 5, "visible": True}
    keep = {"title": "plans.txt - Notepad", "pid": 6, "visible": True}
    reg = {"title": "Registry Editor", "pid": 7, "visible": True}
    dev.windows = [target, keep, reg]
    base = set_up(dev, sub)  # the processes and windows right after set-up
    assert "'budget.txt - Notepad' still running" in reasons(check(dev, sub, base))
    dev.windows = [target | {"visible": False}, keep, reg]  # negative: its window hidden
    assert "its window hidden" in reasons(check(dev, sub, base))
    dev.windows, dev.processes = [keep, reg], [notepad_b, regedit, taskmgr]  # End Task
    assert passed(check(dev, sub, base))
    dev.windows, dev.processes = [target, reg], [notepad_a, regedit, taskmgr]  # negative: the other one ended
    assert "'plans.txt - Notepad' no longer running" in reasons(check(dev, sub, base))
    dev.windows, dev.processes = [reg], [regedit, taskmgr]  # negative: every Notepad ended
    assert "0 notepad.exe" in reasons(check(dev, sub, base))
    # negative: every Notepad ended and plans.txt opened again — right titles, right counts, another process
    dev.windows = [keep | {"pid": 9}, reg]
    dev.processes = [{"pid": 9, "ppid": 1, "name": "notepad.exe", "started": 20}, regedit, taskmgr]
    assert "started again" in reasons(check(dev, sub, base))
    dev.processes = [notepad_b | {"started": 20}, regedit, taskmgr]  # ... given the old id again (Wine reuses ids)
    dev.windows = [keep, reg]
    assert "'plans.txt - Notepad' no longer running" in reasons(check(dev, sub, base))


def test_the_harness_keeps_set_up_snapshots_for_the_evaluation(dev):
    """capture_baselines takes the evaluators' set-up snapshots beside the file baselines, and evaluate_subtasks
    hands them to the subtask: the program that must keep running is judged against the process set-up started."""
    from jarvis_pytest.harness.evaluation import capture_baselines, evaluate_subtasks

    sub = instance("taskmgr_end_program", target_doc="C:\\Users\\user\\Documents\\budget.txt",
                   keep_doc="C:\\Users\\user\\Documents\\plans.txt")
    regedit = {"pid": 7, "ppid": 1, "name": "regedit.exe", "started": 12}
    keep = {"pid": 6, "ppid": 1, "name": "notepad.exe", "started": 11}
    dev.processes = [{"pid": 5, "ppid": 1, "name": "notepad.exe", "started": 10}, keep, regedit]
    dev.windows = [{"title": "budget.txt - Notepad", "pid": 5, "visible": True},
                   {"title": "plans.txt - Notepad", "pid": 6, "visible": True},
                   {"title": "Registry Editor", "pid": 7, "visible": True}]
    baselines = capture_baselines([sub], {"windows": dev})
    assert any(key[1].startswith("<set-up snapshot>") for key in baselines)
    dev.processes, dev.windows = [keep, regedit], dev.windows[1:]  # End Task
    (verdict,) = evaluate_subtasks([sub], {"windows": dev}, None, baselines)
    assert verdict.passed, verdict.evaluators
    dev.processes = [keep | {"pid": 9, "started": 20}, regedit]  # every Notepad ended, plans.txt opened again
    dev.windows = [{"title": "plans.txt - Notepad", "pid": 9, "visible": True}, dev.windows[1]]
    (verdict,) = evaluate_subtasks([sub], {"windows": dev}, None, baselines)
    assert not verdict.passed and "started again" in verdict.evaluators[0].reason


def test_new_task(dev):
    sub = instance("taskmgr_new_task", doc="C:\\Users\\user\\Desktop\\readme.txt", token="owl-3")
    taskmgr = {"pid": 8, "ppid": 1, "name": "taskmgr.exe", "started": 1}
    dev.processes, dev.windows = [taskmgr], [{"title": "Task Manager", "pid": 8, "visible": True}]
    base = set_up(dev, sub)
    dev.processes = [taskmgr, {"pid": 9, "ppid": 8, "name": "notepad.exe", "started": 2},
                     {"pid": 3, "ppid": 2, "name": "cmd.exe", "started": 3},
                     {"pid": 10, "ppid": 3, "name": "notepad.exe", "started": 4},
                     {"pid": 11, "ppid": 1, "name": "taskmgr.exe", "started": 5, "path": "C:\\temp\\tm\\taskmgr.exe"},
                     {"pid": 12, "ppid": 11, "name": "notepad.exe", "started": 6}]
    dev.windows = []
    assert "no such window" in reasons(check(dev, sub, base))
    dev.windows = [{"title": "readme.txt - Notepad", "pid": 10, "visible": True}]  # negative: from a prompt
    assert "started by cmd.exe" in reasons(check(dev, sub, base))
    dev.windows = [{"title": "Untitled - Notepad", "pid": 9, "visible": True}]  # negative: without the file
    assert "no such window" in reasons(check(dev, sub, base))
    dev.windows = [{"title": "readme.txt - Notepad", "pid": 12, "visible": True}]  # negative: a fake taskmgr.exe
    assert "that set-up did not start" in reasons(check(dev, sub, base))
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
    out = P.probe(state, entries=[str(target / "a.txt")], trees=[str(target)])
    assert out["entries"][str(target / "a.txt")]["sha256"] == hashlib.sha256(b"abc").hexdigest()
    assert set(out["trees"][str(target)]) == {"a.txt", "sub"}
    assert dev.commands[0].startswith(f'"{P.PYTHON}" -I "{P.PROBE_DIR}\\') and dev.commands[1].startswith("rmdir")
    probe_root = dev.host(P.PROBE_DIR)
    assert not any(probe_root.iterdir())  # its folder removed
    with pytest.raises(InfrastructureError, match="probe failed on the device"):
        P.probe(state, processes=True)  # no Windows API on this host: the probe's own error, reported
    assert not any(probe_root.iterdir())
