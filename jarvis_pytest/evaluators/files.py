"""File-system checks: existence, exact and partial text content, files on the transfer drive."""

from __future__ import annotations

import io
import posixpath
import shlex
import zipfile
from urllib.parse import unquote

from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.state import FinalState, as_text, judge_file


def _short(text: str, limit: int = 120) -> str:
    return repr(text if len(text) <= limit else text[:limit] + "…")


@evaluator("file_exists")
def file_exists(state: FinalState, path: str, platform: str | None = None) -> Verdict:
    ok = state.exists(path, platform)
    return Verdict.check(ok, f"a file at {path}", "it" if ok else "no file")


@evaluator("file_absent")
def file_absent(state: FinalState, path: str, kept: list[str] | None = None, platform: str | None = None) -> Verdict:
    """No file at `path` (deleted, moved or trashed), while every file of `kept` is still there."""
    gone = not state.exists(path, platform)
    lost = [k for k in kept or [] if not state.exists(k, platform)]
    want = f"no file at {path}" + (f" and the {len(kept)} other file(s) kept" if kept else "")
    found = ("none" if gone else "a file") + (f"; lost {lost!r}" if lost else "")
    return Verdict.check(gone and not lost, want, found)


@evaluator("file_text_equals")
def file_text_equals(state: FinalState, path: str, expected: str, strip: bool = True,
                     platform: str | None = None) -> Verdict:
    text, expected = state.pull_text(path, platform), str(expected)  # a lone "{{slot}}" may render as a number
    if text is None:
        return Verdict.check(False, f"{path} with text {_short(expected)}", "no file")
    got, want = (text.strip(), expected.strip()) if strip else (text, expected)
    return Verdict.check(got == want, f"{path} to read {_short(want)}", _short(got))


@evaluator("file_contains")
def file_contains(state: FinalState, path: str, text: str, platform: str | None = None) -> Verdict:
    content, text = state.pull_text(path, platform), str(text)
    if content is None:
        return Verdict.check(False, f"{path} containing {_short(text)}", "no file")
    return Verdict.check(text in content, f"{path} containing {_short(text)}", _short(content))


@evaluator("file_not_contains")
def file_not_contains(state: FinalState, path: str, text: str, platform: str | None = None) -> Verdict:
    content, text = state.pull_text(path, platform), str(text)
    if content is None:
        return Verdict.check(False, f"{path} without {_short(text)}", "no file")
    return Verdict.check(text not in content, f"{path} without {_short(text)}", _short(content))


@evaluator("files_identical")
def files_identical(state: FinalState, path: str, reference: str, platform: str | None = None,
                    reference_platform: str | None = None) -> Verdict:
    """`path` on this device has the same bytes as `reference` (possibly on another device)."""
    got = state.pull(path, platform)
    ref = state.pull(reference, reference_platform)
    if got is None or ref is None:
        missing = path if got is None else reference
        return Verdict.check(False, f"{path} identical to {reference}", f"no file at {missing}")
    return Verdict.check(got == ref, f"{path} identical to {reference} ({len(ref)} bytes)", f"{len(got)} different bytes" if got != ref else "identical")


@evaluator("transfer_has_file")
def transfer_has_file(state: FinalState, name: str) -> Verdict:
    """A file named `name` (basename) is somewhere on the transfer drive."""
    if state.transfer is None:
        return Verdict(False, "task has no transfer drive")
    names = sorted(posixpath.basename(p) for p in state.transfer.walk())
    base = posixpath.basename(name)
    return Verdict.check(base in names, f"{base!r} on the transfer drive", repr(names[:20]))


@evaluator("file_executable")
def file_executable(state: FinalState, path: str, platform: str | None = None) -> Verdict:
    """`path` is a file its owner may execute."""
    res = state.run(f"stat -c %a {shlex.quote(path)}", platform)
    if res.returncode != 0:
        return Verdict.check(False, f"an executable file at {path}", "no file")
    mode = res.stdout.strip()
    return Verdict.check(int(mode, 8) & 0o100 != 0, f"{path} executable by its owner", f"mode {mode}")


def check_line_endings(data: bytes, ending: str) -> Verdict:
    """Every line of `data` ends with `ending` ("crlf" or "lf"), and there is more than one line."""
    crlf, lf = data.count(b"\r\n"), data.count(b"\n")
    found = f"{crlf} CRLF and {lf - crlf} LF line ends"
    if ending == "crlf":
        return Verdict.check(crlf > 1 and crlf == lf, "every line ending in CRLF (Windows/DOS)", found)
    return Verdict.check(lf > 1 and crlf == 0, "every line ending in LF (Unix)", found)


@evaluator("file_line_endings")
def file_line_endings(state: FinalState, path: str, ending: str, contains: str | None = None,
                      platform: str | None = None) -> Verdict:
    """Every line of `path` ends with `ending` (crlf or lf), and its text still contains `contains`."""
    def check(data: bytes) -> Verdict:
        if contains is not None and str(contains) not in as_text(data):
            return Verdict.check(False, f"{path} still containing {_short(str(contains))}", _short(as_text(data)))
        return check_line_endings(data, ending.lower())
    return judge_file(state, path, f"{path} with {ending.upper()} line ends", bytes, check, platform)


