"""Windows file-system, Recycle Bin and program checks (File Explorer, Wine's file manager, Command Prompt and Task
Manager templates), read through the control server without a Unix shell.

What the server's file API does not say (is a path a folder, a hard link, a hidden file; what a folder holds; which
processes and windows there are; what the Recycle Bin holds) is read by a small probe: a Python script put on the
device through the file API and run with the device's own embeddable CPython (`C:\\jarvis\\python\\python.exe`,
on both backends), which writes its findings as JSON to a file that is fetched back and removed. Why not
`tasklist` or `dir`: under Wine 8 `tasklist` prints nothing (even redirected to a file), `find /c` and `findstr`
print nothing or refuse, and the output of any program the server's `cmd /c` starts (as opposed to cmd's own
commands such as `dir`) never reaches the server (see `windows_files` in the report of issue 17); the probe
writes its own file, so none of that matters.

Expected content comes from the task's own inputs: a file made at set-up is compared with its bytes right after
set-up (the template lists it under `baseline`), never with what the agent left. In a composed task an upstream
subtask may make the file, so there is no baseline: each evaluator then says what it checks instead.
Windows paths are compared case-insensitively (`PLATFORMS["windows"].normalise`).
"""

from __future__ import annotations

import base64
import hashlib
import json
import ntpath
import uuid
from typing import Any
from urllib.parse import unquote

from jarvis_pytest.devices.platforms import PLATFORMS
from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.state import FinalState

WINDOWS = PLATFORMS["windows"]
PYTHON = r"C:\jarvis\python\pythonw.exe"  # no console window
PROBE_DIR = r"C:\temp\jarvis-probe"
IGNORED_NAMES = {"desktop.ini", "thumbs.db"}  # what Windows' own Explorer leaves in folders (hidden, system)

