"""The file evaluators of the Thunar, terminal and Mousepad templates, run on real files (no container): a host
folder stands in for the device, its commands run in a host shell. For each template the result a careful person
leaves passes, and each near-miss state of the template's `negatives` fails with a reason naming what is wrong.
Set-up content and instances come from the templates themselves (rendered with fixed slot values)."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
from dataclasses import replace
from pathlib import Path

import pytest

from jarvis_pytest.devices.base import CommandResult
from jarvis_pytest.devices.platforms import PLATFORMS
from jarvis_pytest.evaluators import get_evaluator
from jarvis_pytest.evaluators.files import digest_text, text_lines
from jarvis_pytest.evaluators.text import check_line_endings
from jarvis_pytest.evaluators.state import FinalState
from jarvis_pytest.generators import generate
from jarvis_pytest.tasks.instances import materialise
from jarvis_pytest.tasks.model import Subtask, TaskTemplate

LIBRARY = Path(__file__).resolve().parents[1] / "tasks" / "ubuntu"


class HostDevice:
    """A device whose files are the host's and whose commands run in a host shell."""

    platform = "ubuntu"

    def run(self, command: str, *, timeout: float = 60.0, user: str | None = None) -> CommandResult:
        res = subprocess.run(["bash", "-c", command], capture_output=True, text=True, timeout=timeout)
        return CommandResult(res.returncode, res.stdout, res.stderr)

    def download(self, path: str) -> bytes:
        return Path(path).read_bytes()

    def exists(self, path: str) -> bool:
        return os.path.lexists(path)


def evaluate(spec: dict, baselines: dict[str, bytes] | None = None):
    """Run one rendered evaluator spec on the host, with `baselines` (path → bytes at set-up)."""
    state = FinalState(platform="ubuntu", devices={"ubuntu": HostDevice()},
                       baselines={("ubuntu", p): b for p, b in (baselines or {}).items()})
    return get_evaluator(spec["func"])(state, **spec["args"])


def instance(name: str, tmp: Path, **values) -> Subtask:
    """The template `name` materialised with `values`, every /home/user path in it moved under the host folder
    `tmp` (so nothing is written outside it)."""
    tpl = TaskTemplate.model_validate(json.loads((LIBRARY / f"{name}.json").read_text()))
    text = materialise(tpl, values).model_dump_json()
    assert str(tmp) not in text
    return Subtask.model_validate_json(text.replace("/home/user/", f"{tmp}/home/user/"))


def upload_content(sub, path: str) -> bytes:
    """The bytes the set-up's upload step puts at `path` (literal content or its generator's output)."""
    for step in sub.config:
        if step.type == "upload_file" and step.path == path:
            return step.content.encode() if step.content is not None else generate(step.generator, step.args)
    raise KeyError(path)


def check(sub, baselines: dict[str, bytes]) -> list:
    return [evaluate(spec.model_dump(), baselines) for spec in sub.evaluate]


def passed(verdicts) -> bool:
    return all(v.passed for v in verdicts)


def reasons(verdicts) -> str:
    return " | ".join(v.reason for v in verdicts if not v.passed)


# -- thunar --------------------------------------------------------------------------------------------------
@pytest.fixture
def copy_task(tmp_path):
    sub = instance("thunar_copy_file", tmp_path, source="/home/user/Documents/budget_2025.txt",
                   target_dir="/home/user/Public")
    src, copy = sub.input["source"].value, sub.output["copy"].value
    os.makedirs(os.path.dirname(src)), os.makedirs(os.path.dirname(copy))
    Path(src).write_bytes(upload_content(sub, src))
    return sub, src, copy, {src: Path(src).read_bytes()}


def test_copy_passes_a_real_copy_and_rejects_links_and_a_changed_original(copy_task):
    sub, src, copy, base = copy_task
    assert not passed(check(sub, base))  # nothing copied yet
    shutil.copy2(src, copy)
    assert passed(check(sub, base))
    assert passed(check(sub, {}))  # fed by an upstream subtask: no baseline, compared as they are
    os.remove(copy)
    os.symlink(src, copy)
    assert "copy is a link, not a file" in reasons(check(sub, base))
    os.remove(copy)
    os.link(src, copy)
    assert "hard link" in reasons(check(sub, base))
    os.remove(copy)
    shutil.copy2(src, copy)
    Path(copy).write_bytes(Path(copy).read_bytes() + b"x")  # the right name, other bytes
    assert "copy holds other content" in reasons(check(sub, base))
    os.remove(copy)
    os.rename(src, copy)
    os.symlink(copy, src)  # moved, and a link to it left where the original was
    assert "original is a link" in reasons(check(sub, base))
    os.remove(src)
    shutil.copy2(copy, src)
    Path(src).write_bytes(b"")
    shutil.copy2(src, copy)
    assert "original changed" in reasons(check(sub, base))
    os.rename(src, src + ".gone")
    assert "original gone" in reasons(check(sub, base))