def check_last_line(text: str, expected: str, previous: list[str] | None = None) -> Verdict:
    """The last non-empty line of `text` is `expected` (trimmed), and the lines in `previous` are still there."""
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    last = lines[-1] if lines else ""
    lost = [p for p in previous or [] if p.strip() not in lines]
    if lost:
        return Verdict.check(False, f"the earlier lines kept and {_short(expected)} added last", f"lost {lost!r}")
    return Verdict.check(last == expected.strip(), f"last line {_short(expected)}", _short(last))


@evaluator("file_last_line")
def file_last_line(state: FinalState, path: str, expected: str, previous: list[str] | None = None,
                   platform: str | None = None) -> Verdict:
    return judge_file(state, path, f"{path} ending with {_short(expected)}", as_text,
                      lambda text: check_last_line(text, expected, previous), platform)


def check_lines_filtered(text: str, word: str, kept: list[str]) -> Verdict:
    """No line of `text` contains `word`, and every line of `kept` is still there."""
    lines = [line.strip() for line in text.splitlines()]
    bad = [line for line in lines if word.casefold() in line.casefold()]
    lost = [k for k in kept if k.strip() not in lines]
    ok = not bad and not lost
    found = (f"{len(bad)} line(s) with it, e.g. {_short(bad[0])}" if bad else "none with it") + \
        (f"; lost {lost!r}" if lost else "")
    return Verdict.check(ok, f"no line containing {word!r} and the {len(kept)} other lines kept", found)


@evaluator("file_lines_without")
def file_lines_without(state: FinalState, path: str, word: str, kept: list[str],
                       platform: str | None = None) -> Verdict:
    return judge_file(state, path, f"{path} without lines containing {word!r}", as_text,
                      lambda text: check_lines_filtered(text, word, kept), platform)


def check_zip_members(data: bytes, names: list[str]) -> Verdict:
    """`data` is a zip archive holding files with each of the base names in `names` (at any folder depth)."""
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as zf:
            members = [posixpath.basename(n) for n in zf.namelist() if not n.endswith("/")]
            broken = zf.testzip()
    except zipfile.BadZipFile:
        return Verdict.check(False, f"a zip archive with {names}", "not a zip archive")
    missing = [n for n in names if posixpath.basename(n) not in members]
    if broken:
        return Verdict.check(False, f"an intact zip archive with {names}", f"a corrupt member {broken!r}")
    return Verdict.check(not missing, f"a zip archive with {names}", f"members {sorted(members)[:20]}")


@evaluator("zip_contains")
def zip_contains(state: FinalState, path: str, names: list[str], platform: str | None = None) -> Verdict:
    return judge_file(state, path, f"a zip archive at {path}", bytes, lambda data: check_zip_members(data, names),
                      platform)


def check_ini_value(text: str, key: str, expected: str) -> Verdict:
    """The last uncommented `key=value` line of an INI-style `text` has `expected` as its value (trimmed; paths
    compared without a trailing slash)."""
    value = None
    for line in text.splitlines():
        name, sep, rest = line.strip().partition("=")
        if sep and not name.startswith(("#", ";")) and name.strip() == key:
            value = rest.strip()
    norm = (lambda v: v.rstrip("/") or v) if expected.startswith("/") else (lambda v: v)
    return Verdict.check(value is not None and norm(value) == norm(expected), f"{key}={expected}",
                         "the key unset" if value is None else f"{key}={value}")


@evaluator("config_value_is")
def config_value_is(state: FinalState, path: str, key: str, expected: str, platform: str | None = None) -> Verdict:
    """An application's INI-style configuration file sets `key` to `expected`."""
    return judge_file(state, path, f"{key}={expected} in {path}", as_text,
                      lambda text: check_ini_value(text, key, str(expected)), platform)


TRASH = "/home/user/.local/share/Trash"


def check_trashinfo(infos: dict[str, str], original: str) -> Verdict:
    """Some freedesktop.org `.trashinfo` text of `infos` (file name → text) records `original` as its Path."""
    for name, text in infos.items():
        for line in text.splitlines():
            key, _, value = line.partition("=")
            if key.strip() == "Path" and unquote(value.strip()) == original:
                return Verdict.check(True, f"{original} in the trash", name)
    return Verdict.check(False, f"{original} in the trash", f"trash entries {sorted(infos)[:10] or 'none'}")


@evaluator("file_in_trash")
def file_in_trash(state: FinalState, name: str, original: str, platform: str | None = None) -> Verdict:
    """The desktop user's trash holds the file once at `original` (its `.trashinfo` names it, its data is there)."""
    listing = state.run(f"ls -1 {TRASH}/info 2>/dev/null", platform).stdout.split()
    infos = {}
    for info in listing:
        if info.endswith(".trashinfo") and state.exists(f"{TRASH}/files/{info[:-len('.trashinfo')]}", platform):
            infos[info] = state.pull_text(f"{TRASH}/info/{info}", platform) or ""
    return check_trashinfo(infos, original)
