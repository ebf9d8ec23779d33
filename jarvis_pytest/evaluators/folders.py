"""Where files are, judged the same way on every platform from `file_facts`: a file moved, renamed or copied, files
sorted into a sub-folder, a file deleted (to the trash or not, no copy of it kept), a file deleted to the trash,
what a folder holds, a folder structure recreated, and what a task had to leave as it was (`changed_since_setup`,
the one such check every evaluator uses).

Every entry counts, hidden and system ones included: a leftover kept but hidden is a leftover, a hidden extra file
is an extra file. Only a file the desktop itself writes into folders (`PlatformSpec.shell_files`, e.g. Explorer's
desktop.ini, and only when it is exactly such a file: `file_facts.shell_made`) is passed over. A file the task
puts somewhere must be a file of its own (not a link, not a second name of another file) and not hidden, unless
its very name hides it. Expected content is the content the set-up gave (the template lists the path under
`baseline`); a path with no baseline (an upstream subtask of a composed task makes it) is checked for its place
only. A folder a task must leave alone is compared with its snapshot taken right after set-up (`snapshots.py`).
Paths are compared as the platform does (`PlatformSpec.normalise`: without case on Windows).
"""

from __future__ import annotations

import hashlib
import ntpath
import posixpath
from typing import Any

from jarvis_pytest.devices.platforms import PlatformSpec, spec
from jarvis_pytest.errors import ConfigError
from jarvis_pytest.evaluators.file_facts import (NOTHING, Entry, Facts, basename, hides_name, read_facts,
                                                 shell_made)
from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.snapshots import setup_snapshot, snapshot_key
from jarvis_pytest.evaluators.state import FinalState

Tree = dict[str, Entry]
LEFTOVER_DEPTH = 2  # how deep a file's old folder is searched for copies of it left behind


# -- small helpers ---------------------------------------------------------------------------------------------
def platform_of(state: FinalState, platform: str | None) -> PlatformSpec:
    return spec(platform or state.platform)


def parent(plat: PlatformSpec, path: str) -> str:
    """The folder that holds `path`."""
    return (ntpath if plat.path_style == "windows" else posixpath).dirname(path.rstrip("\\/"))


def inside(plat: PlatformSpec, folder: str, path: str) -> str:
    """`path` relative to `folder` in comparable form (as `keyed` keys a folder's entries); "" when not inside."""
    root, full = plat.normalise(folder).rstrip(plat.sep) + plat.sep, plat.normalise(path)
    return full[len(root):] if full.startswith(root) else ""


def baseline_sha(state: FinalState, path: str, platform: str | None = None) -> str | None:
    """The SHA-256 of what `path` held right after set-up (None: no baseline)."""
    data = state.baseline(path, platform)
    return None if data is None else hashlib.sha256(data).hexdigest()


def keyed(plat: PlatformSpec, tree: Tree) -> dict[str, tuple[str, Entry]]:
    """A folder's entries by comparable path (`normalise`) → (the path as found, its facts)."""
    return {plat.normalise(rel): (rel, entry) for rel, entry in tree.items()}


def check_file(plat: PlatformSpec, entry: Entry | None, want_sha: str | None, what: str, name: str = "",
               shown: bool = True) -> str | None:
    """Why `entry` is not a regular, independent file with the content `want_sha` (None: any content), shown
    (not hidden, unless `name`, the name asked for, itself hides it; `shown=False`: hidden or not); None when it
    is."""
    entry = entry or NOTHING
    if not entry.exists:
        return f"no {what}"
    if entry.kind != "file":
        return f"{what} is {entry.describe()}, not a file"
    if entry.links > 1:
        return f"{what} is a second name of another file (a hard link), not a file of its own"
    if want_sha is not None and entry.sha256 != want_sha:
        return f"{what} holds other content ({entry.size} bytes)"
    if shown and (entry.hidden or entry.system) and not hides_name(plat, name or what):
        return f"{what} is hidden ({entry.describe()})"
    return None


