"""File-system checks: existence, exact and partial text content (the transfer drive's: `transfer.py`).

Where a task starts from a file made at set-up, expected content comes from that file as it was then (the
template lists it under `baseline`, read with `state.baseline(path)`), never from what the agent left: a moved
file must hold what the original held, an edited text must be the original with only the asked edit applied,
files the instruction did not touch must be unchanged. In a composed task a fed input has no baseline (an
upstream subtask makes it); each evaluator then falls back to the strongest check that needs no original and
says so in its docstring.
"""

from __future__ import annotations

import hashlib
import io
import posixpath
import shlex
import zipfile

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.evaluators.folders import changed_since_setup, with_unchanged
from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.state import FinalState, as_text, judge_file
from jarvis_pytest.evaluators.text import read_answer


def _short(text: str, limit: int = 120) -> str:
    return repr(text if len(text) <= limit else text[:limit] + "…")


def _size(data: bytes | None) -> str:
    return "no file" if data is None else f"{len(data)} bytes"


def text_lines(text: str, blank: bool = True) -> list[str]:
    """The lines of `text` with their ends (LF, CRLF or CR) and trailing spaces removed and trailing blank lines
    dropped (an editor's final newline or its absence is no difference); `blank=False` drops every blank line."""
    lines = [line.rstrip() for line in text.replace("\r\n", "\n").replace("\r", "\n").split("\n")]
    while lines and not lines[-1]:
        lines.pop()
    return lines if blank else [line for line in lines if line]


def _first_difference(got: list[str], want: list[str]) -> str:
    """Where two line lists first differ, for a reason."""
    for i, (g, w) in enumerate(zip(got, want)):
        if g != w:
            return f"line {i + 1} is {_short(g, 60)}, expected {_short(w, 60)}"
    if len(got) > len(want):
        return f"an extra line {len(want) + 1}: {_short(got[len(want)], 60)}"
    return f"{len(got)} line(s), expected {len(want)} (missing {_short(want[len(got)], 60)})"


@evaluator("file_exists")
def file_exists(state: FinalState, path: str, platform: str | None = None) -> Verdict:
    ok = state.exists(path, platform)
    return Verdict.check(ok, f"a file at {path}", "it" if ok else "no file")


@evaluator("file_text_equals")
def file_text_equals(state: FinalState, path: str, expected: str, strip: bool = True,
                     unchanged: list[str] | None = None, platform: str | None = None) -> Verdict:
    """`path` reads `expected` (surrounding white space ignored when `strip`) in any encoding the platform's programs
    write (`text.decode_text` with its code page: UTF-16 with a byte order mark from Windows PowerShell's `>`, UTF-8,
    ANSI), and the files of `unchanged` (e.g. the input the answer was read from) are as they were at set-up (see
    `changed_since_setup`)."""
    expected = str(expected)  # a lone "{{slot}}" may render as a number
    text, why = read_answer(state, path, platform)
    if text is None:
        return Verdict.check(False, f"{path} with text {_short(expected)}", why)
    got, want = (text.strip(), expected.strip()) if strip else (text, expected)
    if got != want:
        return Verdict.check(False, f"{path} to read {_short(want)}", _short(got))
    damaged = changed_since_setup(state, unchanged, platform)
    return Verdict.check(not damaged, f"{path} to read {_short(want)}" + (
        f" and {', '.join(unchanged)} unchanged" if unchanged else ""), "; ".join(damaged) or _short(got))


def digest_text(text: str, algorithm: str = "sha256", length: int | None = 16) -> str:
    """The first `length` hex digits (None: all) of the `algorithm` digest of `text` (UTF-8): with 16, what
    `printf '%s' TEXT | sha256sum | cut -c1-16` prints."""
    return hashlib.new(algorithm, str(text).encode("utf-8")).hexdigest()[:length]


def check_digest(text: str, digest: str, what: str) -> Verdict:
    """`text` is the hex `digest` alone (white space around it aside; upper or lower case, as `sha256sum` and
    PowerShell's `Get-FileHash` write it)."""
    got = text.strip().lstrip("\ufeff").strip()
    return Verdict.check(got.casefold() == digest.casefold(), f"just the {what} {digest}", _short(got) if got
                         else "an empty file")