# The probe: runs on the device (Windows' CPython, standard library and ctypes only). argv: request.json out.json
PROBE = r'''
import base64, hashlib, json, os, stat, sys, traceback


def sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def entry(path):
    try:
        st = os.lstat(path)
    except OSError:
        return {"exists": False}
    attrs = getattr(st, "st_file_attributes", 0)
    is_dir = stat.S_ISDIR(st.st_mode)
    link = stat.S_ISLNK(st.st_mode) or bool(attrs & 0x400)  # a symbolic link or another reparse point
    out = {"exists": True, "dir": is_dir, "link": link, "size": st.st_size, "hidden": bool(attrs & 0x6)}
    if not is_dir and not link:
        try:
            out["nlink"] = os.stat(path).st_nlink
            out["sha256"] = sha256(path)
        except OSError as exc:
            out["error"] = str(exc)
    return out


def tree(root, limit=5000):
    items = {}
    for base, dirs, files in os.walk(root):
        for name in sorted(dirs + files):
            full = os.path.join(base, name)
            items[os.path.relpath(full, root)] = entry(full)
            if len(items) >= limit:
                return items
    return items


def processes():
    import ctypes
    from ctypes import wintypes

    class PE(ctypes.Structure):
        _fields_ = [("dwSize", wintypes.DWORD), ("cntUsage", wintypes.DWORD), ("th32ProcessID", wintypes.DWORD),
                    ("th32DefaultHeapID", ctypes.c_size_t), ("th32ModuleID", wintypes.DWORD),
                    ("cntThreads", wintypes.DWORD), ("th32ParentProcessID", wintypes.DWORD),
                    ("pcPriClassBase", ctypes.c_long), ("dwFlags", wintypes.DWORD),
                    ("szExeFile", ctypes.c_wchar * 260)]

    k = ctypes.WinDLL("kernel32", use_last_error=True)
    k.CreateToolhelp32Snapshot.restype = wintypes.HANDLE
    k.CreateToolhelp32Snapshot.argtypes = [wintypes.DWORD, wintypes.DWORD]
    k.Process32FirstW.argtypes = k.Process32NextW.argtypes = [wintypes.HANDLE, ctypes.POINTER(PE)]
    k.CloseHandle.argtypes = [wintypes.HANDLE]
    snap = k.CreateToolhelp32Snapshot(2, 0)  # TH32CS_SNAPPROCESS
    pe = PE()
    pe.dwSize = ctypes.sizeof(PE)
    out = []
    ok = k.Process32FirstW(snap, ctypes.byref(pe))
    while ok:
        out.append({"pid": pe.th32ProcessID, "ppid": pe.th32ParentProcessID, "name": pe.szExeFile})
        ok = k.Process32NextW(snap, ctypes.byref(pe))
    k.CloseHandle(snap)
    return out


def windows():
    import ctypes
    from ctypes import wintypes

    u = ctypes.WinDLL("user32")
    out = []

    @ctypes.WINFUNCTYPE(wintypes.BOOL, wintypes.HWND, wintypes.LPARAM)
    def each(hwnd, _):
        n = u.GetWindowTextLengthW(hwnd)
        buf = ctypes.create_unicode_buffer(n + 1)
        u.GetWindowTextW(hwnd, buf, n + 1)
        pid = wintypes.DWORD()
        u.GetWindowThreadProcessId(hwnd, ctypes.byref(pid))
        if buf.value:
            out.append({"title": buf.value, "pid": pid.value, "visible": bool(u.IsWindowVisible(hwnd))})
        return True

    u.EnumWindows(each, 0)
    return out


def trash():
    out = {"xdg": [], "recycle": [], "prefix": os.environ.get("WINEPREFIX", "")}
    home = os.environ.get("WINEHOMEDIR", "")  # Wine: its Recycle Bin is the Unix user's freedesktop.org trash
    if home:
        home = home[4:] if home.startswith("\\??\\") else home
        base = os.path.join(home, ".local", "share", "Trash")
        info_dir = os.path.join(base, "info")
        for name in sorted(os.listdir(info_dir)) if os.path.isdir(info_dir) else []:
            if name.endswith(".trashinfo"):
                with open(os.path.join(info_dir, name), encoding="utf-8", errors="replace") as f:
                    text = f.read()
                out["xdg"].append({"name": name, "info": text,
                                   "data": entry(os.path.join(base, "files", name[:-len(".trashinfo")]))})
    for drive in "CDEFGHS":  # Windows: \$Recycle.Bin\<SID>\$I<id><ext> (the record) and $R<id><ext> (the data)
        root = drive + ":\\$Recycle.Bin"
        if not os.path.isdir(root):
            continue
        for base, dirs, files in os.walk(root):
            for name in files:
                if name.upper().startswith("$I"):
                    with open(os.path.join(base, name), "rb") as f:
                        record = base64.b64encode(f.read()).decode()
                    out["recycle"].append({"name": os.path.join(base, name), "info_b64": record,
                                           "data": entry(os.path.join(base, "$R" + name[2:]))})
    return out


def main(req_path, out_path):
    with open(req_path, encoding="utf-8") as f:
        req = json.load(f)
    out = {}
    try:
        out["entries"] = {p: entry(p) for p in req.get("entries", [])}
        out["trees"] = {r: tree(r) if os.path.isdir(r) else None for r in req.get("trees", [])}
        if req.get("processes"):
            out["processes"] = processes()
        if req.get("windows"):
            out["windows"] = windows()
        if req.get("trash"):
            out["trash"] = trash()
    except Exception:
        out["error"] = traceback.format_exc()
    with open(out_path, "w", encoding="utf-8") as f:
        json.dump(out, f)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
'''


def probe(state: FinalState, *, entries: list[str] | None = None, trees: list[str] | None = None,
          processes: bool = False, windows: bool = False, trash: bool = False,
          platform: str | None = None) -> dict[str, Any]:
    """Run the probe on the device: facts of `entries` (paths), the recursive content of `trees` (folders), the
    processes, the top-level windows, the Recycle Bin. An InfrastructureError when it cannot run."""
    device = state.device(platform)
    folder = f"{PROBE_DIR}\\{uuid.uuid4().hex[:12]}"
    request = {"entries": entries or [], "trees": trees or [], "processes": processes, "windows": windows,
               "trash": trash}
    device.upload(f"{folder}\\probe.py", PROBE.encode("utf-8"))
    device.upload(f"{folder}\\request.json", json.dumps(request).encode("utf-8"))
    try:
        res = device.run(f'"{PYTHON}" -I "{folder}\\probe.py" "{folder}\\request.json" "{folder}\\out.json"',
                         timeout=120)
        try:
            data = device.download(f"{folder}\\out.json")
        except Exception as exc:
            raise InfrastructureError(f"the evaluation probe wrote nothing (exit {res.returncode}: "
                                      f"{(res.stdout + res.stderr)[-500:]}): {exc}") from None
    finally:
        device.run(f'rmdir /s /q "{folder}"', timeout=60)
    out = json.loads(data.decode("utf-8"))
    if out.get("error"):
        raise InfrastructureError(f"the evaluation probe failed on the device: {out['error'][-800:]}")
    return out


