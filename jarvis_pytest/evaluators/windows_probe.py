"""The Windows getter: a small probe that reads what the control server's file API does not say — the facts of a
path (a folder, a link, a hard link, its hidden and system attributes, its SHA-256), a folder's whole content,
the files of given sizes anywhere under given folders, the processes (with their start times and image paths),
the top-level windows and the Recycle Bin's raw records.

The probe is a Python script put on the device through the file API and run with the device's own embeddable
CPython (`C:\\jarvis\\python\\pythonw.exe`, on both backends); it writes its findings as JSON to a file that is
fetched back and removed. Why not `tasklist`, `dir` or `attrib`: under Wine 8 `tasklist` prints nothing (even
redirected to a file), `find /c` and `findstr` print nothing or refuse, and the output of any program the
server's `cmd /c` starts (as opposed to cmd's own commands such as `dir`) never reaches the server (see
`windows_files` in the report of issue 17); the probe writes its own file, so none of that matters.

Evaluators do not call it directly for files: `file_facts.read_facts` does, on Windows (`PlatformSpec.file_facts`).
"""

from __future__ import annotations

import base64
import json
import uuid
from typing import Any

from jarvis_pytest.devices.platforms import PlatformSpec
from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.evaluators.file_facts import NOTHING, Entry, Facts, Search
from jarvis_pytest.evaluators.state import FinalState
from jarvis_pytest.evaluators.windows_recycle_bin import recycled_entries

PYTHON = r"C:\jarvis\python\pythonw.exe"  # no console window
PROBE_DIR = r"C:\temp\jarvis-probe"
HEAD_BYTES = 4096  # how much of a file named in the request's `heads` comes back (to tell what wrote it)

# The probe: runs on the device (Windows' CPython, standard library and ctypes only). argv: request.json out.json
PROBE = r'''
import base64, hashlib, json, os, stat, sys, traceback

HEADS = set()  # file names (case folded) whose first bytes are reported


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
    out = {"exists": True, "dir": is_dir, "link": link, "size": st.st_size, "hidden": bool(attrs & 0x2),
           "system": bool(attrs & 0x4), "volume": st.st_dev}
    if not is_dir and not link:
        try:
            out["nlink"] = os.stat(path).st_nlink
            out["sha256"] = sha256(path)
            if os.path.basename(path).casefold() in HEADS:
                with open(path, "rb") as f:
                    out["head_b64"] = base64.b64encode(f.read(%(head)d)).decode()
        except OSError as exc:
            out["error"] = str(exc)
    return out


def tree(root, depth=None, limit=5000):
    items = {}
    for base, dirs, files in os.walk(root):
        level = 0 if base == root else os.path.relpath(base, root).count(os.sep) + 1
        if depth is not None and level + 1 >= depth:
            dirs_below, dirs[:] = list(dirs), []  # list this level, go no deeper
        else:
            dirs_below = dirs
        for name in sorted(dirs_below + files):
            full = os.path.join(base, name)
            items[os.path.relpath(full, root)] = entry(full)
            if len(items) >= limit:
                return items
    return items


def search(roots, sizes, limit=5000):
    """Every regular file under `roots`, at any depth, whose size is one of `sizes`: full path -> its facts.
    Links and other reparse points below a root (junctions such as "Application Data") are not entered; folders
    that cannot be read are passed over."""
    sizes, out, stack = set(sizes), {}, [r for r in roots if os.path.isdir(r)]
    while stack:
        folder = stack.pop()
        try:
            with os.scandir(folder) as it:
                items = list(it)
        except OSError:
            continue
        for item in items:
            try:
                st = item.stat(follow_symlinks=False)
            except OSError:
                continue
            if stat.S_ISLNK(st.st_mode) or getattr(st, "st_file_attributes", 0) & 0x400:
                continue
            if stat.S_ISDIR(st.st_mode):
                stack.append(item.path)
            elif stat.S_ISREG(st.st_mode) and st.st_size in sizes:
                out[item.path] = entry(item.path)
                if len(out) >= limit:
                    return out
    return out


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
    k.OpenProcess.restype = wintypes.HANDLE
    k.OpenProcess.argtypes = [wintypes.DWORD, wintypes.BOOL, wintypes.DWORD]
    k.GetProcessTimes.argtypes = [wintypes.HANDLE] + [ctypes.POINTER(wintypes.FILETIME)] * 4
    k.QueryFullProcessImageNameW.argtypes = [wintypes.HANDLE, wintypes.DWORD, wintypes.LPWSTR,
                                             ctypes.POINTER(wintypes.DWORD)]

    def identity(pid):
        """(its creation time as a FILETIME count, its image's full path); None where the process denies it."""
        h = k.OpenProcess(0x1000, False, pid)  # PROCESS_QUERY_LIMITED_INFORMATION
        if not h:
            return None, None
        times = [wintypes.FILETIME() for _ in range(4)]
        started = None
        if k.GetProcessTimes(h, *[ctypes.byref(t) for t in times]):
            started = (times[0].dwHighDateTime << 32) | times[0].dwLowDateTime
        buf, size = ctypes.create_unicode_buffer(1024), wintypes.DWORD(1024)
        path = buf.value if k.QueryFullProcessImageNameW(h, 0, buf, ctypes.byref(size)) else None
        k.CloseHandle(h)
        return started, path

    snap = k.CreateToolhelp32Snapshot(2, 0)  # TH32CS_SNAPPROCESS
    pe = PE()
    pe.dwSize = ctypes.sizeof(PE)
    out = []
    ok = k.Process32FirstW(snap, ctypes.byref(pe))
    while ok:
        started, path = identity(pe.th32ProcessID)
        out.append({"pid": pe.th32ProcessID, "ppid": pe.th32ParentProcessID, "name": pe.szExeFile,
                    "started": started, "path": path})
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
            out.append({"title": buf.value, "pid": pid.value, "visible": bool(u.IsWindowVisible(hwnd)),
                        "hwnd": hwnd or 0})
        return True

    u.EnumWindows(each, 0)
    return out


def trash(recycle):
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
        root = drive + ":\\" + recycle
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
        HEADS.update(n.casefold() for n in req.get("heads", []))
        out["entries"] = {p: entry(p) for p in req.get("entries", [])}
        out["trees"] = {r: tree(r, req.get("depth")) if os.path.isdir(r) and not os.path.islink(r) else None
                        for r in req.get("trees", [])}
        if req.get("processes"):
            out["processes"] = processes()
        if req.get("windows"):
            out["windows"] = windows()
        if req.get("trash"):
            out["trash"] = trash(req["trash"])
        if req.get("search"):
            out["found"] = search(req["search"], req.get("sizes", []))
    except Exception:
        out["error"] = traceback.format_exc()
    with open(out_path, "w", encoding="utf-8") as f:
        json.dump(out, f)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
''' % {"head": HEAD_BYTES}