@pytest.mark.parametrize("template,src_slot,dest_slot,values", [
    ("thunar_move_to_new_folder", "source", "moved",
     {"source": "/home/user/Documents/minutes.txt", "folder_name": "Project X"}),
    ("thunar_rename_file", "source_file", "renamed_file",
     {"source_file": "/home/user/Desktop/ideas.txt", "new_stem": "final_version"}),
])
def test_move_and_rename_need_the_original_content_at_the_new_place(tmp_path, template, src_slot, dest_slot, values):
    sub = instance(template, tmp_path, **values)
    src, dest = sub.input[src_slot].value, sub.output[dest_slot].value
    os.makedirs(os.path.dirname(dest), exist_ok=True)
    Path(src).write_bytes(upload_content(sub, src))
    base = {src: Path(src).read_bytes()}
    assert not passed(check(sub, base))
    shutil.copy(src, dest)  # copied, not moved
    assert "copied, not moved" in reasons(check(sub, base))
    os.remove(src)
    assert passed(check(sub, base))  # the file manager's move (same bytes at the new place)
    shutil.copy(dest, os.path.join(os.path.dirname(src), "." + os.path.basename(src)))  # a hidden copy kept
    assert "a copy of" in reasons(check(sub, base)) and "(hidden)" in reasons(check(sub, base))
    os.remove(os.path.join(os.path.dirname(src), "." + os.path.basename(src)))
    Path(dest).write_bytes(b"")  # an empty file of that name, the original deleted
    assert "holds other content" in reasons(check(sub, base))
    assert passed(check(sub, {}))  # no baseline (fed input): only the move is checked
    os.remove(dest)
    os.symlink("/etc/hostname", dest)
    assert "a link, not a file" in reasons(check(sub, base))


@pytest.fixture
def sort_task(tmp_path):
    sub = instance("thunar_sort_by_type", tmp_path, folder="/home/user/Downloads", ext=".csv", sub="by_type")
    folder = sub.input["folder"].value
    subprocess.run(["bash", "-c", sub.config[0].command], check=True)  # the template's own set-up command
    spec = sub.evaluate[0].model_dump()
    base = {str(p): p.read_bytes() for p in Path(folder).iterdir()}
    return folder, spec, base


def run_in(folder: str, command: str) -> None:
    subprocess.run(["bash", "-c", command], cwd=folder, check=True)


def test_sorting_passes_the_careful_move(sort_task):
    folder, spec, base = sort_task
    assert set(os.listdir(folder)) == {"alpha.csv", "beta.csv", "gamma.csv", "other.png", "other.txt", "other.pdf"}
    assert not evaluate(spec, base).passed
    run_in(folder, "mkdir by_type && mv alpha.csv beta.csv gamma.csv by_type/")
    assert evaluate(spec, base).passed


@pytest.mark.parametrize("command,reason", [
    ("mkdir by_type && for n in alpha beta gamma; do : > by_type/$n.csv; rm $n.csv; done", "holds other content"),
    ("mkdir by_type && cp *.csv by_type/ && for n in alpha beta gamma; do mv $n.csv .$n.csv; done",
     "a copy of alpha.csv left at .alpha.csv (hidden)"),
    ("mkdir by_type && mv *.csv by_type/ && echo x > by_type/.notes", "by_type also holds ['.notes (hidden)']"),
    ("mkdir by_type && mv *.csv by_type/ && mv other.png other.txt by_type/", "other.png gone from the folder"),
    ("mkdir by_type && mv alpha.csv by_type/ && cp beta.csv gamma.csv by_type/", "beta.csv still in the folder"),
    ("mkdir by_type && mv *.csv by_type/ && echo x > other.pdf", "other.pdf holds other content"),
])
def test_sorting_rejects_the_negatives(sort_task, command, reason):
    folder, spec, base = sort_task
    run_in(folder, command)
    verdict = evaluate(spec, base)
    assert not verdict.passed and reason in verdict.reason, verdict.reason