# -- small helpers ---------------------------------------------------------------------------------------------
def norm(path: str) -> str:
    """A Windows path in comparable form (separators unified, case folded)."""
    return WINDOWS.normalise(path)


def rel_key(rel: str) -> str:
    """A path inside a folder in comparable form (`a/b` and `A\\b` are one)."""
    return ntpath.normpath(rel.replace("/", "\\")).casefold()


def digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _short(text: str, limit: int = 100) -> str:
    return repr(text if len(text) <= limit else text[:limit] + "…")


def decode_text(data: bytes) -> str:
    """Text a Windows program wrote: UTF-16 with its byte order mark, UTF-8 (a BOM dropped), else ANSI (cp1252)."""
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        return data.decode("utf-16")
    try:
        return data.decode("utf-8").lstrip("\ufeff")
    except UnicodeDecodeError:
        return data.decode("cp1252", errors="replace")


def visible_entries(tree: dict[str, dict]) -> dict[str, tuple[str, dict]]:
    """A probed tree's entries that a person sees, keyed by `rel_key` → (the path as found, its facts): hidden or
    system files and Explorer's own desktop.ini / Thumbs.db left out."""
    out = {}
    for rel, info in tree.items():
        if info.get("hidden") or ntpath.basename(rel.replace("/", "\\")).casefold() in IGNORED_NAMES:
            continue
        out[rel_key(rel)] = (rel.replace("/", "\\"), info)
    return out


def describe_entry(info: dict | None) -> str:
    if not info or not info.get("exists", True):
        return "nothing"
    if info.get("dir"):
        return "a folder"
    if info.get("link"):
        return "a link"
    return f"a file of {info.get('size', '?')} bytes"


def check_regular_file(info: dict | None, want_sha: str | None, what: str) -> str | None:
    """Why `info` (a probed entry) is not a regular, independent file with the content `want_sha` (None: any
    content); None when it is."""
    if not info or not info.get("exists"):
        return f"no {what}"
    if info.get("dir"):
        return f"{what} is a folder, not a file"
    if info.get("link"):
        return f"{what} is a link, not a file"
    if info.get("nlink", 1) > 1:
        return f"{what} is a second name of another file (a hard link), not a file of its own"
    if want_sha is not None and info.get("sha256") != want_sha:
        return f"{what} holds other content ({info.get('size')} bytes)"
    return None


def baseline_sha(state: FinalState, path: str, platform: str | None = None) -> str | None:
    data = state.baseline(path, platform)
    return None if data is None else digest(data)


def kept_problems(state: FinalState, facts: dict[str, dict], kept: list[str] | None,
                  platform: str | None = None) -> list[str]:
    """What happened to the files of `kept` that should be as they were at set-up: gone, changed (against their
    baseline; only their presence is checked for a path with no baseline)."""
    problems = []
    for path in kept or []:
        info = facts.get(path)
        want = baseline_sha(state, path, platform)
        why = check_regular_file(info, want, "it") if info and info.get("exists") else "gone"
        if why:
            problems.append(f"{path}: {why}")
    return problems


# -- files: moved, copied, sorted, trees -----------------------------------------------------------------------
def check_moved(dest: dict | None, source: dict | None, original_sha: str | None) -> Verdict:
    """A file moved (or renamed): nothing left at the source, and at the destination a regular file of its own
    holding what the source held at set-up (`original_sha`; None: unknown, so any content)."""
    want = "the file moved: none left at its old place, its content" + (
        "" if original_sha is None else " (as at set-up)") + " at the new one"
    left = bool(source and source.get("exists"))
    why = check_regular_file(dest, original_sha, "file at the new place")
    if why:
        return Verdict.check(False, want, why + ("; the original still at its old place" if left else ""))
    if left:
        return Verdict.check(False, want, "the original still at its old place (copied, not moved)")
    return Verdict.check(True, want, "so")


