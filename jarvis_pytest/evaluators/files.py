"""File-system checks: existence, exact and partial text content, files on the transfer drive.

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
import ntpath
import posixpath
import shlex
import zipfile
from urllib.parse import unquote

from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.state import FinalState, as_text, judge_file


def _short(text: str, limit: int = 120) -> str:
    return repr(text if len(text) <= limit else text[:limit] + "…")


def _size(data: bytes | None) -> str:
    return "no file" if data is None else f"{len(data)} bytes"


def file_kind(state: FinalState, path: str, platform: str | None = None) -> tuple[str, str] | None:
    """(`stat`'s file type, e.g. "regular file" or "symbolic link", and "device:inode") of `path` itself (a
    symbolic link is not followed), or None when there is nothing at `path`."""
    res = state.run(f"stat -c '%F|%d:%i' -- {shlex.quote(path)}", platform)
    if res.returncode != 0 or "|" not in res.stdout:
        return None
    kind, _, ident = res.stdout.strip().partition("|")
    return ("regular file" if kind == "regular empty file" else kind), ident


def changed_files(state: FinalState, paths: list[str] | None, platform: str | None = None) -> list[str]:
    """What happened to each of `paths` that should be as it was at set-up: "<path> gone", or "<path> changed"
    when its bytes differ from its baseline (only existence is checked for a path with no baseline)."""
    problems = []
    for path in paths or []:
        data = state.pull(path, platform)
        if data is None:
            problems.append(f"{path} gone")
            continue
        original = state.baseline(path, platform)
        if original is not None and data != original:
            problems.append(f"{path} changed ({len(original)} bytes at set-up, now {len(data)})")
    return problems


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


@evaluator("file_absent")
def file_absent(state: FinalState, path: str, kept: list[str] | None = None, platform: str | None = None) -> Verdict:
    """No file at `path` (deleted, moved or trashed), while every file of `kept` is still there — with the bytes it
    had at set-up when the template lists it under `baseline` (its existence only otherwise)."""
    gone = not state.exists(path, platform)
    lost = changed_files(state, kept, platform)
    want = f"no file at {path}" + (f" and the {len(kept)} other file(s) kept unchanged" if kept else "")
    found = ("none" if gone else "a file") + (f"; {'; '.join(lost)}" if lost else "")
    return Verdict.check(gone and not lost, want, found)


@evaluator("file_text_equals")
def file_text_equals(state: FinalState, path: str, expected: str, strip: bool = True,
                     unchanged: list[str] | None = None, platform: str | None = None) -> Verdict:
    """`path` reads `expected` (surrounding white space ignored when `strip`), and the files of `unchanged` (e.g.
    the input the answer was read from) are as they were at set-up (see `changed_files`)."""
    text, expected = state.pull_text(path, platform), str(expected)  # a lone "{{slot}}" may render as a number
    if text is None:
        return Verdict.check(False, f"{path} with text {_short(expected)}", "no file")
    got, want = (text.strip(), expected.strip()) if strip else (text, expected)
    if got != want:
        return Verdict.check(False, f"{path} to read {_short(want)}", _short(got))
    damaged = changed_files(state, unchanged, platform)
    return Verdict.check(not damaged, f"{path} to read {_short(want)}" + (
        f" and {', '.join(unchanged)} unchanged" if unchanged else ""), "; ".join(damaged) or _short(got))


def digest_text(text: str, algorithm: str = "sha256", length: int = 16) -> str:
    """The first `length` hex digits of the `algorithm` digest of `text` (UTF-8): what
    `printf '%s' TEXT | sha256sum | cut -c1-16` prints."""
    return hashlib.new(algorithm, str(text).encode("utf-8")).hexdigest()[:length]


@evaluator("file_text_is_digest")
def file_text_is_digest(state: FinalState, path: str, of: str, algorithm: str = "sha256", length: int = 16,
                        platform: str | None = None) -> Verdict:
    """`path` reads the first `length` hex digits of the `algorithm` digest of the text `of` — the output of a
    program that computes it when it runs (recomputed here on the host from the task's own value), so copying the
    value `of` out of the program's text is not its output."""
    want = digest_text(of, algorithm, length)
    text = state.pull_text(path, platform)
    if text is None:
        return Verdict.check(False, f"{path} holding the {algorithm} check code {want} of {_short(str(of))}", "no file")
    got = text.strip()
    return Verdict.check(got == want, f"{path} holding the {algorithm} check code {want} of {_short(str(of))}",
                         _short(got))


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


def check_copy(copy: bytes | None, source: bytes | None, original: bytes | None, kind: str | None = "regular file",
               same_file: bool = False) -> Verdict:
    """`copy` is an independent copy of `source`: a regular file (`kind`, not a symbolic link) that is not the
    source itself under another name (`same_file`: one inode, a hard link), with the source's bytes; and when the
    source's content at set-up (`original`) is known, the source still holds it, so the two match on the real
    content and not on an emptied or rewritten source."""
    want = "an independent copy holding the original's content" + (
        f" ({len(original)} bytes)" if original is not None else "")
    if copy is None or source is None:
        return Verdict.check(False, want, "no copy" if copy is None else "the original gone")
    if kind is not None and kind != "regular file":
        return Verdict.check(False, want, f"a {kind}, not a copied file")
    if same_file:
        return Verdict.check(False, want, "the original itself under a second name (a hard link), not a copy")
    if original is not None and source != original:
        return Verdict.check(False, want, f"the original changed since set-up ({len(original)} bytes then, "
                             f"{len(source)} now)")
    return Verdict.check(copy == source, want, "identical" if copy == source else f"{len(copy)} different bytes")


@evaluator("files_identical")
def files_identical(state: FinalState, path: str, reference: str, platform: str | None = None,
                    reference_platform: str | None = None, copy: bool = False) -> Verdict:
    """`path` on this device has the same bytes as `reference` (possibly on another device).

    `copy`: `path` must also be a copy made of `reference` (see `check_copy`): a regular file, not a link to it,
    and `reference` must still hold its set-up content when the template lists it under `baseline`. In a composed
    task where an upstream subtask makes `reference` there is no baseline: the two are then compared as they are.
    """
    got = state.pull(path, platform)
    ref = state.pull(reference, reference_platform)
    if copy:
        kind = file_kind(state, path, platform)
        same = False
        if kind is not None and (platform or state.platform) == (reference_platform or state.platform):
            ref_kind = file_kind(state, reference, reference_platform)
            same = ref_kind is not None and ref_kind[1] == kind[1]
        return check_copy(got, ref, state.baseline(reference, reference_platform), kind and kind[0], same)
    if got is None or ref is None:
        missing = path if got is None else reference
        return Verdict.check(False, f"{path} identical to {reference}", f"no file at {missing}")
    return Verdict.check(got == ref, f"{path} identical to {reference} ({len(ref)} bytes)", f"{len(got)} different bytes" if got != ref else "identical")


def check_moved(data: bytes | None, original: bytes | None, source_left: bool, kind: str | None = "regular file"
                ) -> Verdict:
    """A file moved (or renamed): nothing left at the source (`source_left` false), and at the destination a
    regular file (`kind`) holding `data` equal to what the source held at set-up (`original`; when it is unknown,
    only that a file is there)."""
    want = "the file moved: none left at its old place, and its content" + (
        f" ({len(original)} bytes)" if original is not None else "") + " at the new one"
    if data is None:
        return Verdict.check(False, want, "no file at the new place" + (
            "; the original still there" if source_left else ""))
    if kind is not None and kind != "regular file":
        return Verdict.check(False, want, f"a {kind} at the new place")
    if source_left:
        return Verdict.check(False, want, "the original still at its old place (copied, not moved)")
    if original is not None and data != original:
        return Verdict.check(False, want, f"a different file at the new place ({len(data)} bytes)")
    return Verdict.check(True, want, "it moved" + (" with its content" if original is not None else ""))


@evaluator("file_moved")
def file_moved(state: FinalState, path: str, original: str, platform: str | None = None) -> Verdict:
    """The file once at `original` is now at `path` (moved or renamed): no file at `original`, and at `path` a
    regular file with the bytes `original` had at set-up (the template lists `original` under `baseline`). When
    `original` has no baseline (in a composed task an upstream subtask makes it) only the move itself is checked:
    a regular file at `path`, none at `original`."""
    data = state.pull(path, platform)
    kind = file_kind(state, path, platform) if data is not None else None
    return check_moved(data, state.baseline(original, platform), state.exists(original, platform),
                       kind and kind[0])


def check_sorted(sub: str, found: dict[str, tuple[bytes | None, bytes | None]],
                 originals: dict[str, bytes | None], moved: list[str], kept: list[str]) -> Verdict:
    """A folder sorted: each file of `moved` is in the sub-folder `sub` and no longer at the top, each file of
    `kept` still at the top and not in `sub`, each with its set-up bytes. `found[name]` is (the bytes at the top,
    the bytes in `sub`), `originals[name]` the set-up bytes (None: unknown for a moved file; for a kept file, a
    name that did not exist at set-up and is skipped)."""
    problems = []
    for name in moved:
        top, inside = found.get(name, (None, None))
        if inside is None:
            problems.append(f"{name} not in {sub}")
        elif originals.get(name) is not None and inside != originals[name]:
            problems.append(f"{sub}/{name} is not the original ({len(inside)} bytes, {len(originals[name])} at set-up)")
        if top is not None:
            problems.append(f"{name} still in the folder")
    for name in kept:
        original = originals.get(name)
        if original is None:
            continue
        top, inside = found.get(name, (None, None))
        if top is None:
            problems.append(f"{name} gone from the folder")
        elif top != original:
            problems.append(f"{name} changed")
        if inside is not None:
            problems.append(f"{name} put in {sub} too")
    checked = [k for k in kept if originals.get(k) is not None]
    want = f"{', '.join(moved)} moved into {sub} unchanged, and {', '.join(checked) or 'no other file'} left in place"
    return Verdict.check(not problems, want, "; ".join(problems) or "so")


@evaluator("folder_sorted")
def folder_sorted(state: FinalState, folder: str, sub: str, moved: list[str], kept: list[str],
                  platform: str | None = None) -> Verdict:
    """The files `moved` (names) of `folder` were moved into `folder/sub` and the files `kept` were left in
    `folder`, all with their set-up content. The template lists every `folder/<name>` under `baseline`: a kept name
    with no baseline did not exist at set-up and is skipped (so `kept` may list every name the set-up could make);
    a moved name with no baseline is checked for its place only."""
    found = {name: (state.pull(f"{folder}/{name}", platform), state.pull(f"{folder}/{sub}/{name}", platform))
             for name in [*moved, *kept]}
    originals = {name: state.baseline(f"{folder}/{name}", platform) for name in [*moved, *kept]}
    return check_sorted(sub, found, originals, moved, kept)


@evaluator("transfer_has_file")
def transfer_has_file(state: FinalState, name: str) -> Verdict:
    """A file named `name` (basename) is somewhere on the transfer drive."""
    if state.transfer is None:
        return Verdict(False, "task has no transfer drive")
    names = sorted(posixpath.basename(p) for p in state.transfer.walk())
    base = posixpath.basename(name)
    return Verdict.check(base in names, f"{base!r} on the transfer drive", repr(names[:20]))


@evaluator("transfer_arrived_unchanged")
def transfer_arrived_unchanged(state: FinalState, source: str, source_platform: str, path: str,
                               folder: str = "/data", source_changes_later: bool = False,
                               destination_changes_later: bool = False) -> Verdict:
    """The file `source` on `source_platform` went through the transfer drive (a file of its name in `folder`)
    and arrived at `path` on this subtask's device byte for byte: the three copies have one SHA-256. A side that
    another subtask of the task edits or consumes on purpose (`*_changes_later`, set by composition) is not
    compared; the drive's copy always is."""
    want = f"{path} equal to {source} on the {source_platform} device, through the drive's {folder}"
    if state.transfer is None:
        return Verdict.check(False, want, "a task without a transfer drive")
    name = ntpath.basename(source) if "\\" in source else posixpath.basename(source)
    copies: list[tuple[str, bytes]] = []
    if not source_changes_later:
        origin = state.pull(source, source_platform)
        if origin is None:
            return Verdict.check(False, want, f"no file at {source} on the {source_platform} device")
        copies.append(("source", origin))
    try:
        copies.append(("drive", state.transfer.download(f"{folder.rstrip('/')}/{name}")))
    except FileNotFoundError:
        return Verdict.check(False, want, f"no {name} in the drive's {folder}")
    if not destination_changes_later:
        arrived = state.pull(path)
        if arrived is None:
            return Verdict.check(False, want, f"no file at {path}")
        copies.append(("destination", arrived))
    if len(copies) == 1:
        return Verdict.check(True, want, f"{name} on the drive; source and destination not compared: other "
                             "subtasks change both")
    digests = {which: hashlib.sha256(data).hexdigest()[:16] for which, data in copies}
    skipped = [side for side, flag in (("source", source_changes_later), ("destination", destination_changes_later))
               if flag]
    note = f" ({' and '.join(skipped)} not compared: another subtask changes it)" if skipped else ""
    return Verdict.check(len(set(digests.values())) == 1, want,
                         "sha256 " + ", ".join(f"{k} {v}" for k, v in digests.items()) + note)


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
    damaged = changed_files(state, [path], platform) if unchanged else []
    want = f"{path} executable by its owner" + (", its content unchanged" if unchanged else "")
    return Verdict.check(not damaged, want, "; ".join(damaged) or f"mode {mode}")


def check_line_endings(data: bytes, ending: str, original: bytes | None = None) -> Verdict:
    """Every line of `data` ends with `ending` ("crlf" or "lf"), there is more than one line and no stray CR; and
    when the text before the conversion (`original`) is known, the lines are the original's lines, unchanged
    (trailing blank lines and spaces aside)."""
    crlf, lf, cr = data.count(b"\r\n"), data.count(b"\n"), data.count(b"\r")
    found = f"{crlf} CRLF and {lf - crlf} LF line ends" + (f" and {cr - crlf} stray CR" if cr > crlf else "")
    if ending == "crlf":
        verdict = Verdict.check(crlf > 1 and crlf == lf == cr, "every line ending in CRLF (Windows/DOS)", found)
    else:
        verdict = Verdict.check(lf > 1 and cr == 0, "every line ending in LF (Unix)", found)
    if not verdict.passed or original is None:
        return verdict
    got, want = text_lines(as_text(data)), text_lines(as_text(original))
    return Verdict.check(got == want, f"{ending.upper()} line ends and the {len(want)} lines of the original unchanged",
                         "the same lines" if got == want else _first_difference(got, want))


@evaluator("file_line_endings")
def file_line_endings(state: FinalState, path: str, ending: str, contains: str | None = None,
                      platform: str | None = None) -> Verdict:
    """Every line of `path` ends with `ending` (crlf or lf), and its lines are those it had at set-up (the
    template lists `path` under `baseline`); with no baseline, its text still contains `contains`."""
    original = state.baseline(path, platform)

    def check(data: bytes) -> Verdict:
        if original is None and contains is not None and str(contains) not in as_text(data):
            return Verdict.check(False, f"{path} still containing {_short(str(contains))}", _short(as_text(data)))
        return check_line_endings(data, ending.lower(), original)
    return judge_file(state, path, f"{path} with {ending.upper()} line ends", bytes, check, platform)


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


def check_lines_filtered(text: str, word: str, kept: list[str], original: str | None = None) -> Verdict:
    """No line of `text` contains `word`, and every line of `kept` is still there. When the text before the edit
    (`original`) is known: the non-blank lines are exactly the original's lines without `word`, in their order and
    unchanged (blank lines and trailing spaces aside)."""
    lines = [line.strip() for line in text.splitlines()]
    bad = [line for line in lines if word.casefold() in line.casefold()]
    if original is not None:
        got = text_lines(text, blank=False)
        want = [line for line in text_lines(original, blank=False) if word.casefold() not in line.casefold()]
        found = "so" if got == want else (f"{len(bad)} line(s) with it, e.g. {_short(bad[0])}" if bad
                                          else _first_difference(got, want))
        return Verdict.check(got == want, f"the lines containing {word!r} deleted and the {len(want)} other lines "
                             "kept unchanged", found)
    lost = [k for k in kept if k.strip() not in lines]
    ok = not bad and not lost
    found = (f"{len(bad)} line(s) with it, e.g. {_short(bad[0])}" if bad else "none with it") + \
        (f"; lost {lost!r}" if lost else "")
    return Verdict.check(ok, f"no line containing {word!r} and the {len(kept)} other lines kept", found)


@evaluator("file_lines_without")
def file_lines_without(state: FinalState, path: str, word: str, kept: list[str],
                       platform: str | None = None) -> Verdict:
    """The lines of `path` containing `word` deleted, the others as they were at set-up (the template lists `path`
    under `baseline`); with no baseline, the lines `kept` are still somewhere in the file."""
    original = state.baseline(path, platform)
    return judge_file(state, path, f"{path} without lines containing {word!r}", as_text,
                      lambda text: check_lines_filtered(text, str(word), kept,
                                                        None if original is None else as_text(original)), platform)


def check_replaced(text: str, old: str, new: str, original: str | None = None) -> Verdict:
    """Every `old` of the text replaced by `new`: when the text before the edit (`original`) is known, `text` is
    exactly the original with that replacement (trailing blank lines and spaces aside); otherwise `new` is there
    and `old` is not."""
    if original is not None:
        got, want = text_lines(text), text_lines(original.replace(old, new))
        return Verdict.check(got == want, f"the original text with every {old!r} replaced by {new!r} and nothing "
                             "else changed", "so" if got == want else _first_difference(got, want))
    ok = new in text and old not in text
    return Verdict.check(ok, f"{new!r} and no {old!r}", _short(text))


@evaluator("file_text_replaced")
def file_text_replaced(state: FinalState, path: str, old: str, new: str, platform: str | None = None) -> Verdict:
    """`path` is its set-up text (the template lists it under `baseline`) with every `old` replaced by `new`, the
    rest unchanged. With no baseline (an upstream subtask made the file) only: `new` present, `old` absent."""
    original = state.baseline(path, platform)
    return judge_file(state, path, f"{path} with {old!r} replaced by {new!r}", as_text,
                      lambda text: check_replaced(text, str(old), str(new),
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
        damaged = changed_files(state, [f"{folder}/{posixpath.basename(n)}" for n in names], platform)
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
    damaged = changed_files(state, [archive], platform)
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


TRASH = "/home/user/.local/share/Trash"


def check_trashinfo(infos: dict[str, str], original: str, data: dict[str, bytes | None] | None = None,
                    content: bytes | None = None) -> Verdict:
    """Some freedesktop.org `.trashinfo` text of `infos` (file name → text) records `original` as its Path; when
    the file's content at set-up (`content`) is known, the trashed data of that entry (`data[info name]`) is it."""
    want = f"{original} in the trash" + (f" with its content ({len(content)} bytes)" if content is not None else "")
    named = []
    for name, text in infos.items():
        for line in text.splitlines():
            key, _, value = line.partition("=")
            if key.strip() == "Path" and unquote(value.strip()) == original:
                named.append(name)
    if not named:
        return Verdict.check(False, want, f"trash entries {sorted(infos)[:10] or 'none'}")
    if content is None or data is None:
        return Verdict.check(True, want, named[0])
    good = [n for n in named if data.get(n) == content]
    if good:
        return Verdict.check(True, want, good[0])
    sizes = ", ".join(f"{n}: {_size(data.get(n))}" for n in named)
    return Verdict.check(False, want, f"an entry naming it whose data is another file ({sizes})")


@evaluator("file_in_trash")
def file_in_trash(state: FinalState, name: str, original: str, trash: str = TRASH,
                  platform: str | None = None) -> Verdict:
    """The desktop user's trash holds the file once at `original`: a `.trashinfo` names it and its data is there —
    the bytes `original` had at set-up when the template lists it under `baseline` (in a composed task an
    upstream subtask may make the file: then only that the entry and some data are there)."""
    listing = state.run(f"ls -1 {shlex.quote(trash)}/info 2>/dev/null", platform).stdout.splitlines()
    infos, data = {}, {}
    for info in listing:
        if info.endswith(".trashinfo"):
            stored = state.pull(f"{trash}/files/{info[:-len('.trashinfo')]}", platform)
            if stored is not None:
                infos[info] = state.pull_text(f"{trash}/info/{info}", platform) or ""
                data[info] = stored
    return check_trashinfo(infos, original, data, state.baseline(original, platform))