TRASHINFO = "[Trash Info]\nPath={path}\nDeletionDate=2026-01-01T00:00:00\n"


def test_trash_needs_the_trashed_data_and_the_other_file_unchanged(tmp_path, monkeypatch):
    victim, keep = tmp_path / "dl" / "old draft.txt", tmp_path / "dl" / "keep_me.txt"
    trash = tmp_path / "Trash"
    monkeypatch.setitem(PLATFORMS, "ubuntu", replace(PLATFORMS["ubuntu"], trash=str(trash)))
    victim.parent.mkdir()
    victim.write_text("not needed any more\n")
    keep.write_text("still needed\n")
    base = {str(victim): victim.read_bytes(), str(keep): keep.read_bytes()}
    in_trash = {"func": "file_in_trash", "args": {"original": str(victim), "kept": [str(keep)]}}
    (trash / "files").mkdir(parents=True), (trash / "info").mkdir()
    assert "it still there" in evaluate(in_trash, base).reason
    info = trash / "info" / f"{victim.name}.trashinfo"
    info.write_text(TRASHINFO.format(path=str(victim).replace(" ", "%20")))
    (trash / "files" / victim.name).write_bytes(b"")  # deleted for good, an entry faked with an empty file
    victim.unlink()
    verdict = evaluate(in_trash, base)
    assert not verdict.passed and "trashed data holds other content" in verdict.reason
    (trash / "files" / victim.name).write_bytes(base[str(victim)])  # what Move to Trash leaves
    assert evaluate(in_trash, base).passed
    assert evaluate(in_trash, {}).passed  # no baseline (fed input): the entry and some data
    (victim.parent / ".old draft.txt").write_bytes(base[str(victim)])  # trashed, and a hidden copy kept
    assert "a copy of old draft.txt left at .old draft.txt (hidden)" in evaluate(in_trash, base).reason
    (victim.parent / ".old draft.txt").unlink()
    keep.write_text("scratch\n")
    verdict = evaluate(in_trash, base)
    assert not verdict.passed and "keep_me.txt: it holds other content" in verdict.reason


@pytest.fixture
def delete_task(tmp_path, monkeypatch):
    """viewer_delete_image on host files: the home folder, /tmp and /var/tmp of the platform (its user roots) and
    its trash moved under `tmp_path`."""
    sub = instance("viewer_delete_image", tmp_path, image="/home/user/Pictures/trip/blurry_shot.png")
    home = tmp_path / "home" / "user"
    roots = (str(home), str(tmp_path / "tmp"), str(tmp_path / "var" / "tmp"))
    monkeypatch.setitem(PLATFORMS, "ubuntu", replace(PLATFORMS["ubuntu"], trash=str(home / ".local/share/Trash"),
                                                     user_roots=roots))
    image = Path(sub.input["image"].value)
    image.parent.mkdir(parents=True)
    for root in roots[1:]:
        os.makedirs(root)
    image.write_bytes(os.urandom(2000))
    for name in ("beach.png", "castle.png"):
        (image.parent / name).write_bytes(os.urandom(1500))
    return sub, image, {p: Path(p).read_bytes() for p in sub.baseline}


def trash_it(path: Path, trash: Path) -> Path:
    """What the viewer's Delete does (the template's oracle): the file moved to the freedesktop.org trash."""
    (trash / "files").mkdir(parents=True, exist_ok=True), (trash / "info").mkdir(exist_ok=True)
    (trash / "info" / f"{path.name}.trashinfo").write_text(TRASHINFO.format(path=path))
    return Path(shutil.move(path, trash / "files" / path.name))


def test_delete_passes_the_trash_or_rm_and_nothing_else(delete_task, tmp_path):
    sub, image, base = delete_task
    home, trash = tmp_path / "home" / "user", tmp_path / "home" / "user" / ".local/share/Trash"
    assert "still there (a file of 2000 bytes)" in reasons(check(sub, base))
    trashed = trash_it(image, trash)
    assert passed(check(sub, base))
    trashed.unlink()  # removed for good
    assert passed(check(sub, base))
    image.write_bytes(b"other bytes")  # the right name, other bytes
    assert "still there (a file of 11 bytes)" in reasons(check(sub, base))
    image.unlink()
    image.symlink_to(home / "nowhere")  # a dangling link at its place
    assert "still there (a link)" in reasons(check(sub, base))
    image.unlink()
    assert passed(check(sub, {p: b for p, b in base.items() if p != str(image)}))