@evaluator("windows_file_moved")
def windows_file_moved(state: FinalState, path: str, original: str, kept: list[str] | None = None,
                       platform: str | None = None) -> Verdict:
    """The file once at `original` is now at `path` (moved or renamed; names compared as Windows does, without
    case): no file at `original`, at `path` a regular file with the bytes `original` had at set-up, and the files
    of `kept` unchanged. When `original` has no baseline (an upstream subtask of a composed task made it), only
    the move itself is checked."""
    if norm(path) == norm(original):
        raise ValueError(f"windows_file_moved: path and original are one path ({path})")
    facts = probe(state, entries=[path, original, *(kept or [])], platform=platform)["entries"]
    verdict = check_moved(facts.get(path), facts.get(original), baseline_sha(state, original, platform))
    if not verdict.passed:
        return verdict
    lost = kept_problems(state, facts, kept, platform)
    return Verdict.check(not lost, f"{original} moved to {path} with its content, the other files unchanged",
                         "; ".join(lost) or "so")


def check_copied(copy: dict | None, source: dict | None, original_sha: str | None) -> Verdict:
    """`copy` is an independent copy of `source`: a regular file of its own (not a link or a second name of the
    source) with the source's content; the source still there, holding what it held at set-up (`original_sha`;
    None: unknown, then the two are compared as they are)."""
    want = "an independent copy holding the original's content, the original kept"
    if not source or not source.get("exists"):
        return Verdict.check(False, want, "the original gone" + ("" if copy and copy.get("exists") else
                                                                  ", and no copy"))
    why = check_regular_file(source, original_sha, "original")
    if why:
        return Verdict.check(False, want, why.replace("original holds", "the original changed: it holds"))
    why = check_regular_file(copy, source.get("sha256"), "copy")
    return Verdict.check(why is None, want, why or "identical")


@evaluator("windows_file_copied")
def windows_file_copied(state: FinalState, path: str, source: str, platform: str | None = None) -> Verdict:
    """`path` is a copy of `source` (see `check_copied`), which the template lists under `baseline`; in a composed
    task an upstream subtask may make `source` (no baseline): the copy is then compared with it as it is."""
    facts = probe(state, entries=[path, source], platform=platform)["entries"]
    return check_copied(facts.get(path), facts.get(source), baseline_sha(state, source, platform))


def check_sorted(sub: str, top: dict[str, tuple[str, dict]], inside: dict[str, tuple[str, dict]] | None,
                 originals: dict[str, str | None], moved: list[str], kept: list[str]) -> Verdict:
    """A folder sorted: each name of `moved` is in the sub-folder `sub` (`inside`: its visible entries, None when
    it is no folder) and no longer at the top (`top`), each of `kept` still at the top and not in `sub`, each with
    its set-up content (`originals[name]`: the sha256 at set-up; None: unknown for a moved name, and a kept name
    that did not exist at set-up is skipped), and `sub` holds nothing else."""
    problems = []
    if inside is None:
        problems.append(f"no folder {sub}")
        inside = {}
    for name in moved:
        key = rel_key(name)
        why = check_regular_file(inside.get(key, (None, None))[1], originals.get(name), f"{name} in {sub}")
        if why:
            problems.append(why)
        if key in top:
            problems.append(f"{name} still in the folder")
    for name in kept:
        if originals.get(name) is None:
            continue
        key = rel_key(name)
        why = check_regular_file(top.get(key, (None, None))[1], originals[name], name)
        if why:
            problems.append(why.replace(f"no {name}", f"{name} gone from the folder"))
        if key in inside:
            problems.append(f"{name} put in {sub} too")
    extra = sorted(found for key, (found, _) in inside.items()
                   if key not in {rel_key(n) for n in [*moved, *kept]})
    if extra:
        problems.append(f"{sub} also holds {extra[:5]}")
    checked = [k for k in kept if originals.get(k) is not None]
    want = f"{', '.join(moved)} moved into {sub} unchanged, {', '.join(checked) or 'no other file'} left in place"
    return Verdict.check(not problems, want, "; ".join(problems) or "so")


@evaluator("windows_folder_sorted")
def windows_folder_sorted(state: FinalState, folder: str, sub: str, moved: list[str], kept: list[str],
                          platform: str | None = None) -> Verdict:
    """The files `moved` (names) of `folder` are in its new sub-folder `sub` and no longer in `folder`, the files
    `kept` are still in `folder` and not in `sub`, all with their set-up content. The template lists every
    `folder\\<name>` under `baseline`: a kept name with no baseline did not exist at set-up and is skipped, a moved
    name with no baseline is checked for its place only."""
    tree = probe(state, trees=[folder], platform=platform)["trees"][folder]
    if tree is None:
        return Verdict.check(False, f"the folder {folder}", "no such folder")
    entries = visible_entries(tree)
    top = {k: v for k, v in entries.items() if "\\" not in k}
    sub_key = rel_key(sub)
    inside = None
    if sub_key in top and top[sub_key][1].get("dir"):
        prefix = sub_key + "\\"
        inside = {k[len(prefix):]: (shown[len(prefix):], info) for k, (shown, info) in entries.items()
                  if k.startswith(prefix)}
    originals = {name: baseline_sha(state, f"{folder}\\{name}", platform) for name in [*moved, *kept]}
    return check_sorted(sub, top, inside, originals, moved, kept)