def counted(plat: PlatformSpec, found: dict[str, tuple[str, Entry]]) -> dict[str, tuple[str, Entry]]:
    """`found` without the files the desktop itself wrote (`shell_made`); everything else counts, hidden or not."""
    return {k: (rel, e) for k, (rel, e) in found.items() if not shell_made(plat, rel, e)}


def label(rel: str, entry: Entry) -> str:
    """An entry for a reason: its path, and what it is when that matters (hidden, a folder)."""
    marks = [m for m, on in (("hidden", entry.hidden), ("system", entry.system), ("a folder", entry.kind == "dir"))
             if on]
    return rel + (f" ({', '.join(marks)})" if marks else "")


def copies_left(plat: PlatformSpec, tree: Tree, digests: dict[str, str], allowed: set[str]) -> list[str]:
    """Files of `tree` holding the content of one of `digests` (name → sha256) at a place not in `allowed`
    (comparable paths): copies of a file that was to leave, kept under another name, hidden, or dressed as a file
    the desktop writes."""
    out = []
    for key, (rel, entry) in sorted(keyed(plat, tree).items()):
        for name, sha in digests.items():
            if key not in allowed and entry.kind == "file" and entry.sha256 == sha:
                out.append(f"a copy of {name} left at {label(rel, entry)}")
    return out


# -- what a task must leave as it was --------------------------------------------------------------------------
def tree_json(tree: Tree) -> dict[str, dict[str, Any]]:
    return {rel: {"kind": e.kind, "sha256": e.sha256, "hidden": e.hidden, "system": e.system, "links": e.links}
            for rel, e in tree.items()}


def capture_folders(state: FinalState, paths: list[str] | None, platform: str | None = None) -> dict[str, Any]:
    """Set-up capture: the whole content of each of `paths` that is a folder (files have their `baseline`)."""
    plat = platform_of(state, platform)
    facts = read_facts(state, trees=list(paths or []), platform=plat.name)
    return {snapshot_key("folder " + plat.normalise(p)): tree_json(t) for p, t in facts.trees.items() if t is not None}


def folder_changes(plat: PlatformSpec, before: dict[str, dict], now: Tree | None) -> list[str]:
    """How a folder's content `now` differs from its set-up snapshot `before`: entries gone, changed (kind,
    content, hidden or system mark, a file turned into a hard link) or added (hidden ones too)."""
    if now is None:
        return ["the folder is gone"]
    found = counted(plat, keyed(plat, now))
    was = {plat.normalise(rel): (rel, facts) for rel, facts in before.items()}
    problems = []
    for key, (rel, old) in sorted(was.items()):
        if key not in found:
            problems.append(f"{rel} gone")
            continue
        new = tree_json({rel: found[key][1]})[rel]
        if new != old:
            what = [k for k in ("kind", "sha256", "hidden", "system", "links") if new[k] != old[k]]
            problems.append(f"{rel} changed ({', '.join('content' if k == 'sha256' else k for k in what)})")
    added = [label(rel, e) for key, (rel, e) in sorted(found.items()) if key not in was]
    if added:
        problems.append(f"added {added[:6]}" + (f" and {len(added) - 6} more" if len(added) > 6 else ""))
    return problems


def changed_since_setup(state: FinalState, paths: list[str] | None, platform: str | None = None, *,
                        folders: list[str] | None = None, facts: Facts | None = None) -> list[str]:
    """What changed since set-up among `paths` and `folders`, each said as "<path>: <what>" (empty: nothing) — the
    one check of "left as it was" for every evaluator and platform. A file of `paths` must still be there as a
    regular file of its own (not a link, not a second name of another file), not hidden unless its name hides it,
    holding its baseline's bytes (a path with no baseline — an upstream subtask of a composed task made it — is
    checked for all but its content). A path of `paths` with a set-up snapshot (`capture_folders`), and every path
    of `folders` (which must have one), is a folder compared with its snapshot (`folder_changes`: hidden and
    system entries count). `facts`: what the caller already read, used for the files it holds."""
    plat = platform_of(state, platform)

    def snapped(path: str) -> bool:
        return state.baseline(snapshot_key("folder " + plat.normalise(path)), plat.name) is not None

    trees = [*(folders or []), *(p for p in paths or [] if p not in (folders or []) and snapped(p))]
    files = [p for p in paths or [] if p not in trees]
    if not trees and not files:
        return []
    if trees or facts is None or any(p not in facts.entries for p in files):
        facts = read_facts(state, entries=files, trees=trees, platform=plat.name)
    problems = []
    for path in files:
        entry = facts.entries.get(path, NOTHING)
        why = check_file(plat, entry, baseline_sha(state, path, plat.name), "it", path) if entry.exists else "gone"
        if why:
            problems.append(f"{path}: {why}")
    for folder in trees:
        before = setup_snapshot(state, "folder " + plat.normalise(folder), plat.name)
        problems += [f"{folder}: {why}" for why in folder_changes(plat, before, facts.trees.get(folder))]
    return problems


