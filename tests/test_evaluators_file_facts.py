"""The platform-neutral file facts (`evaluators/file_facts.py`): the POSIX shell reader run on host files with the
host's GNU tools and with nothing but toybox's applets (what Android has), and which desktop files folder checks
pass over (`shell_made`). No container."""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
from dataclasses import replace
from pathlib import Path

import pytest

from jarvis_pytest.devices.base import CommandResult
from jarvis_pytest.devices.platforms import PLATFORMS
from jarvis_pytest.evaluators.file_facts import Entry, read_facts, shell_made
from jarvis_pytest.evaluators.state import FinalState

TOYBOX_APPLETS = ("stat", "find", "sha256sum", "cut", "sed", "head")


class ShellHost:
    """A POSIX device whose files are the host's; commands run in /bin/sh with `path` as PATH."""

    def __init__(self, path: str):
        self.path = path

    def run(self, command: str, *, timeout: float = 60.0, user: str | None = None) -> CommandResult:
        res = subprocess.run(["/bin/sh", "-c", command], capture_output=True, text=True, timeout=timeout,
                             env={"PATH": self.path})
        return CommandResult(res.returncode, res.stdout, res.stderr)

    def exists(self, path: str) -> bool:
        return os.path.lexists(path)

    def download(self, path: str) -> bytes:
        return Path(path).read_bytes()


def toybox_path(tmp_path: Path) -> str:
    toybox = shutil.which("toybox")
    if not toybox:
        pytest.skip("toybox not installed: apt-get install toybox")
    bin_dir = tmp_path / "toybox-bin"
    bin_dir.mkdir()
    for applet in TOYBOX_APPLETS:
        (bin_dir / applet).symlink_to(toybox)
    return str(bin_dir)


@pytest.mark.parametrize("tools", ["gnu", "toybox"])
def test_posix_facts_of_files_folders_links_hidden_names_and_the_trash(tmp_path, monkeypatch, tools):
    path = os.environ["PATH"] if tools == "gnu" else toybox_path(tmp_path)
    root = tmp_path / "d"
    (root / "sub" / "deeper").mkdir(parents=True)
    (root / "a b.txt").write_bytes(b"abc")
    (root / ".hidden").write_bytes(b"")
    os.link(root / "a b.txt", root / "sub" / "second name")
    (root / "link").symlink_to("/etc/hostname")
    (root / "sub" / "deeper" / "x").write_bytes(b"x")
    (root / "odd\nname").write_bytes(b"y")  # a line break in a name: listed, never lost
    trash = tmp_path / "Trash"
    (trash / "info").mkdir(parents=True), (trash / "files").mkdir()
    (trash / "info" / "gone.txt.trashinfo").write_text("[Trash Info]\nPath=/home/user/my%20gone.txt\n")
    (trash / "files" / "gone.txt").write_bytes(b"gone")
    monkeypatch.setitem(PLATFORMS, "ubuntu", replace(PLATFORMS["ubuntu"], trash=str(trash)))
    state = FinalState(platform="ubuntu", devices={"ubuntu": ShellHost(path)})
    facts = read_facts(state, entries=[str(root / "a b.txt"), str(root / "none")],
                       trees=[str(root), str(tmp_path / "no folder")], trash=True)
    a = facts.entries[str(root / "a b.txt")]
    assert a.kind == "file" and a.size == 3 and a.links == 2 and a.sha256.startswith("ba7816bf")
    assert not facts.entries[str(root / "none")].exists and facts.trees[str(tmp_path / "no folder")] is None
    tree = facts.trees[str(root)]
    assert tree[".hidden"].hidden and not tree["a b.txt"].hidden and tree["link"].kind == "link"
    assert tree["sub"].kind == "dir" and tree["sub/second name"].links == 2 and "sub/deeper/x" in tree
    assert {"odd", "name"} <= set(tree) and tree["name"].exists  # the odd name: two lines, both count
    assert len(tree) == 9
    assert facts.trash == [("/home/user/my gone.txt", Entry(exists=True, kind="file", size=4,
                                                            sha256=hashlib.sha256(b"gone").hexdigest()))]
    shallow = read_facts(state, trees=[str(root)], depth=1).trees[str(root)]
    assert "sub" in shallow and "sub/second name" not in shallow


@pytest.mark.parametrize("tools", ["gnu", "toybox"])
def test_posix_search_finds_files_of_a_size_at_any_depth_through_a_linked_root(tmp_path, tools):
    """A search (`read_facts(search=, sizes=)`): every regular file of an asked size under the folders, hidden ones
    and second names too; a folder given as a link (Android's /sdcard) is searched, links below it are not
    followed; other sizes are not reported."""
    path = os.environ["PATH"] if tools == "gnu" else toybox_path(tmp_path)
    real = tmp_path / "storage"
    (real / "Pictures" / ".hidden dir").mkdir(parents=True)
    (real / "Pictures" / "a.png").write_bytes(b"12345")
    (real / "Pictures" / ".hidden dir" / "b").write_bytes(b"abcde")
    os.link(real / "Pictures" / "a.png", real / "second")
    (real / "Pictures" / "small").write_bytes(b"123")
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "c").write_bytes(b"zzzzz")
    (real / "linked").symlink_to(outside)
    (real / "file link").symlink_to(outside / "c")
    (tmp_path / "sdcard").symlink_to(real)
    state = FinalState(platform="ubuntu", devices={"ubuntu": ShellHost(path)})
    sd = str(tmp_path / "sdcard")
    facts = read_facts(state, search=[sd, str(tmp_path / "no folder")], sizes=[5, 99])
    assert sorted(facts.found) == [f"{sd}/Pictures/.hidden dir/b", f"{sd}/Pictures/a.png", f"{sd}/second"]
    assert facts.found[f"{sd}/second"].links == 2 and facts.found[f"{sd}/second"].sha256 == hashlib.sha256(
        b"12345").hexdigest()
    assert facts.found[f"{sd}/Pictures/.hidden dir/b"].kind == "file"
    assert read_facts(state, entries=[sd]).found is None  # no search asked


def test_only_the_desktops_own_files_are_passed_over():
    windows, ubuntu = PLATFORMS["windows"], PLATFORMS["ubuntu"]
    ini = "\r\n[.ShellClassInfo]\r\nIconResource=C:\\x.dll,3\r\n".encode("utf-16")
    explorer = Entry(exists=True, kind="file", size=len(ini), hidden=True, system=True, head=ini)
    assert shell_made(windows, "sub\\desktop.ini", explorer)
    assert shell_made(windows, "DESKTOP.INI", explorer)  # names compared as Windows does
    assert not shell_made(ubuntu, "desktop.ini", explorer)  # no such files on Ubuntu
    assert not shell_made(windows, "notes.ini", explorer)
    assert not shell_made(windows, "desktop.ini", replace(explorer, system=False))
    text = b"alpha of .csv\r\n"
    assert not shell_made(windows, "desktop.ini", replace(explorer, head=text, size=len(text)))
    assert not shell_made(windows, "desktop.ini", replace(explorer, size=len(ini) + 5000))  # more than its head
    ole = b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1" + bytes(100)
    assert shell_made(windows, "Thumbs.db", Entry(exists=True, kind="file", size=4096, hidden=True, system=True,
                                                  head=ole))
    assert not shell_made(windows, "Thumbs.db", Entry(exists=True, kind="file", size=3, hidden=True, system=True,
                                                      head=b"abc"))