def check_tree(root: str, found: dict[str, tuple[str, dict]] | None, dirs: list[str], files: dict[str, str | None],
               absent: list[str], exact: bool) -> Verdict:
    """A folder's content (`found`: its visible entries, None when `root` is no folder): every path of `dirs` a
    folder, every path of `files` a regular file with the content `files[path]` (a sha256; None: any content),
    nothing at the paths of `absent`, and with `exact` nothing else at all."""
    want = (f"{root} holding the folders {dirs or '(none)'} and the files {sorted(files) or '(none)'}"
            + (" and nothing else" if exact else "") + (f", without {absent}" if absent else ""))
    if found is None:
        return Verdict.check(False, want, f"no folder {root}")
    problems = []
    for rel in dirs:
        info = found.get(rel_key(rel), (None, None))[1]
        if not info or not info.get("dir"):
            problems.append(f"{rel} is {describe_entry(info)}, not a folder")
    for rel, sha in files.items():
        why = check_regular_file(found.get(rel_key(rel), (None, None))[1], sha, rel)
        if why:
            problems.append(why)
    for rel in absent:
        if rel_key(rel) in found:
            problems.append(f"{rel} still there")
    if exact:
        allowed = {rel_key(p) for p in [*dirs, *files]}
        # the folders on the way to an expected path are expected too
        for p in list(allowed):
            while "\\" in p:
                p = p.rsplit("\\", 1)[0]
                allowed.add(p)
        extra = sorted(shown for key, (shown, _) in found.items() if key not in allowed)
        if extra:
            problems.append(f"also {extra[:6]}" + (f" and {len(extra) - 6} more" if len(extra) > 6 else ""))
    return Verdict.check(not problems, want, "; ".join(problems) or "so")


@evaluator("windows_tree")
def windows_tree(state: FinalState, root: str, dirs: list[str] | None = None,
                 files: list[list[str]] | None = None, absent: list[str] | None = None, exact: bool = False,
                 platform: str | None = None) -> Verdict:
    """The folder `root` holds the sub-folders `dirs` and the files `files` (paths inside `root`), with nothing at
    the paths of `absent`, and — with `exact` — nothing else (hidden and system files aside). `files` lists
    `[path inside root, device path whose set-up content it must hold]` pairs (the source listed under
    `baseline`; "" for any content; a source with no baseline, made by an upstream subtask, also means any
    content) — pairs, not a mapping, so that both sides may be templated."""
    tree = probe(state, trees=[root], platform=platform)["trees"][root]
    want_files = {rel: (baseline_sha(state, src, platform) if src else None) for rel, src in (files or [])}
    return check_tree(root, None if tree is None else visible_entries(tree), list(dirs or []), want_files,
                      list(absent or []), exact)


@evaluator("windows_folders_copied")
def windows_folders_copied(state: FinalState, source: str, target: str, dirs: list[str],
                           files: list[list[str]] | None = None, platform: str | None = None) -> Verdict:
    """The folder structure of `source` recreated under `target` without its files: `target` holds exactly the
    sub-folders `dirs` (paths inside it, at every depth) and no file; and `source` is as the set-up left it —
    exactly `dirs` and the files `files` (`[path inside source, device path whose set-up content it holds]`,
    see `windows_tree`)."""
    trees = probe(state, trees=[target, source], platform=platform)["trees"]
    made = check_tree(target, None if trees.get(target) is None else visible_entries(trees[target]), list(dirs), {},
                      [], exact=True)
    want_files = {rel: (baseline_sha(state, src, platform) if src else None) for rel, src in (files or [])}
    kept = check_tree(source, None if trees.get(source) is None else visible_entries(trees[source]), list(dirs),
                      want_files, [], exact=True)
    want = f"the {len(dirs)} folders of {source} recreated under {target} without files, {source} unchanged"
    if not made.passed:
        return Verdict.check(False, want, made.reason.split("found ", 1)[-1])
    return Verdict.check(kept.passed, want, "so" if kept.passed else f"{source}: {kept.reason.split('found ', 1)[-1]}")