def with_unchanged(state: FinalState, verdict: Verdict, want: str, platform: str | None,
                   unchanged: list[str] | None = None, folders: list[str] | None = None) -> Verdict:
    """`verdict`, failed as well when something of `unchanged` or `folders` changed since set-up
    (`changed_since_setup`)."""
    named = [*(folders or []), *(unchanged or [])]
    if not verdict.passed or not named:
        return verdict
    lost = changed_since_setup(state, unchanged, platform, folders=folders)
    return Verdict.check(not lost, f"{want}, {', '.join(named)} unchanged", "; ".join(lost) or "so")


def found_part(verdict: Verdict) -> str:
    """What a verdict's reason says was found (the text after "found ")."""
    return verdict.reason.split("found ", 1)[-1]


# -- moved, sorted ----------------------------------------------------------------------------------------------
def check_moved(plat: PlatformSpec, dest: Entry, source: Entry, original_sha: str | None, name: str,
                copies: list[str]) -> Verdict:
    """A file moved (or renamed): nothing left at the source (hidden or not), at the destination a file of its own
    holding what the source held at set-up (`original_sha`; None: unknown, so any content), and no copy of it
    left behind (`copies`)."""
    want = "the file moved: none left at its old place, its content" + (
        "" if original_sha is None else " (as at set-up)") + " at the new one"
    problems = []
    why = check_file(plat, dest, original_sha, "file at the new place", name)
    if why:
        problems.append(why)
    if source.exists:
        problems.append(f"the original still at its old place ({source.describe()})" + (
            "" if why else ": copied, not moved"))
    problems += copies
    return Verdict.check(not problems, want, "; ".join(problems) or "so")


@evaluator("file_moved")
def file_moved(state: FinalState, path: str, original: str, kept: list[str] | None = None,
               platform: str | None = None) -> Verdict:
    """The file once at `original` is now at `path` (moved or renamed): nothing at `original` (hidden or not), at
    `path` a file of its own with the bytes `original` had at set-up, no copy of those bytes left in its old folder
    (under another name, hidden or not), and the files of `kept` unchanged. When `original` has no baseline (an
    upstream subtask of a composed task made it) only the move itself is checked."""
    plat = platform_of(state, platform)
    if plat.normalise(path) == plat.normalise(original):
        raise ConfigError(f"file_moved: `path` and `original` are one path ({path})", field="evaluate.args",
                          fix="give the file's new place as `path` and its set-up place as `original`")
    original_sha = baseline_sha(state, original, plat.name)
    old_folder = parent(plat, original)
    facts = read_facts(state, entries=[path, original, *(kept or [])], trees=[old_folder] if original_sha else [],
                       depth=LEFTOVER_DEPTH, platform=plat.name)
    copies = []
    if original_sha:
        copies = copies_left(plat, facts.trees.get(old_folder) or {}, {basename(plat, original): original_sha},
                             {inside(plat, old_folder, p) for p in (path, original)})
    verdict = check_moved(plat, facts.entries[path], facts.entries[original], original_sha, basename(plat, path),
                          copies)
    lost = changed_since_setup(state, kept, plat.name, facts=facts)
    if not verdict.passed or not lost:
        return verdict
    return Verdict.check(False, f"{original} moved to {path} with its content, the other files unchanged",
                         "; ".join(lost))