@pytest.mark.parametrize("where", [
    "home/user/Documents/blurry_shot.png",        # moved out of the folder (a template negative)
    "var/tmp/blurry_shot.png",                    # moved outside the home folder (a template negative)
    "home/user/Pictures/trip/.blurry_shot.png",   # renamed to a hidden name in place (a template negative)
    "home/user/.cache/x/renamed.bin",             # under another name in a hidden folder
    "tmp/blurry_shot.png",
])
def test_delete_fails_the_bytes_kept_anywhere_the_user_keeps_files(delete_task, tmp_path, where):
    sub, image, base = delete_task
    target = tmp_path / where
    target.parent.mkdir(parents=True, exist_ok=True)
    shutil.move(image, target)
    found = reasons(check(sub, base))
    assert f"its content still at {target}" in found and "not deleted" in found, found
    if target.name.startswith("."):
        assert f"{target} (hidden)" in found


def test_delete_fails_a_second_name_kept_and_a_damaged_or_wrong_neighbour(delete_task, tmp_path):
    sub, image, base = delete_task
    home, trash = tmp_path / "home" / "user", tmp_path / "home" / "user" / ".local/share/Trash"
    keep = home / "Documents" / "keep.png"
    keep.parent.mkdir()
    trashed = trash_it(image, trash)
    os.link(trashed, keep)  # trashed, and a second name of the trashed data kept outside the trash
    assert f"its content still at {keep} (a second name of it: a hard link)" in reasons(check(sub, base))
    keep.unlink()
    beach, castle = image.parent / "beach.png", image.parent / "castle.png"
    castle.write_bytes(b"blank")  # the damage negative: a neighbour overwritten
    assert f"{castle}: it holds other content" in reasons(check(sub, base))
    castle.write_bytes(base[str(castle)])
    trash_it(beach, trash)  # the wrong picture deleted too
    assert f"{beach}: gone" in reasons(check(sub, base))
    shutil.move(trash / "files" / "beach.png", beach)
    os.remove(castle)
    os.link(beach, castle)  # a neighbour replaced by a second name of another file
    assert f"{castle}: it is a second name of another file" in reasons(check(sub, {**base, str(castle): base[str(
        beach)]}))
    os.remove(castle)
    castle.write_bytes(base[str(castle)])
    assert passed(check(sub, base))


def test_delete_passes_over_a_file_that_held_the_bytes_at_set_up(delete_task):
    sub, image, base = delete_task
    twin = image.parent / "beach.png"
    twin.write_bytes(base[str(image)])  # set-up made a neighbour with the same bytes: not a copy the agent left
    image.unlink()
    assert passed(check(sub, {**base, str(twin): base[str(image)]}))
    assert "its content still at" in reasons(check(sub, {**base, str(twin): b"other"}))


# -- terminal ------------------------------------------------------------------------------------------------
def test_count_must_leave_the_log_unchanged(tmp_path):
    log, answer = tmp_path / "server.log", tmp_path / "ERROR_count.txt"
    log.write_text("a ERROR\nb INFO\nc ERROR\n")
    spec = {"func": "file_text_equals", "args": {"path": str(answer), "expected": 2, "unchanged": [str(log)]}}
    base = {str(log): log.read_bytes()}
    answer.write_text("2\n")
    assert evaluate(spec, base).passed
    log.write_text("a ERROR\nc ERROR\n")
    verdict = evaluate(spec, base)
    assert not verdict.passed and "server.log: it holds other content" in verdict.reason
    log.write_text("a ERROR\nb INFO\nc ERROR\n")
    assert evaluate(spec, base).passed
    os.link(log, tmp_path / "second name.log")  # the log's bytes kept, but a second name made for it
    verdict = evaluate(spec, base)
    assert not verdict.passed and "server.log: it is a second name of another file" in verdict.reason