def probe(state: FinalState, *, entries: list[str] | None = None, trees: list[str] | None = None,
          depth: int | None = None, processes: bool = False, windows: bool = False, trash: str | None = None,
          heads: list[str] | None = None, search: list[str] | None = None, sizes: list[int] | None = None,
          platform: str | None = None) -> dict[str, Any]:
    """Run the probe on the device: facts of `entries` (paths), the content of `trees` (folders, `depth` levels
    deep; None: all), the processes, the top-level windows, the Recycle Bin (`trash`: the name of each drive's bin
    folder), with the first bytes of files named as in `heads`; with `search` (folders) and `sizes`, every regular
    file under them of one of those sizes (`found`). An InfrastructureError when it cannot run."""
    device = state.device(platform)
    folder = f"{PROBE_DIR}\\{uuid.uuid4().hex[:12]}"
    request = {"entries": entries or [], "trees": trees or [], "depth": depth, "processes": processes,
               "windows": windows, "trash": trash, "heads": heads or []}
    if search:
        request.update(search=list(search), sizes=list(sizes or []))
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


def as_entry(info: dict | None) -> Entry:
    """A probed entry's facts as a platform-neutral `Entry`."""
    if not info or not info.get("exists"):
        return NOTHING
    kind = "dir" if info.get("dir") else "link" if info.get("link") else "file"
    return Entry(exists=True, kind=kind, size=info.get("size"), sha256=info.get("sha256"),
                 links=int(info.get("nlink", 1)), hidden=bool(info.get("hidden")), system=bool(info.get("system")),
                 head=base64.b64decode(info.get("head_b64", "")), volume=info.get("volume"))


def read_facts(state: FinalState, entries: list[str], trees: list[str], depth: int | None, trash: bool,
               plat: PlatformSpec, search: Search | None = None) -> Facts:
    """`file_facts.read_facts` on Windows: one run of the probe."""
    more = {"search": list(search.roots), "sizes": list(search.sizes)} if search else {}
    out = probe(state, entries=entries, trees=trees, depth=depth, trash=plat.trash if trash else None,
                heads=list(plat.shell_files), platform=plat.name, **more)
    return Facts(entries={p: as_entry(out["entries"].get(p)) for p in entries},
                 trees={r: None if out["trees"].get(r) is None else
                        {rel.replace("/", "\\"): as_entry(info) for rel, info in out["trees"][r].items()}
                        for r in trees},
                 trash=None if not trash else [(p, as_entry(d)) for p, d in recycled_entries(out["trash"])],
                 found=None if not search else {p: as_entry(info) for p, info in (out.get("found") or {}).items()})