def check_sorted(plat: PlatformSpec, sub: str, tree: Tree, originals: dict[str, str | None], moved: list[str],
                 kept: list[str]) -> Verdict:
    """A folder sorted (`tree`: its content two levels deep): each name of `moved` is in the sub-folder `sub` and
    no longer at the top (hidden or not), each of `kept` still at the top and not in `sub`, each with its set-up
    content (`originals[name]`: the sha256 at set-up; None: unknown for a moved name, and a kept name that did not
    exist at set-up is skipped); `sub` holds nothing else, and no copy of a moved file is left anywhere else."""
    found = counted(plat, keyed(plat, tree))
    sep = plat.sep
    sub_key = plat.normalise(sub)
    top = {k: v for k, v in found.items() if sep not in k}
    inside = None
    if sub_key in top and top[sub_key][1].kind == "dir":
        inside = {k[len(sub_key) + 1:]: (rel[len(sub) + 1:], e) for k, (rel, e) in found.items()
                  if k.startswith(sub_key + sep)}
    problems = [] if inside is not None else [f"no folder {sub}" + (
        f" ({top[sub_key][1].describe()} there)" if sub_key in top else "")]
    inside = inside or {}
    for name in moved:
        key = plat.normalise(name)
        why = check_file(plat, inside.get(key, (name, NOTHING))[1], originals.get(name), f"{name} in {sub}", name)
        if why:
            problems.append(why)
        if key in top:
            problems.append(f"{label(*top[key])} still in the folder")
    for name in kept:
        if originals.get(name) is None:
            continue
        key = plat.normalise(name)
        why = check_file(plat, top.get(key, (name, NOTHING))[1], originals[name], name, name)
        if why:
            problems.append(why.replace(f"no {name}", f"{name} gone from the folder"))
        if key in inside:
            problems.append(f"{name} put in {sub} too")
    names = {plat.normalise(n) for n in [*moved, *kept]}
    extra = [label(rel, e) for key, (rel, e) in sorted(inside.items()) if key not in names]
    if extra:
        problems.append(f"{sub} also holds {extra[:5]}")
    digests = {name: originals[name] for name in moved if originals.get(name)}
    allowed = {f"{sub_key}{sep}{plat.normalise(n)}" for n in moved} | {plat.normalise(n) for n in moved}
    problems += copies_left(plat, tree, digests, allowed)
    checked = [k for k in kept if originals.get(k) is not None]
    want = f"{', '.join(moved)} moved into {sub} unchanged, {', '.join(checked) or 'no other file'} left in place"
    return Verdict.check(not problems, want, "; ".join(problems) or "so")


@evaluator("folder_sorted")
def folder_sorted(state: FinalState, folder: str, sub: str, moved: list[str], kept: list[str],
                  platform: str | None = None) -> Verdict:
    """The files `moved` (names) of `folder` are in its new sub-folder `sub` and no longer in `folder`, the files
    `kept` are still in `folder` and not in `sub`, all with their set-up content; `sub` holds nothing else and no
    copy of a moved file is left in `folder` (hidden or under another name). The template lists every
    `folder/<name>` under `baseline`: a kept name with no baseline did not exist at set-up and is skipped, a moved
    name with no baseline is checked for its place only."""
    plat = platform_of(state, platform)
    tree = read_facts(state, trees=[folder], depth=2, platform=plat.name).trees[folder]
    if tree is None:
        return Verdict.check(False, f"the folder {folder}", "no such folder")
    originals = {name: baseline_sha(state, plat.join(folder, name), plat.name) for name in [*moved, *kept]}
    return check_sorted(plat, sub, tree, originals, list(moved), list(kept))


# -- the trash ---------------------------------------------------------------------------------------------------
def check_trashed(plat: PlatformSpec, entries: list[tuple[str, Entry]], original: str,
                  original_sha: str | None) -> Verdict:
    """Some trash entry records `original` (compared as the platform compares paths) and holds its set-up content
    (`original_sha`; None: unknown, then any data)."""
    want = f"{original} in the trash" + (" with its content" if original_sha else "")
    named = [data for path, data in entries if plat.normalise(path) == plat.normalise(original)]
    if not named:
        return Verdict.check(False, want, f"trash entries {[p for p, _ in entries][:8] or 'none'}")
    whys = [check_file(plat, data, original_sha, "trashed data", shown=False) for data in named]
    if any(w is None for w in whys):
        return Verdict.check(True, want, "so")
    return Verdict.check(False, want, f"an entry naming it, but {whys[0]}")