# -- the Recycle Bin ---------------------------------------------------------------------------------------------
def recycle_record_path(record: bytes) -> str | None:
    """The original path a Windows Recycle Bin record (`$I…`) names: version 1 (Vista to 8.1: a fixed 260-character
    field) or version 2 (Windows 10 and later: a length, then the path), both after the size and deletion time."""
    if len(record) < 24:
        return None
    version = int.from_bytes(record[:8], "little")
    if version == 1:
        raw = record[24:24 + 520]
    elif version == 2 and len(record) >= 28:
        n = int.from_bytes(record[24:28], "little")
        raw = record[28:28 + 2 * n]
    else:
        return None
    return raw.decode("utf-16-le", errors="replace").split("\0")[0]


def trashinfo_path(text: str, prefix: str) -> str | None:
    """The Windows path a freedesktop.org `.trashinfo` (Wine's Recycle Bin) names: `Path=` is the Unix path, under
    the Wine prefix's `dosdevices/c:/…` for a drive letter, else reached through `Z:`."""
    for line in text.splitlines():
        key, _, value = line.partition("=")
        if key.strip() == "Path":
            unix = unquote(value.strip())
            marker = (prefix.rstrip("/") + "/dosdevices/") if prefix else "/dosdevices/"
            at = unix.find(marker) if prefix else unix.find("/dosdevices/")
            if at >= 0:
                rest = unix[at + len(marker):]
                return rest[:1].upper() + rest[1:].replace("/", "\\")
            return "Z:" + unix.replace("/", "\\")
    return None


def recycled_entries(trash: dict) -> list[tuple[str, dict]]:
    """(the original Windows path, the facts of the recycled data) of every Recycle Bin entry the probe found."""
    out = []
    for item in trash.get("xdg", []):
        path = trashinfo_path(item.get("info", ""), trash.get("prefix", ""))
        if path:
            out.append((path, item.get("data") or {}))
    for item in trash.get("recycle", []):
        path = recycle_record_path(base64.b64decode(item.get("info_b64", "")))
        if path:
            out.append((path, item.get("data") or {}))
    return out


def check_recycled(entries: list[tuple[str, dict]], original: str, original_sha: str | None) -> Verdict:
    """Some Recycle Bin entry records `original` (compared as Windows paths) and holds its set-up content
    (`original_sha`; None: unknown, then any data)."""
    want = f"{original} in the Recycle Bin" + (" with its content" if original_sha else "")
    named = [data for path, data in entries if norm(path) == norm(original)]
    if not named:
        return Verdict.check(False, want, f"Recycle Bin entries {[p for p, _ in entries][:8] or 'none'}")
    whys = [check_regular_file(data, original_sha, "recycled data") for data in named]
    if any(w is None for w in whys):
        return Verdict.check(True, want, "so")
    return Verdict.check(False, want, f"an entry naming it, but {whys[0]}")


@evaluator("windows_file_in_recycle_bin")
def windows_file_in_recycle_bin(state: FinalState, original: str, kept: list[str] | None = None,
                                platform: str | None = None) -> Verdict:
    """The file once at `original` was deleted to the Recycle Bin: nothing at `original`, an entry of the bin
    records that path and holds the bytes it had at set-up (listed under `baseline`; with no baseline, any
    data), and the files of `kept` are unchanged. Under Wine the bin is the Unix user's freedesktop.org trash
    (what Wine's Explorer uses when `~/.local/share/Trash` exists); on Windows `\\$Recycle.Bin`."""
    out = probe(state, entries=[original, *(kept or [])], trash=True, platform=platform)
    facts = out["entries"]
    if facts.get(original, {}).get("exists"):
        return Verdict.check(False, f"{original} deleted to the Recycle Bin", "it still there")
    verdict = check_recycled(recycled_entries(out["trash"]), original, baseline_sha(state, original, platform))
    if not verdict.passed:
        return verdict
    lost = kept_problems(state, facts, kept, platform)
    return Verdict.check(not lost, f"{original} in the Recycle Bin, the other files unchanged",
                         "; ".join(lost) or "so")