def test_the_script_output_is_what_running_the_script_writes(tmp_path):
    sub = instance("terminal_run_script", tmp_path, script="/home/user/bin/setup.sh", token="amber-4821")
    script = sub.input["script"].value
    os.makedirs(os.path.dirname(script))
    Path(script).write_bytes(upload_content(sub, script))
    os.chmod(script, 0o644)
    base = {script: Path(script).read_bytes()}
    assert not any(v.passed for v in check(sub, base))
    result = sub.output["result"].value
    Path(result).write_text("amber-4821\n")  # the token copied out of the script by hand
    os.chmod(script, 0o755)
    assert "check code" in reasons(check(sub, base))
    subprocess.run(["bash", "-c", sub.solution[0].command], check=True)  # the oracle: chmod +x and run it
    assert passed(check(sub, base))
    assert Path(result).read_text().strip() == digest_text("amber-4821")
    Path(script).write_text("#!/bin/sh\necho hi\n")  # the script rewritten
    assert "changed" in reasons(check(sub, base))


def test_a_digest_of_a_text_or_of_a_file_never_both(tmp_path):
    """`file_text_is_digest` hashes exactly one of a text (`of`) and a file's bytes (`file`); `length` cuts the hex
    digits (the script's `cut -c1-16`), else the whole digest is asked."""
    from jarvis_pytest.errors import ConfigError

    out, src = tmp_path / "out.txt", tmp_path / "src.csv"
    src.write_bytes(b"a,b\n")
    for args in ({}, {"of": "x", "file": str(src)}):
        with pytest.raises(ConfigError, match="exactly one of"):
            evaluate({"func": "file_text_is_digest", "args": {"path": str(out), **args}})
    whole = hashlib.sha256(b"x").hexdigest()
    out.write_text(whole[:16] + "\n")
    assert evaluate({"func": "file_text_is_digest", "args": {"path": str(out), "of": "x", "length": 16}}).passed
    assert not evaluate({"func": "file_text_is_digest", "args": {"path": str(out), "of": "x"}}).passed
    out.write_text(hashlib.sha256(b"a,b\n").hexdigest().upper())
    assert evaluate({"func": "file_text_is_digest", "args": {"path": str(out), "file": str(src)}},
                    {str(src): b"a,b\n"}).passed


@pytest.fixture
def archive_task(tmp_path):
    sub = instance("terminal_unzip_archive", tmp_path, archive="/home/user/Downloads/photos.zip",
                   target="/home/user/Documents/unpacked")
    archive, target = sub.input["archive"].value, sub.input["target"].value
    src = tmp_path / "src"
    (src / "inner").mkdir(parents=True)
    (src / "README.txt").write_text("readme for photos\n")
    (src / "inner" / "data.csv").write_text("a,b\n")
    (src / "inner" / "logo.png").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(64)))
    os.makedirs(os.path.dirname(archive))
    subprocess.run(["bash", "-c", f"cd {src} && zip -qr '{archive}' ."], check=True)
    return sub, archive, target, {archive: Path(archive).read_bytes()}


def test_unzip_passes_unzip_d_and_an_extract_here_folder(archive_task):
    sub, archive, target, base = archive_task
    assert not passed(check(sub, base))
    subprocess.run(["bash", "-c", sub.solution[0].command], check=True)
    assert passed(check(sub, base))
    shutil.rmtree(target)
    subprocess.run(["bash", "-c", f"mkdir -p '{target}/photos' && unzip -q '{archive}' -d '{target}/photos'"],
                   check=True)
    assert passed(check(sub, base))  # an archive manager's "extract here" folder named after the archive


@pytest.mark.parametrize("command,reason", [
    ("mkdir -p '{t}/inner' && echo 'readme for photos' > '{t}/README.txt' && : > '{t}/inner/data.csv' && "
     ": > '{t}/inner/logo.png'", "inner/data.csv (0 bytes, 4 in the archive)"),
    ("mkdir -p '{t}' && unzip -q '{a}' README.txt -d '{t}'", "missing"),
    ("mkdir -p '{t}' && unzip -q '{a}' -d '{t}' && rm '{a}'", "photos.zip: gone"),
    ("mkdir -p '{t}' && unzip -qj '{a}' -d '{t}'", "missing"),
])
def test_unzip_rejects_the_negatives(archive_task, command, reason):
    sub, archive, target, base = archive_task
    subprocess.run(["bash", "-c", command.format(t=target, a=archive)], check=True)
    text = reasons(check(sub, base))
    assert reason in text, text