@evaluator("file_in_trash")
def file_in_trash(state: FinalState, original: str, kept: list[str] | None = None,
                  platform: str | None = None) -> Verdict:
    """The file once at `original` was deleted to the desktop's trash (`PlatformSpec.trash`: the freedesktop.org
    trash on Linux; the Recycle Bin on Windows, which under Wine is the Unix user's freedesktop.org trash): nothing
    at `original` (hidden or not), an entry of the trash records that path and holds the bytes it had at set-up
    (listed under `baseline`; with no baseline, any data), no copy of them left in its folder, and the files of
    `kept` unchanged."""
    plat = platform_of(state, platform)
    if plat.trash is None:
        raise ConfigError(f"file_in_trash: the {plat.name} platform has no trash", field="evaluate.func",
                          fix="check the deletion with file_deleted instead")
    original_sha = baseline_sha(state, original, plat.name)
    folder = parent(plat, original)
    facts = read_facts(state, entries=[original, *(kept or [])], trees=[folder] if original_sha else [],
                       depth=LEFTOVER_DEPTH, trash=True, platform=plat.name)
    left = facts.entries[original]
    if left.exists:
        return Verdict.check(False, f"{original} deleted to the trash", f"it still there ({left.describe()})")
    verdict = check_trashed(plat, facts.trash or [], original, original_sha)
    if not verdict.passed:
        return verdict
    problems = changed_since_setup(state, kept, plat.name, facts=facts)
    if original_sha:
        problems += copies_left(plat, facts.trees.get(folder) or {}, {basename(plat, original): original_sha}, set())
    return Verdict.check(not problems, f"{original} in the trash, the other files unchanged",
                         "; ".join(problems) or "so")


# -- deleted -----------------------------------------------------------------------------------------------------
def search_roots(plat: PlatformSpec, path: str) -> list[str]:
    """Where copies of a deleted file are looked for: every place the user may keep files (`PlatformSpec.user_roots`)
    and the file's own folder, when it is outside them."""
    roots = list(plat.user_roots)
    folder = parent(plat, path)
    if folder and not any(plat.normalise(folder) == plat.normalise(r) or inside(plat, r, folder) for r in roots):
        roots.append(folder)
    return roots


def trashed(plat: PlatformSpec, found: str, original: str) -> bool:
    """Whether the file at `found` is the platform's trash holding `original`: a file under the trash folder
    (`PlatformSpec.trash`: a freedesktop.org trash, or a Recycle Bin folder on any drive), or `original` renamed in
    its own folder with the trash's mark (`PlatformSpec.trash_prefix`: Android's `.trashed-<expiry>-<name>`)."""
    if plat.trash:
        if plat.is_absolute(plat.trash):
            if inside(plat, plat.trash, found):
                return True
        elif plat.normalise(plat.trash) in plat.normalise(found).split(plat.sep):
            return True
    if plat.trash_prefix and plat.normalise(parent(plat, found)) == plat.normalise(parent(plat, original)):
        name, base = basename(plat, found), basename(plat, original)
        marked = name[len(plat.trash_prefix):] if name.startswith(plat.trash_prefix) else ""
        expiry, _, rest = marked.partition("-")
        return expiry.isdigit() and rest == base
    return False


def check_deleted(plat: PlatformSpec, path: str, left: Entry, copies: list[str], changed: list[str],
                  kept: list[str]) -> Verdict:
    """The file at `path` is deleted: nothing there (`left`, hidden or not, a link too), no copy of its bytes kept
    anywhere (`copies`: where they are, outside the trash), and nothing changed among the files of `kept`
    (`changed`, as `changed_since_setup` says it)."""
    want = f"{path} deleted (gone, or in the trash)" + (f" and the {len(kept)} other file(s) kept unchanged"
                                                         if kept else "")
    problems = [f"{path} still there ({left.describe()})"] if left.exists else []
    if copies:
        problems.append(f"its content still at {', '.join(copies[:3])}" + (
            f" and {len(copies) - 3} more" if len(copies) > 3 else "") + ": moved or copied, not deleted")
    problems += changed
    return Verdict.check(not problems, want, "; ".join(problems) or "deleted, the others kept")