# -- Command Prompt ----------------------------------------------------------------------------------------------
@evaluator("windows_batch_creates")
def windows_batch_creates(state: FinalState, bat: str, folder: str, names: list[str],
                          platform: str | None = None) -> Verdict:
    """The batch file `bat` creates the sub-folders `names` in the current directory, and was run in `folder`:
    `folder` holds them; then `bat` is run once more by the evaluator in an empty scratch folder (its input from
    NUL, so a `pause` does not wait) and must create exactly those folders there — a batch file that does nothing,
    writes elsewhere, or makes only some of them fails."""
    want = f"{bat} creating {names} where it runs, run in {folder}"
    out = probe(state, entries=[bat], trees=[folder], platform=platform)
    why = check_regular_file(out["entries"].get(bat), None, "batch file")
    if why:
        return Verdict.check(False, want, why)
    tree = out["trees"].get(folder)
    found = None if tree is None else visible_entries(tree)
    missing = [n for n in names if not (found or {}).get(rel_key(n), (None, {}))[1].get("dir")]
    if missing:
        return Verdict.check(False, want, f"no folder {missing} in {folder} (the batch file not run there?)")
    scratch = f"{PROBE_DIR}\\run-{uuid.uuid4().hex[:12]}"
    device = state.device(platform)
    try:
        res = device.run(f'mkdir "{scratch}" && cd /d "{scratch}" && call "{bat}" <nul', timeout=60)
        made = probe(state, trees=[scratch], platform=platform)["trees"].get(scratch) or {}
    finally:
        device.run(f'rmdir /s /q "{scratch}"', timeout=60)
    verdict = check_tree("a scratch folder", visible_entries(made), list(names), {}, [], exact=True)
    if not verdict.passed:
        timed_out = " (it ran past 60 s)" if res.returncode == 124 else ""
        return Verdict(False, f"run in an empty folder{timed_out}, the batch file left: "
                       + verdict.reason.split("found ", 1)[-1] + f"; expected {names} as folders there")
    return Verdict.check(True, want, f"it creates {names} where it runs, and they are in {folder}")


def listed_names(text: str) -> list[str]:
    """The non-blank lines of a listing, trimmed."""
    return [line.strip() for line in text.replace("\r\n", "\n").split("\n") if line.strip()]


def check_listing(text: str, names: list[str], folder: str) -> Verdict:
    """The lines of `text` are exactly the file names `names` (any order, compared without case, each once)."""
    want = f"the {len(names)} file names of {folder}, one per line, names only"
    lines = listed_names(text)
    got = [line.casefold() for line in lines]
    expected = [n.casefold() for n in names]
    missing = [n for n in names if n.casefold() not in got]
    extra = [line for line in lines if line.casefold() not in expected]
    doubled = sorted({line for line in got if got.count(line) > 1})
    problems = ([f"missing {missing}"] if missing else []) + ([f"other lines {[x[:60] for x in extra[:5]]}"]
                                                              if extra else []) + (
        [f"listed twice {doubled}"] if doubled else [])
    return Verdict.check(not problems, want, "; ".join(problems) or "so")


@evaluator("windows_file_lists")
def windows_file_lists(state: FinalState, path: str, folder: str, names: list[str],
                       platform: str | None = None) -> Verdict:
    """`path` (a text file: ANSI, UTF-8 or UTF-16 as Windows programs write it) lists exactly the file names
    `names` of `folder`, which the set-up made (the task's own inputs), one per line in any order."""
    data = state.pull(path, platform)
    if data is None:
        return Verdict.check(False, f"a listing at {path}", "no file")
    return check_listing(decode_text(data), list(names), folder)


def check_number(text: str, expected: int) -> Verdict:
    """`text` is the whole number `expected` alone (surrounding white space aside)."""
    got = text.strip()
    ok = got.lstrip("+-").isdigit() and int(got) == expected
    return Verdict.check(ok, f"just the number {expected}", _short(got) if got else "an empty file")


@evaluator("windows_file_number")
def windows_file_number(state: FinalState, path: str, terms: list[Any], op: str = "sum",
                        unchanged: list[str] | None = None, platform: str | None = None) -> Verdict:
    """`path` holds just the whole number computed on the host from the task's own values `terms` (`op`: "sum"
    or "count"), and the files of `unchanged` (e.g. the input the numbers came from) are as at set-up."""
    values = [int(str(t)) for t in terms]
    expected = sum(values) if op == "sum" else len(values)
    data = state.pull(path, platform)
    if data is None:
        return Verdict.check(False, f"{path} holding {expected}", "no file")
    verdict = check_number(decode_text(data), expected)
    if not verdict.passed or not unchanged:
        return verdict
    facts = probe(state, entries=list(unchanged), platform=platform)["entries"]
    lost = kept_problems(state, facts, unchanged, platform)
    return Verdict.check(not lost, f"{path} holding {expected}, {', '.join(unchanged)} unchanged",
                         "; ".join(lost) or "so")