@pytest.fixture
def zip_task(tmp_path):
    sub = instance("terminal_zip_folder", tmp_path, folder="/home/user/Documents/thesis", archive_name="bundle")
    folder, archive = sub.input["folder"].value, sub.output["archive"].value
    os.makedirs(folder), os.makedirs(os.path.dirname(archive))
    Path(folder, "part_one.txt").write_text("part one of thesis\n")
    Path(folder, "part_two.txt").write_text("part two\n")
    Path(folder, "cover.png").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(40)))
    base = {str(p): p.read_bytes() for p in Path(folder).iterdir()}
    return sub, folder, archive, base


@pytest.mark.parametrize("command", [
    "cd '{d}' && zip -qr '{a}' thesis",  # the oracle's way
    "zip -qr '{a}' '{f}'",  # an absolute path: …/Documents/thesis/part_one.txt
])
def test_zip_passes_the_folder_zipped(zip_task, command):
    sub, folder, archive, base = zip_task
    assert not passed(check(sub, base))
    subprocess.run(["bash", "-c", command.format(d=os.path.dirname(folder), a=archive, f=folder)], check=True)
    assert passed(check(sub, base)), reasons(check(sub, base))


@pytest.mark.parametrize("command,reason", [
    ("d=$(mktemp -d) && mkdir $d/thesis && touch $d/thesis/part_one.txt $d/thesis/part_two.txt $d/thesis/cover.png"
     " && cd $d && zip -qr '{a}' thesis", "different content"),
    ("cd '{d}' && zip -qr '{a}' thesis -x '*.png'", "no ['cover.png']"),
    ("cd '{d}' && zip -qrm '{a}' thesis", "part_one.txt: gone"),
    ("cd '{f}' && zip -q '{a}' *", "inside its folder thesis/"),  # the files without their folder
    ("echo 'not a zip' > '{a}'", "not a zip archive"),
])
def test_zip_rejects_the_negatives(zip_task, command, reason):
    sub, folder, archive, base = zip_task
    subprocess.run(["bash", "-c", command.format(d=os.path.dirname(folder), a=archive, f=folder)], check=True)
    text = reasons(check(sub, base))
    assert reason in text, text


# -- mousepad ------------------------------------------------------------------------------------------------
def text_task(tmp_path, name, **values):
    sub = instance(name, tmp_path, **values)
    path = sub.baseline[0]
    os.makedirs(os.path.dirname(path), exist_ok=True)
    Path(path).write_bytes(upload_content(sub, path))
    return sub, Path(path), {path: Path(path).read_bytes()}


def test_append_accepts_the_editor_ways_and_rejects_reordering(tmp_path):
    sub, path, base = text_task(tmp_path, "mousepad_append_line", list_file="/home/user/Documents/groceries.txt",
                                item="olive oil (1 L)")
    assert not passed(check(sub, base))
    for fair in (b"bread\ntea\nbatteries\nolive oil (1 L)", b"bread\ntea\nbatteries\n\nolive oil (1 L)\n"):
        path.write_bytes(fair)  # typed after the last line, with or without a blank line or final newline
        assert passed(check(sub, base)), fair
    for bad, reason in ((b"batteries\nbread\ntea\nolive oil (1 L)\n", "line 1 is 'batteries'"),
                        (b"olive oil (1 L)\n", "line 1 is 'olive oil (1 L)'"),
                        (b"olive oil (1 L)\nbread\ntea\nbatteries\n", "line 1")):
        path.write_bytes(bad)
        assert reason in reasons(check(sub, base)), bad
    path.write_bytes(b"bread\ntea\nbatteries\nolive oil (1 L)\n")
    assert passed(check(sub, {}))  # no baseline: the earlier lines and the last line