@evaluator("file_deleted")
def file_deleted(state: FinalState, path: str, kept: list[str] | None = None, platform: str | None = None) -> Verdict:
    """The file at `path` is deleted — removed, or put in the platform's trash (`trashed`) — and not moved, copied
    or hidden instead: nothing at `path` (hidden or not, not even a link), and no file anywhere the user may keep
    files (`search_roots`: `PlatformSpec.user_roots` and its own folder) holds the bytes it had at set-up, under any
    name, hidden or not, as a second name (hard link) or not — except files that held them at set-up too (listed
    under `baseline`). Without a baseline (an input an upstream subtask of a composed task made, whose source may
    rightly hold the same bytes) only its absence is checked. Every file of `kept` is still there unchanged
    (`changed_since_setup`)."""
    plat = platform_of(state, platform)
    original = state.baseline(path, plat.name)
    roots = search_roots(plat, path) if original is not None else []
    facts = read_facts(state, entries=[path, *(kept or [])], search=roots,
                       sizes=[len(original)] if original is not None else [], platform=plat.name)
    copies = []
    if original is not None:
        sha = hashlib.sha256(original).hexdigest()
        for where, entry in sorted((facts.found or {}).items()):
            if entry.kind != "file" or entry.sha256 != sha or plat.normalise(where) == plat.normalise(path):
                continue
            if trashed(plat, where, path) or baseline_sha(state, where, plat.name) == sha:
                continue
            copies.append(label(where, entry) + (" (a second name of it: a hard link)" if entry.links > 1 else ""))
    return check_deleted(plat, path, facts.entries[path], copies,
                         changed_since_setup(state, kept, plat.name, facts=facts), list(kept or []))


# -- what a folder holds -------------------------------------------------------------------------------------------
def check_tree(plat: PlatformSpec, root: str, tree: Tree | None, dirs: list[str], files: dict[str, str | None],
               absent: list[str], exact: bool) -> Verdict:
    """A folder's content (`tree`, None when `root` is no folder): every path of `dirs` a folder, every path of
    `files` a file with the content `files[path]` (a sha256; None: any content), nothing at the paths of `absent`
    (hidden or not), and with `exact` nothing else at all (hidden entries too; `shell_made` files aside)."""
    want = (f"{root} holding the folders {dirs or '(none)'} and the files {sorted(files) or '(none)'}"
            + (" and nothing else" if exact else "") + (f", without {absent}" if absent else ""))
    if tree is None:
        return Verdict.check(False, want, f"no folder {root}")
    found = counted(plat, keyed(plat, tree))
    problems = []
    for rel in dirs:
        rel_found, entry = found.get(plat.normalise(rel), (rel, NOTHING))
        if entry.kind != "dir":
            problems.append(f"{rel} is {entry.describe()}, not a folder")
        elif entry.hidden or entry.system:
            problems.append(f"{rel} is hidden ({entry.describe()})")
    for rel, sha in files.items():
        why = check_file(plat, found.get(plat.normalise(rel), (rel, NOTHING))[1], sha, rel, rel)
        if why:
            problems.append(why)
    for rel in absent:
        if plat.normalise(rel) in found:
            problems.append(f"{label(*found[plat.normalise(rel)])} still there")
    if exact:
        allowed = {plat.normalise(p) for p in [*dirs, *files]}
        for p in list(allowed):  # the folders on the way to an expected path are expected too
            while plat.sep in p:
                p = p.rsplit(plat.sep, 1)[0]
                allowed.add(p)
        extra = [label(rel, e) for key, (rel, e) in sorted(found.items()) if key not in allowed]
        if extra:
            problems.append(f"also {extra[:6]}" + (f" and {len(extra) - 6} more" if len(extra) > 6 else ""))
    return Verdict.check(not problems, want, "; ".join(problems) or "so")


