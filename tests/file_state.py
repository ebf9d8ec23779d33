"""A FinalState over files held in memory, for the evaluator tests that need no container.

Its device answers the platform-neutral file facts (`evaluators/file_facts.py`) of those files as the real readers
do: the POSIX facts script (`posix_facts_reply`) and, on Windows, the probe (`probe_reply`) — each a regular file
of its own, shown, with its size and SHA-256; a folder is any path that holds one of them."""

from __future__ import annotations

import hashlib
import json
import re
import shlex

from jarvis_pytest.devices.base import CommandResult
from jarvis_pytest.evaluators.state import FinalState

_PROBE_RUN = re.compile(r'^"[^"]+" -I "([^"]+)\\probe\.py" "([^"]+)" "([^"]+)"$')


def _under(files: dict[str, bytes], root: str, sep: str) -> dict[str, bytes | None]:
    """What `root` holds among `files`: path inside it → bytes (None: a folder on the way to a file)."""
    prefix = root.rstrip(sep) + sep
    out: dict[str, bytes | None] = {}
    for path, data in files.items():
        if path.startswith(prefix):
            rel = path[len(prefix):]
            parts = rel.split(sep)
            for i in range(1, len(parts)):
                out.setdefault(sep.join(parts[:i]), None)
            out[rel] = data
    return out


def _posix_record(path: str, data: bytes | None, is_dir: bool) -> str:
    if data is not None:
        return f"regular file|1|{len(data)}|{hashlib.sha256(data).hexdigest()}|{path}"
    return f"directory|2|4096||{path}" if is_dir else f"none|||{path}"


def posix_facts_reply(command: str, files: dict[str, bytes]) -> str | None:
    """What the POSIX file-facts script (`file_facts.posix_script`) prints for `files`, or None when `command` is
    not that script: entries, trees and a search for files of given sizes. The trash is empty."""
    if not command.startswith("f() {"):
        return None
    out = []
    for line in command.splitlines():
        if line.startswith("f ") and line.endswith(" E"):
            path = shlex.split(line)[1]
            out.append("E " + _posix_record(path, files.get(path), bool(_under(files, path, "/"))))
        elif m := re.match(r"if \[ -d (.+?) \] && \[ ! -L .*echo 'R(\d+) '; find .* -mindepth 1( -maxdepth (\d+))?",
                           line):
            root, i, depth = shlex.split(m.group(1))[0], m.group(2), m.group(4)
            held = _under(files, root, "/")
            if not held:
                continue
            out.append(f"R{i} ")
            for rel, data in held.items():
                if depth is None or rel.count("/") < int(depth):
                    out.append(f"T{i} " + _posix_record(f"{root.rstrip('/')}/{rel}", data, data is None))
        elif m := re.match(r"if \[ -d (.+?) \]; then find -H .* -type f \\\( (.*) \\\) ", line):
            root, sizes = shlex.split(m.group(1))[0], {int(n) for n in re.findall(r"-size (\d+)c", m.group(2))}
            for rel, data in _under(files, root, "/").items():
                if data is not None and len(data) in sizes:
                    out.append("S " + _posix_record(f"{root.rstrip('/')}/{rel}", data, False))
    return "\n".join(out) + "\n"


def _probe_entry(data: bytes | None, is_dir: bool) -> dict:
    if data is not None:
        return {"exists": True, "dir": False, "link": False, "size": len(data), "hidden": False, "system": False,
                "nlink": 1, "sha256": hashlib.sha256(data).hexdigest()}
    return {"exists": True, "dir": True, "link": False, "size": 0, "hidden": False, "system": False} if is_dir \
        else {"exists": False}


def probe_reply(command: str, files: dict[str, bytes]) -> bool:
    """Carry out a run of the Windows probe (`windows_probe.probe`) on `files`: its answer written where it asks
    (processes, windows and the Recycle Bin reported empty). False when `command` is no probe run."""
    m = _PROBE_RUN.match(command)
    if not m:
        return False
    req = json.loads(files[m.group(2)])
    depth = req.get("depth")
    out = {"entries": {p: _probe_entry(files.get(p), bool(_under(files, p, "\\"))) for p in req["entries"]},
           "trees": {}, "processes": [], "windows": [], "trash": {"xdg": [], "recycle": [], "prefix": ""}}
    for root in req["trees"]:
        held = _under(files, root, "\\")
        out["trees"][root] = {rel: _probe_entry(data, data is None) for rel, data in held.items()
                              if depth is None or rel.count("\\") < depth} if held else None
    if req.get("search"):
        sizes = set(req.get("sizes", []))
        out["found"] = {root.rstrip("\\") + "\\" + rel: _probe_entry(data, False) for root in req["search"]
                        for rel, data in _under(files, root, "\\").items() if data is not None and len(data) in sizes}
    files[m.group(3)] = json.dumps(out).encode("utf-8")
    return True


class _FilesDevice:
    """A device that holds exactly `files`: any other path does not exist; it answers the file-facts readers, and
    every other command fails."""

    def __init__(self, files: dict[str, bytes]):
        self.files = files

    def exists(self, path: str) -> bool:
        return path in self.files or any(f.startswith(path.rstrip("/\\") + sep) for f in self.files
                                         for sep in ("/", "\\"))

    def download(self, path: str) -> bytes:
        return self.files[path]

    def upload(self, path: str, data: bytes) -> None:
        self.files[path] = data

    def run(self, command, user=None, timeout=60.0):
        reply = posix_facts_reply(command, self.files)
        if reply is not None:
            return CommandResult(0, reply, "")
        if probe_reply(command, self.files):
            return CommandResult(0, "", "")
        if m := re.fullmatch(r'rmdir /s /q "([^"]+)"', command):
            for path in [p for p in self.files if p.startswith(m.group(1) + "\\")]:
                del self.files[path]
            return CommandResult(0, "", "")
        return CommandResult(1, "", "")


def state_with(files: dict[str, bytes], platform: str = "ubuntu",
               baselines: dict[str, bytes] | None = None) -> FinalState:
    """A FinalState whose device holds exactly `files` (any other path is missing); `baselines` are the files
    as they were right after set-up."""
    return FinalState(platform=platform, devices={platform: _FilesDevice(dict(files))},
                      baselines={(platform, p): d for p, d in (baselines or {}).items()})