def test_crlf_must_keep_every_line(tmp_path):
    sub, path, base = text_task(tmp_path, "mousepad_crlf_line_endings",
                                text_file="/home/user/Documents/config_notes.txt", topic="VPN access")
    assert not passed(check(sub, base))
    path.write_bytes(base[str(path)].replace(b"\n", b"\r\n"))  # what the editor's Line Ending > DOS saves
    assert passed(check(sub, base))
    converted = base[str(path)].replace(b"\n", b"\r\n")
    for bad, reason in ((b"Notes on VPN access\r\n\r\n", "line 2 is '\\r\\n'"),
                        (b"Notes on VPN access\r\n2. follow the guide\r\n3. report back\r\n", "line 2"),
                        (base[str(path)].replace(b"\n", b"\r"), "the right lines with 4 CR line breaks"),
                        (base[str(path)].replace(b"\n", b"\r\r\n"), "4 CR, 4 CRLF line breaks"),  # stray CRs
                        (converted + b"\r\n\r\n", "an extra line 5"),           # blank lines added at the end
                        (converted.replace(b"\r\n", b"  \r\n", 1), "line 1 is"),  # trailing spaces
                        (b"\xef\xbb\xbf" + converted, "stored as UTF-8 with BOM"),
                        (converted[:-2], "without a final line break")):
        path.write_bytes(bad)
        assert reason in reasons(check(sub, base)), (bad, reasons(check(sub, base)))
    assert check_line_endings(b"a\r\nb\r\n", "crlf", b"a\nb\n").passed
    assert not check_line_endings(b"a\r\nb\r\n", "crlf", b"a\nb").passed  # a final line break added


def test_delete_lines_must_delete_whole_lines_only(tmp_path):
    sub, path, base = text_task(tmp_path, "mousepad_delete_lines", text_file="/home/user/Desktop/tasks.txt",
                                word="obsolete")
    assert not passed(check(sub, base))
    kept = "Anna Berg - confirmed\nCarla Diaz - confirmed\nEli Ford - pending\n"
    path.write_text(kept)
    assert passed(check(sub, base))
    path.write_text(kept.rstrip("\n"))  # the last line deleted from the end of the line before it
    assert passed(check(sub, base))
    path.write_text("Anna Berg - confirmed\n\nCarla Diaz - confirmed\n\nEli Ford - pending\n\n")
    assert "line 2 is '\\n'" in reasons(check(sub, base))  # the lines' text deleted, empty lines left
    path.write_text(base[str(path)].decode().replace("obsolete", ""))  # the word erased, the lines kept
    assert "line 2 is 'Ben Cole - \\n'" in reasons(check(sub, base))
    path.write_text(kept + "Eli Ford - pending\n")
    assert "an extra line 4" in reasons(check(sub, base))
    path.write_bytes(kept.replace("\n", "\r\n").encode())  # the lines deleted, the file saved with CRLF
    assert "the right lines with 3 CRLF line breaks" in reasons(check(sub, base))
    path.write_text(kept.replace("Diaz", "Díaz"))  # a kept line edited
    assert "line 2 is 'Carla Díaz - confirmed\\n'" in reasons(check(sub, base))
    path.write_text("")
    assert "an empty file" in reasons(check(sub, base))
    path.write_text(kept)
    assert passed(check(sub, {}))  # no baseline (fed by an upstream subtask): no word, the kept lines there
    path.write_text(kept.replace("Eli Ford", "Eli  Ford"))
    assert "lost ['Eli Ford - pending']" in reasons(check(sub, {}))


def test_replace_must_leave_the_rest_of_the_text(tmp_path):
    sub, path, base = text_task(tmp_path, "mousepad_replace_text", text_file="/home/user/Documents/todo.txt",
                                old_word="Monday", new_word="Friday")
    assert not passed(check(sub, base))
    replaced = base[str(path)].decode().replace("Monday", "Friday")
    path.write_text(replaced)  # Replace All, saved: the editor keeps the line breaks and the final one
    assert passed(check(sub, base))
    for bad, reason in (("Friday\n", "line 1 is 'Friday\\n'"),
                        ("The Friday review has moved.\nPlease read the Friday items before lunch.\n", "line 1"),
                        (base[str(path)].decode().replace("Monday", "Friday", 1), "line 3"),
                        (replaced.replace("\n", "\r\n"), "the right lines with 3 CRLF line breaks"),
                        (replaced.rstrip("\n"), "without a final line break"),
                        (replaced.replace("\n", "   \n", 1), "line 1 is")):
        path.write_bytes(bad.encode())
        assert reason in reasons(check(sub, base)), (bad, reasons(check(sub, base)))
    path.write_text("Friday\n")
    assert passed(check(sub, {}))  # no baseline: the weaker check (new word present, old absent)


def test_text_lines_ignore_line_ends_and_trailing_blank_lines():
    assert text_lines("a\r\nb  \n\n\n") == ["a", "b"] == text_lines("a\nb")
    assert text_lines("a\n\nb\n", blank=False) == ["a", "b"]