@evaluator("folder_holds")
def folder_holds(state: FinalState, root: str, dirs: list[str] | None = None, files: list[list[str]] | None = None,
                 absent: list[str] | None = None, exact: bool = False, platform: str | None = None) -> Verdict:
    """The folder `root` holds the sub-folders `dirs` and the files `files` (paths inside `root`), with nothing at
    the paths of `absent`, and — with `exact` — nothing else (hidden and system entries count: `check_tree`).
    `files` lists `[path inside root, device path whose set-up content it must hold]` pairs (the source listed
    under `baseline`; "" for any content; a source with no baseline, made by an upstream subtask, also means any
    content) — pairs, not a mapping, so that both sides may be templated."""
    plat = platform_of(state, platform)
    tree = read_facts(state, trees=[root], platform=plat.name).trees[root]
    want_files = {rel: (baseline_sha(state, src, plat.name) if src else None) for rel, src in (files or [])}
    return check_tree(plat, root, tree, list(dirs or []), want_files, list(absent or []), exact)


@evaluator("folders_copied")
def folders_copied(state: FinalState, source: str, target: str, dirs: list[str],
                   files: list[list[str]] | None = None, platform: str | None = None) -> Verdict:
    """The folder structure of `source` recreated under `target` without its files: `target` holds exactly the
    sub-folders `dirs` (paths inside it, at every depth) and nothing else; and `source` is as the set-up left it —
    exactly `dirs` and the files `files` (`[path inside source, device path whose set-up content it holds]`,
    see `folder_holds`). Hidden and system entries count on both sides."""
    plat = platform_of(state, platform)
    trees = read_facts(state, trees=[target, source], platform=plat.name).trees
    made = check_tree(plat, target, trees.get(target), list(dirs), {}, [], exact=True)
    want_files = {rel: (baseline_sha(state, src, plat.name) if src else None) for rel, src in (files or [])}
    kept = check_tree(plat, source, trees.get(source), list(dirs), want_files, [], exact=True)
    want = f"the {len(dirs)} folders of {source} recreated under {target} without files, {source} unchanged"
    if not made.passed:
        return Verdict.check(False, want, found_part(made))
    return Verdict.check(kept.passed, want, "so" if kept.passed else f"{source}: {found_part(kept)}")


# -- copies ---------------------------------------------------------------------------------------------------------
def check_copied(plat: PlatformSpec, copy: Entry, source: Entry, original_sha: str | None, copy_name: str = "",
                 source_name: str = "") -> Verdict:
    """`copy` is an independent copy of `source`: a regular file of its own (not a link, not a second name of the
    source or of any file), shown unless its name (`copy_name`) hides it, holding the source's bytes; the source
    still there as a shown regular file of its own (unless `source_name` hides it), holding what it held at set-up
    (`original_sha`; None: unknown, then the two are compared as they are) — so an emptied, rewritten, hidden or
    linked source cannot make a wrong copy match."""
    want = "an independent copy holding the original's content, the original kept as set up"
    if not source.exists:
        return Verdict.check(False, want, "the original gone" + ("" if copy.exists else ", and no copy"))
    why = check_file(plat, source, original_sha, "original", source_name)
    if why:
        return Verdict.check(False, want, why.replace("original holds", "the original changed: it holds"))
    why = check_file(plat, copy, source.sha256, "copy", copy_name)
    return Verdict.check(why is None, want, why or f"identical ({copy.size} bytes)")


@evaluator("file_copied")
def file_copied(state: FinalState, path: str, source: str, platform: str | None = None) -> Verdict:
    """`path` is a copy of `source` (see `check_copied`), on any platform: a download, a "Save a copy", a file
    manager's or a shell's copy. The template lists `source` under `baseline`; in a composed task an upstream
    subtask may make `source` (no baseline): the copy is then compared with it as it is."""
    plat = platform_of(state, platform)
    facts = read_facts(state, entries=[path, source], platform=plat.name)
    return check_copied(plat, facts.entries[path], facts.entries[source], baseline_sha(state, source, plat.name),
                        basename(plat, path), basename(plat, source))