@evaluator("file_text_is_digest")
def file_text_is_digest(state: FinalState, path: str, of: str | None = None, file: str | None = None,
                        algorithm: str = "sha256", length: int | None = None, platform: str | None = None) -> Verdict:
    """`path` holds just the hex `algorithm` digest (its first `length` digits; None: all of it; upper or lower
    case), in any encoding the platform's programs write (`text.decode_text`), of exactly one of:

    - `of`, a text (its UTF-8 bytes): the output of a program that computes it when it runs, recomputed here from
      the task's own value, so copying the value `of` out of the program's text is not its output;
    - `file`, a file of the device (e.g. PowerShell's `Get-FileHash`): of the bytes it had at set-up (its
      baseline; as it is now when an upstream subtask of a composed task made it), and `file` must still be
      there as set up (`changed_since_setup`: not edited, hidden, linked or replaced), so the hash of a file
      changed afterwards, or of another file, fails."""
    if (of is None) == (file is None):
        raise ConfigError("file_text_is_digest: give exactly one of `of` (a text) and `file` (a file's path)",
                          field="evaluate.args", fix="pass `of` to hash a text, or `file` to hash a file's bytes")
    algo = algorithm.lower().replace("-", "")
    if file is None:
        digest, what = digest_text(str(of), algo, length), f"{algorithm} check code of {_short(str(of))}:"
    else:
        data = state.baseline(file, platform)
        data = data if data is not None else state.pull(file, platform)
        if data is None:
            return Verdict.check(False, f"the {algorithm} hash of {file} in {path}", f"no file at {file}")
        digest, what = hashlib.new(algo, data).hexdigest()[:length], f"{algorithm} hash of {file}:"
    text, why = read_answer(state, path, platform)
    if text is None:
        return Verdict.check(False, f"{path} holding the {what} {digest}", why)
    verdict = check_digest(text, digest, what)
    if not verdict.passed or file is None:
        return verdict
    return with_unchanged(state, verdict, f"{path} holding the {what} {digest}", platform, unchanged=[file])


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


@evaluator("file_executable")
def file_executable(state: FinalState, path: str, unchanged: bool = False, platform: str | None = None) -> Verdict:
    """`path` is a file its owner may execute; with `unchanged`, also still holding the bytes it had at set-up (made
    executable, not rewritten; a file with no baseline is not compared)."""
    res = state.run(f"stat -c %a {shlex.quote(path)}", platform)
    if res.returncode != 0:
        return Verdict.check(False, f"an executable file at {path}", "no file")
    mode = res.stdout.strip()
    if int(mode, 8) & 0o100 == 0:
        return Verdict.check(False, f"{path} executable by its owner", f"mode {mode}")
    damaged = changed_since_setup(state, [path], platform) if unchanged else []
    want = f"{path} executable by its owner" + (", its content unchanged" if unchanged else "")
    return Verdict.check(not damaged, want, "; ".join(damaged) or f"mode {mode}")


def check_last_line(text: str, expected: str, previous: list[str] | None = None, original: str | None = None
                    ) -> Verdict:
    """The last non-empty line of `text` is `expected` (trimmed), and the lines in `previous` are still there.
    When the text before the edit (`original`) is known: the non-blank lines are exactly the original's, in their
    order, followed by `expected` (blank lines and surrounding spaces aside)."""
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    if original is not None:
        want = [line.strip() for line in text_lines(original, blank=False)] + [expected.strip()]
        return Verdict.check(lines == want, f"the {len(want) - 1} original lines unchanged and {_short(expected)} "
                             "added after them", "so" if lines == want else _first_difference(lines, want))
    last = lines[-1] if lines else ""
    lost = [p for p in previous or [] if p.strip() not in lines]
    if lost:
        return Verdict.check(False, f"the earlier lines kept and {_short(expected)} added last", f"lost {lost!r}")
    return Verdict.check(last == expected.strip(), f"last line {_short(expected)}", _short(last))


@evaluator("file_last_line")
def file_last_line(state: FinalState, path: str, expected: str, previous: list[str] | None = None,
                   platform: str | None = None) -> Verdict:
    """`expected` added as the last line of `path`, its other lines as they were at set-up (the template lists
    `path` under `baseline`); with no baseline, the lines `previous` are still somewhere in the file."""
    original = state.baseline(path, platform)
    return judge_file(state, path, f"{path} ending with {_short(expected)}", as_text,
                      lambda text: check_last_line(text, str(expected), previous,
                                                   None if original is None else as_text(original)), platform)


def _zip_files(data: bytes) -> dict[str, bytes]:
    """The file members of a zip archive (name → bytes); raises BadZipFile for a corrupt archive or member."""
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        broken = zf.testzip()
        if broken:
            raise zipfile.BadZipFile(f"a corrupt member {broken!r}")
        return {n: zf.read(n) for n in zf.namelist() if not n.endswith("/")}