# -- programs ----------------------------------------------------------------------------------------------------
def check_programs(procs: list[dict], wins: list[dict], ended: list[str], running: list[str],
                   images: dict[str, int]) -> Verdict:
    """No window (shown or hidden) titled as in `ended`, a shown window titled as each of `running` (titles
    compared without case), and `images[name]` processes of each program image `name`."""
    titles: dict[str, list[dict]] = {}
    for w in wins:
        titles.setdefault(w["title"].casefold(), []).append(w)
    problems = []
    for title in ended:
        left = titles.get(title.casefold(), [])
        if left:
            problems.append(f"{title!r} still running" + ("" if any(w["visible"] for w in left)
                                                          else " (its window hidden)"))
    for title in running:
        if not any(w["visible"] for w in titles.get(title.casefold(), [])):
            problems.append(f"{title!r} no longer running")
    counts = {}
    for p in procs:
        counts[p["name"].casefold()] = counts.get(p["name"].casefold(), 0) + 1
    for name, n in images.items():
        if counts.get(name.casefold(), 0) != int(n):
            problems.append(f"{counts.get(name.casefold(), 0)} {name} process(es), expected {n}")
    want = f"{ended} ended, {running} still running"
    return Verdict.check(not problems, want, "; ".join(problems) or "so")


@evaluator("windows_programs")
def windows_programs(state: FinalState, ended: list[str], running: list[str], images: dict[str, int] | None = None,
                     platform: str | None = None) -> Verdict:
    """The programs whose windows are titled `ended` were ended (no window of that title left, not even a hidden
    one), those titled `running` still run, and each program image of `images` has that many processes (so a
    window closed while its process lives on, or the wrong instance ended, fails)."""
    out = probe(state, processes=True, windows=True, platform=platform)
    return check_programs(out["processes"], out["windows"], list(ended), list(running), dict(images or {}))


def check_started_by(procs: list[dict], wins: list[dict], titles: list[str], image: str, parent: str) -> Verdict:
    """A shown window titled as one of `titles` belongs to a process of `image` whose parent process is a
    `parent` (e.g. Task Manager: the program was started from it)."""
    want = f"a window {titles[0]!r} of {image} started by {parent}"
    by_pid = {p["pid"]: p for p in procs}
    shown = [w for w in wins if w["visible"] and w["title"].casefold() in {t.casefold() for t in titles}]
    if not shown:
        near = sorted({w["title"] for w in wins if w["visible"]})[:8]
        return Verdict.check(False, want, f"no such window; windows {near}")
    found = []
    for w in shown:
        proc = by_pid.get(w["pid"])
        if proc is None:
            found.append(f"a window of process {w['pid']} (gone)")
            continue
        if proc["name"].casefold() != image.casefold():
            found.append(f"a window of {proc['name']}")
            continue
        dad = by_pid.get(proc["ppid"])
        if dad and dad["name"].casefold() == parent.casefold():
            return Verdict.check(True, want, f"{image} (pid {proc['pid']}) started by {dad['name']}")
        found.append(f"{image} started by {dad['name'] if dad else 'a process no longer running'}")
    return Verdict.check(False, want, "; ".join(found))


@evaluator("windows_started_by")
def windows_started_by(state: FinalState, titles: list[str], image: str, parent: str,
                       unchanged: list[str] | None = None, platform: str | None = None) -> Verdict:
    """A window titled as one of `titles` shows, its program is `image`, that program was started by `parent`
    (its parent process), and the files of `unchanged` are as at set-up (opened, not edited)."""
    out = probe(state, entries=list(unchanged or []), processes=True, windows=True, platform=platform)
    verdict = check_started_by(out["processes"], out["windows"], list(titles), image, parent)
    if not verdict.passed or not unchanged:
        return verdict
    lost = kept_problems(state, out["entries"], unchanged, platform)
    return Verdict.check(not lost, f"a window {titles[0]!r} of {image} started by {parent}, "
                         f"{', '.join(unchanged)} unchanged", "; ".join(lost) or "so")