def check_zip_members(data: bytes, names: list[str], folder: str | None = None,
                      originals: dict[str, bytes | None] | None = None) -> Verdict:
    """`data` is a zip archive holding files with each of the base names in `names` (at any folder depth). With
    `folder` (a folder's name), each is inside that folder in the archive (`…/folder/name`); with `originals`
    (name → the file's bytes at set-up), each member holds those bytes."""
    want = f"a zip archive with {names}" + (f" inside its folder {folder}/" if folder else "")
    try:
        files = _zip_files(data)
    except zipfile.BadZipFile as exc:
        return Verdict.check(False, want, "not a zip archive" if "corrupt member" not in str(exc) else str(exc))
    members = [posixpath.basename(n) for n in files]
    missing, wrong = [], []
    for name in names:
        base = posixpath.basename(name)
        hits = [n for n in files if posixpath.basename(n) == base
                and (folder is None or posixpath.basename(posixpath.dirname(n)) == folder)]
        if not hits:
            missing.append(base)
        elif originals and originals.get(base) is not None and all(files[n] != originals[base] for n in hits):
            wrong.append(f"{hits[0]} ({len(files[hits[0]])} bytes, the original {len(originals[base])})")
    if missing:
        return Verdict.check(False, want, f"no {missing} there; members {sorted(files)[:20] or sorted(members)}")
    if wrong:
        return Verdict.check(False, want + " holding the original files", f"different content: {'; '.join(wrong)}")
    return Verdict.check(True, want, f"members {sorted(files)[:20]}")


@evaluator("zip_contains")
def zip_contains(state: FinalState, path: str, names: list[str], folder: str | None = None,
                 platform: str | None = None) -> Verdict:
    """`path` is a zip archive holding files named `names`. With `folder` (the path of the folder zipped): each
    as `<folder's name>/<name>` holding the bytes `folder/<name>` had at set-up (its baseline, else its current
    bytes), and the folder's files still there unchanged (zipped, not moved into the archive)."""
    originals = None
    if folder is not None:
        originals = {posixpath.basename(n): state.baseline(f"{folder}/{posixpath.basename(n)}", platform)
                     or state.pull(f"{folder}/{posixpath.basename(n)}", platform) for n in names}

    def check(data: bytes) -> Verdict:
        verdict = check_zip_members(data, names, folder and posixpath.basename(folder.rstrip("/")), originals)
        if not verdict.passed or folder is None:
            return verdict
        damaged = changed_since_setup(state, [f"{folder}/{posixpath.basename(n)}" for n in names], platform)
        return Verdict.check(not damaged, f"the files of {folder} zipped and still there unchanged",
                             "; ".join(damaged) or "so")
    return judge_file(state, path, f"a zip archive at {path}", bytes, check, platform)


def check_extracted(archive: bytes, found: dict[str, bytes | None]) -> Verdict:
    """Every file member of the zip `archive` was extracted with its bytes: `found[member]` is the bytes of the
    file at that member's path under the target folder (None: none there)."""
    try:
        files = _zip_files(archive)
    except zipfile.BadZipFile as exc:
        return Verdict.check(False, "the archive's files extracted", f"the archive unreadable: {exc}")
    missing = [n for n in files if found.get(n) is None]
    wrong = [f"{n} ({len(found[n])} bytes, {len(files[n])} in the archive)" for n in files
             if found.get(n) is not None and found[n] != files[n]]
    want = f"the {len(files)} files of the archive extracted with their content"
    if missing or wrong:
        return Verdict.check(False, want, "; ".join(([f"missing {missing}"] if missing else [])
                                                    + ([f"different: {', '.join(wrong)}"] if wrong else [])))
    return Verdict.check(True, want, f"{sorted(files)}")


@evaluator("zip_extracted")
def zip_extracted(state: FinalState, archive: str, target: str, platform: str | None = None) -> Verdict:
    """Every file of the zip `archive` (as it was at set-up: the template lists it under `baseline`; with no
    baseline, as it is now) is under `target` at its path in the archive with the same bytes — or under
    `target/<archive stem>/`, the folder an archive manager's "extract here" makes — and the archive itself is
    still there unchanged."""
    data = state.baseline(archive, platform) or state.pull(archive, platform)
    if data is None:
        return Verdict.check(False, f"the files of {archive} extracted into {target}", f"no archive at {archive}")
    try:
        members = list(_zip_files(data))
    except zipfile.BadZipFile as exc:
        return Verdict.check(False, f"the files of {archive} extracted", f"the archive unreadable: {exc}")
    stem = posixpath.splitext(posixpath.basename(archive))[0]
    best: Verdict | None = None
    for root in (target, f"{target}/{stem}"):
        verdict = check_extracted(data, {m: state.pull(f"{root}/{m}", platform) for m in members})
        if verdict.passed:
            best = verdict
            break
        best = best or verdict  # report against `target` itself
    assert best is not None
    if not best.passed:
        return Verdict(False, best.reason.replace("expected ", f"expected under {target}: ", 1))
    damaged = changed_since_setup(state, [archive], platform)
    return Verdict.check(not damaged, f"the files of {archive} extracted into {target}, the archive kept",
                         "; ".join(damaged) or best.reason.partition("found ")[2])


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
