"""Checks of a Windows device's registry and of `.reg` files, read on the host: a platform data store. (Files Windows
programs write are judged by the platform-neutral evaluators — text in `text.py`/`files.py`, copies and downloads
in `folders.py` — and Edge's favourites by `browser.py`, as Chromium's bookmarks.)

How the registry is read: `reg query "<key>" /s` runs on the device (`state.run`) and its output is parsed here
(`parse_reg_query`: REG_SZ, REG_EXPAND_SZ, REG_MULTI_SZ, REG_DWORD and REG_QWORD in hex, REG_BINARY, REG_NONE).
Under Wine a console program started by the control server's console-less `cmd` writes its output to a console
of its own, so `reg query`'s output never reaches the caller (its exit code does); then the same key is read with
`reg export "<key>" <file> /y`, the file pulled to the host and parsed as a `.reg` file (`parse_reg_file`). Both
give the same `Branch`: every key of the branch with its values, names compared case-insensitively as Windows does.

How the rest of a key is checked unchanged (README "Writing a template", rule 3): the template's set-up exports
the branch it touches to a snapshot file (`reg export <key> <snapshot> /y`) and lists the snapshot under
`baseline`; `state.baseline(snapshot)` is the branch right after set-up, whatever the agent does to the file
later. Every value and key of the snapshot other than the ones the task asks for must still be there with the
same type and data, and no other key or value may appear, except names the template allows (`may_change`: values
Windows itself rewrites along with the asked one, e.g. the Settings app's transcoded wallpaper).

Settings a program writes only when it exits (Minesweeper's field: winemine saves it to its key on exit) are not
final while it runs: the registry may already hold the right values while the program holds others that it
writes over them on exit. Such a template names the program (`owner`, its image name), its instruction says to
quit it, and the evaluator fails while a process of that image runs (the process list read by the Windows probe).
"""

from __future__ import annotations

import fnmatch
import re
import time
import uuid
from dataclasses import dataclass
from typing import Any, Iterable

from jarvis_pytest.devices.platforms import PLATFORMS
from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.state import FinalState
from jarvis_pytest.evaluators.windows_probe import probe

WINDOWS = PLATFORMS["windows"]
ROOTS = {"HKCU": "HKEY_CURRENT_USER", "HKLM": "HKEY_LOCAL_MACHINE", "HKCR": "HKEY_CLASSES_ROOT",
         "HKU": "HKEY_USERS", "HKCC": "HKEY_CURRENT_CONFIG"}
TYPES = ("REG_SZ", "REG_EXPAND_SZ", "REG_MULTI_SZ", "REG_DWORD", "REG_QWORD", "REG_BINARY", "REG_NONE")
STRING_TYPES = ("REG_SZ", "REG_EXPAND_SZ")
DEFAULT_NAMES = ("(default)", "@")  # how `reg query` and .reg files name a key's default (unnamed) value
NOT_SET = "(value not set)"
REG5_HEADER = "Windows Registry Editor Version 5.00"
REG4_HEADER = "REGEDIT4"
SCRATCH = WINDOWS.home + "\\AppData\\Local\\Temp"  # where the evaluator's own `reg export` goes (then deleted)


# -- the registry model ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RegValue:
    """A registry value: its type (REG_SZ, ...) and data (str for strings, int for DWORD/QWORD, bytes for binary
    and REG_NONE, a tuple of str for REG_MULTI_SZ)."""

    type: str
    data: Any

    def show(self) -> str:
        if self.type in ("REG_DWORD", "REG_QWORD") and isinstance(self.data, int):
            return f"{self.type} {self.data} (0x{self.data:x})"
        if isinstance(self.data, bytes):
            return f"{self.type} {self.data.hex(',') or '(empty)'}"
        if isinstance(self.data, tuple):
            return f"{self.type} {list(self.data)!r}"
        return f"{self.type} {self.data!r}"


@dataclass
class RegKey:
    """One key: its path as written, and its values by case-folded name → (name as written, value)."""

    path: str
    values: dict[str, tuple[str, RegValue]]


Branch = dict[str, RegKey]  # case-folded full key path → key


def norm_key(path: str) -> str:
    """A key path in the form two paths of the same key compare equal in: the root spelled out (HKCU →
    HKEY_CURRENT_USER), no trailing backslash, case folded (registry names are case-insensitive)."""
    path = path.strip().strip("\\")
    head, _, rest = path.partition("\\")
    head = ROOTS.get(head.upper(), head.upper())
    return (head + ("\\" + rest if rest else "")).casefold()


def long_key(path: str) -> str:
    """`path` with its root spelled out (for commands and messages)."""
    path = path.strip().strip("\\")
    head, _, rest = path.partition("\\")
    return ROOTS.get(head.upper(), head) + ("\\" + rest if rest else "")


def value_name(name: str) -> str:
    """How a value is named in messages ("(Default)" for the unnamed one)."""
    return name or "(Default)"


def typed_value(type_: str, data: Any) -> RegValue:
    """The value a template means by `type` and `data`: REG_DWORD/REG_QWORD from an int or a decimal or 0x-hex
    string, REG_BINARY from hex text (commas and spaces ignored), REG_MULTI_SZ from a list, strings as given."""
    t = str(type_).upper()
    if t not in TYPES:
        raise ValueError(f"unknown registry type {type_!r} (use one of {', '.join(TYPES)})")
    if t in ("REG_DWORD", "REG_QWORD"):
        if isinstance(data, bool) or not isinstance(data, (int, str)):
            raise ValueError(f"{t} data must be a number, not {data!r}")
        return RegValue(t, data if isinstance(data, int) else int(str(data).strip(), 0))
    if t in ("REG_BINARY", "REG_NONE"):
        return RegValue(t, bytes(data) if isinstance(data, (bytes, bytearray))
                        else bytes.fromhex(re.sub(r"[\s,]", "", str(data))))
    if t == "REG_MULTI_SZ":
        return RegValue(t, tuple(str(x) for x in (data if isinstance(data, (list, tuple)) else [data])))
    return RegValue(t, str(data))


# -- `reg query` output -----------------------------------------------------------------------------------------------
QUERY_LINE = re.compile(r"^ {4}(.*?) {4}(REG_[A-Z_]+)(?: {4}(.*))?$")


def _query_value(type_: str, text: str) -> RegValue:
    if type_ in ("REG_DWORD", "REG_QWORD"):
        try:
            return RegValue(type_, int(text.strip(), 16))
        except ValueError:
            return RegValue(type_, text)  # e.g. Wine's reg prints "(null)" for a QWORD
    if type_ in ("REG_BINARY", "REG_NONE"):
        try:
            return RegValue(type_, bytes.fromhex(text.strip()))
        except ValueError:
            return RegValue(type_, text)
    if type_ == "REG_MULTI_SZ":
        return RegValue(type_, tuple(text.split("\\0")) if text else ())
    return RegValue(type_, text)


def parse_reg_query(text: str) -> Branch:
    """The keys and values `reg query <key> [/s]` printed: a line with the full path of each key (HKEY_...),
    then its values indented by four spaces, `name    TYPE    data`. Sub-key paths listed without values (no
    `/s`) count as keys too. The unnamed value, `(Default)`, is the name ""; "(value not set)" means no value."""
    branch: Branch = {}
    current: RegKey | None = None
    for line in text.splitlines():
        if not line.strip():
            continue
        if line.startswith("HKEY_") or line.split("\\", 1)[0].upper() in ROOTS:
            path = line.strip()
            current = branch.setdefault(norm_key(path), RegKey(long_key(path), {}))
            continue
        m = QUERY_LINE.match(line)
        if m is None or current is None:
            continue
        name, type_, data = m.group(1), m.group(2), m.group(3) or ""
        if name.casefold() in DEFAULT_NAMES:
            if data == NOT_SET:
                continue
            name = ""
        current.values[name.casefold()] = (name, _query_value(type_, data))
    return branch


# -- .reg files ---------------------------------------------------------------------------------------------------------
@dataclass
class RegFile:
    """A parsed `.reg` file: its format ("5.00" or "REGEDIT4"), encoding, keys, and what it deletes."""

    version: str
    encoding: str
    branch: Branch
    deletions: list[str]


def decode_reg_text(data: bytes) -> tuple[str, str]:
    """A .reg file's text and encoding: UTF-16 LE with its byte order mark (what regedit and `reg export` write for
    version 5.00), UTF-16 BE, UTF-8 (with or without a mark), else the ANSI code page (REGEDIT4)."""
    if data.startswith(b"\xff\xfe"):
        return data[2:].decode("utf-16-le"), "UTF-16 LE with BOM"
    if data.startswith(b"\xfe\xff"):
        return data[2:].decode("utf-16-be"), "UTF-16 BE with BOM"
    if data.startswith(b"\xef\xbb\xbf"):
        return data[3:].decode("utf-8"), "UTF-8 with BOM"
    try:
        return data.decode("utf-8"), "UTF-8"
    except UnicodeDecodeError:
        return data.decode("cp1252", errors="replace"), "ANSI (cp1252)"


def _quoted(text: str, pos: int) -> tuple[str, int]:
    """The string in double quotes starting at text[pos] (escapes \\\\ and \\"), and the index after it."""
    if pos >= len(text) or text[pos] != '"':
        raise ValueError(f"expected a quoted string at {text[pos:pos + 20]!r}")
    out, i = [], pos + 1
    while i < len(text):
        c = text[i]
        if c == "\\" and i + 1 < len(text):
            out.append(text[i + 1])
            i += 2
            continue
        if c == '"':
            return "".join(out), i + 1
        out.append(c)
        i += 1
    raise ValueError(f"unterminated string {text[pos:pos + 30]!r}")


def _hex_bytes(text: str) -> bytes:
    text = re.sub(r"[\s\\]", "", text)
    return bytes(int(x, 16) for x in text.split(",") if x)


def _strings(raw: bytes, wide: bool) -> str:
    return raw.decode("utf-16-le" if wide else "cp1252", errors="replace")


def _reg_file_value(spec: str, wide: bool) -> RegValue | None:
    """The value of the text right of `=` in a .reg line (None: a deletion, `-`)."""
    spec = spec.strip()
    if spec == "-":
        return None
    if spec.startswith('"'):
        s, end = _quoted(spec, 0)
        if spec[end:].strip():
            raise ValueError(f"text after the string: {spec[end:]!r}")
        return RegValue("REG_SZ", s)
    low = spec.lower()
    if low.startswith("dword:"):
        return RegValue("REG_DWORD", int(spec[6:].strip(), 16))
    m = re.match(r"hex(?:\(([0-9a-f]+)\))?:(.*)$", spec, re.I | re.S)
    if m is None:
        raise ValueError(f"unknown value format {spec[:40]!r}")
    kind = int(m.group(1), 16) if m.group(1) else 3
    raw = _hex_bytes(m.group(2))
    if kind == 1:
        return RegValue("REG_SZ", _strings(raw, wide).rstrip("\0"))
    if kind == 2:
        return RegValue("REG_EXPAND_SZ", _strings(raw, wide).rstrip("\0"))
    if kind == 7:
        parts = _strings(raw, wide).rstrip("\0").split("\0")
        return RegValue("REG_MULTI_SZ", tuple(parts) if parts != [""] else ())
    if kind == 4:
        return RegValue("REG_DWORD", int.from_bytes(raw[:4], "little"))
    if kind == 0xB:
        return RegValue("REG_QWORD", int.from_bytes(raw[:8], "little"))
    if kind == 0:
        return RegValue("REG_NONE", raw)
    return RegValue("REG_BINARY", raw)


def parse_reg_file(data: bytes) -> RegFile:
    """A `.reg` file as regedit (File > Export) and `reg export` write it: the header line (`Windows Registry
    Editor Version 5.00`, UTF-16; or `REGEDIT4`, ANSI), `[key]` sections (`[-key]` deletes a key), and values
    `"name"=...` / `@=...`: a quoted string, `dword:`, `hex:` (binary) or `hex(n):` (2 expandable string, 7 multi
    string, b QWORD, 0 none), hex lists continued over lines ending in a backslash. Raises ValueError on a file
    that is not one."""
    text, encoding = decode_reg_text(data)
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    joined: list[str] = []
    for line in lines:
        if joined and joined[-1].endswith("\\") and not joined[-1].lstrip().startswith("["):
            joined[-1] = joined[-1][:-1] + line.strip()
        else:
            joined.append(line)
    body = [ln for ln in joined if ln.strip() and not ln.lstrip().startswith(";")]
    if not body:
        raise ValueError("an empty file")
    header = body[0].strip()
    if header == REG5_HEADER:
        version, wide = "5.00", True
    elif header == REG4_HEADER:
        version, wide = "REGEDIT4", False
    else:
        raise ValueError(f"no .reg header (first line {header[:60]!r})")
    branch: Branch = {}
    deletions: list[str] = []
    current: RegKey | None = None
    for line in body[1:]:
        s = line.strip()
        if s.startswith("["):
            if not s.endswith("]"):
                raise ValueError(f"unclosed key line {s[:60]!r}")
            path = s[1:-1]
            if path.startswith("-"):
                deletions.append(long_key(path[1:]))
                current = None
                continue
            current = branch.setdefault(norm_key(path), RegKey(long_key(path), {}))
            continue
        if current is None:
            raise ValueError(f"a value outside a key: {s[:60]!r}")
        if s.startswith("@"):
            name, rest = "", s[1:]
        else:
            name, end = _quoted(s, 0)
            rest = s[end:]
        rest = rest.lstrip()
        if not rest.startswith("="):
            raise ValueError(f"no '=' in {s[:60]!r}")
        value = _reg_file_value(rest[1:], wide)
        if value is None:
            deletions.append(f"{current.path}\\{value_name(name)}")
            continue
        current.values[name.casefold()] = (name, value)
    return RegFile(version, encoding, branch, deletions)


# -- reading the live registry -----------------------------------------------------------------------------------------
def _subtree(branch: Branch, key: str) -> Branch:
    root = norm_key(key)
    return {k: v for k, v in branch.items() if k == root or k.startswith(root + "\\")}


def read_branch(state: FinalState, key: str, platform: str | None = None) -> tuple[Branch | None, str]:
    """The key `key` and every key below it with their values, as the device's registry holds them now, and how
    it was read; (None, why) when the key does not exist."""
    key = long_key(key)
    res = state.run(f'reg query "{key}" /s', platform)
    if res.returncode == 0 and re.search(r"^HKEY_", res.stdout, re.M) and res.stdout.isascii() \
            and "?" not in res.stdout:
        return _subtree(parse_reg_query(res.stdout), key), "reg query"
    if res.returncode != 0:
        return None, f"no key {key} (reg query exit {res.returncode})"
    # the key exists but reg's output never came (a Wine device, see the module's docstring), or it holds text
    # outside ASCII that `reg query` prints through the console's code page (`?` for what it lacks): export the
    # key instead (a .reg file is UTF-16, exact)
    scratch = f"{SCRATCH}\\jarvis-reg-{uuid.uuid4().hex[:12]}.reg"
    exp = state.run(f'(if not exist "{SCRATCH}" mkdir "{SCRATCH}") & reg export "{key}" "{scratch}" /y', platform)
    try:
        if exp.returncode != 0 or not state.exists(scratch, platform):
            return None, f"no key {key} (reg export exit {exp.returncode})"
        data = state.device(platform).download(scratch)
    finally:
        state.run(f'del /f /q "{scratch}" 2>nul', platform)
    try:
        return _subtree(parse_reg_file(data).branch, key), "reg export"
    except ValueError as exc:
        return None, f"the export of {key} unreadable ({exc})"


def baseline_branch(state: FinalState, snapshot: str | None, key: str,
                    platform: str | None = None) -> tuple[Branch | None, str]:
    """The branch `key` as the set-up's snapshot `.reg` file (listed under `baseline`) recorded it."""
    if not snapshot:
        return None, ""
    data = state.baseline(snapshot, platform)
    if data is None:
        return None, f"no set-up snapshot {snapshot} (list it under `baseline`)"
    try:
        return _subtree(parse_reg_file(data).branch, key), ""
    except ValueError as exc:
        return None, f"the set-up snapshot {snapshot} unreadable ({exc})"


def _matches(name: str, patterns: Iterable[str]) -> bool:
    return any(fnmatch.fnmatchcase(name.casefold(), p.casefold()) for p in patterns)


def branch_changes(before: Branch, after: Branch, allowed: set[tuple[str, str]] | None = None,
                   new_keys: Iterable[str] = (), may_change: Iterable[str] = ()) -> list[str]:
    """What differs between two states of a branch, as short phrases: keys or values removed, added or changed.
    `allowed`: (case-folded key, case-folded value name) pairs the task is meant to change; `new_keys`: keys the
    task is meant to create (their values are checked elsewhere); `may_change`: value-name patterns Windows may
    rewrite along with the asked change."""
    allowed = allowed or set()
    new = {norm_key(k) for k in new_keys}
    may = list(may_change)
    out: list[str] = []
    for k, key in before.items():
        if k not in after:
            out.append(f"key {key.path} deleted")
            continue
        now = after[k].values
        for n, (name, value) in key.values.items():
            if (k, n) in allowed or _matches(name, may):
                continue
            if n not in now:
                out.append(f"{key.path}\\{value_name(name)} deleted")
            elif now[n][1] != value:
                out.append(f"{key.path}\\{value_name(name)} changed from {value.show()} to {now[n][1].show()}")
        for n, (name, value) in now.items():
            if n not in key.values and (k, n) not in allowed and not _matches(name, may):
                out.append(f"{key.path}\\{value_name(name)} added ({value.show()})")
    for k, key in after.items():
        if k not in before and k not in new:
            out.append(f"key {key.path} added")
    return out


def _said(items: list[str], limit: int = 4) -> str:
    head = "; ".join(items[:limit])
    return head + (f"; and {len(items) - limit} more" if len(items) > limit else "")


def _expected(values: dict[str, Any], means: dict[str, Any] | None) -> dict[str, tuple[str, RegValue]]:
    out: dict[str, tuple[str, RegValue]] = {}
    for name, spec in values.items():
        if not isinstance(spec, (list, tuple)) or len(spec) != 2:
            raise ValueError(f"value {name!r}: give [type, data], not {spec!r}")
        type_, data = spec
        if means and isinstance(data, str) and data in means:
            data = means[data]
        shown = "" if name.casefold() in DEFAULT_NAMES else name
        out[shown.casefold()] = (shown, typed_value(type_, data))
    return out


def check_values(now: Branch | None, how: str, key: str, expected: dict[str, tuple[str, RegValue]],
                 absent: list[str], only: bool = False, before: Branch | None = None, branch: str | None = None,
                 may_change: Iterable[str] = ()) -> Verdict:
    """The key `key` of `now` holds every `expected` value (type and data), none of the `absent` ones, nothing
    else when `only`; and, when the set-up state `before` of the branch `branch` is known, nothing else in that
    branch changed."""
    k = norm_key(key)
    shown = ", ".join(f"{value_name(n)} = {v.show()}" for n, v in expected.values())
    gone = ", ".join(f"no value {value_name(a)}" for a in absent)
    want = f"{long_key(key)} with " + "; ".join(x for x in (shown, gone) if x)
    if only:
        want += " and no other value"
    if before is not None:
        want += f", the rest of {long_key(branch or key)} as set up"
    if now is None or k not in now:
        return Verdict.check(False, want, how if now is None else f"no key {long_key(key)}")
    values = now[k].values
    problems: list[str] = []
    for n, (name, value) in expected.items():
        if n not in values:
            others = ", ".join(value_name(x[0]) for x in values.values()) or "none"
            problems.append(f"no value {value_name(name)} (values: {others})")
        elif values[n][1] != value:
            got = values[n][1]
            extra = " (same text, wrong type)" if str(got.data) == str(value.data) and got.type != value.type else ""
            problems.append(f"{value_name(values[n][0])} = {got.show()}{extra}")
    for a in absent:
        n = "" if a.casefold() in DEFAULT_NAMES else a.casefold()
        if n in values:
            problems.append(f"{value_name(values[n][0])} still there ({values[n][1].show()})")
    if only:
        extra_values = [value_name(nm) for n, (nm, _) in values.items() if n not in expected]
        if extra_values:
            problems.append(f"other values too: {', '.join(extra_values)}")
    if before is not None:
        allowed = {(k, n) for n in expected} | {(k, "" if a.casefold() in DEFAULT_NAMES else a.casefold())
                                                for a in absent}
        # keys on the way to `key` that the set-up did not make are the task's to create
        new_keys = [key] + [key.rsplit("\\", i)[0] for i in range(1, key.count("\\"))]
        new_keys = [p for p in new_keys if norm_key(p) not in before]
        after = _subtree(now, branch or key)
        problems += [f"damage: {c}" for c in branch_changes(before, after, allowed, new_keys, may_change)]
    found = _said(problems) if problems else "; ".join(
        x for x in (", ".join(f"{value_name(values[n][0])} = {values[n][1].show()}" for n in expected),
                    "the rest unchanged" if before is not None else "") if x) or "as expected"
    return Verdict.check(not problems, want, found + (f" (read with {how})" if how else ""))


EXIT_GRACE = 3.0  # seconds a program that shows no window more is given to finish the exit it began


def still_running(state: FinalState, image: str, platform: str | None = None) -> list[dict]:
    """The processes of the program `image` (e.g. winemine.exe) that run now. One that shows no window any more
    is in the middle of exiting (an exit begun before evaluation): it is given EXIT_GRACE seconds to finish."""
    deadline = time.monotonic() + EXIT_GRACE
    while True:
        facts = probe(state, processes=True, windows=True, platform=platform)
        procs = [p for p in facts.get("processes", []) if str(p.get("name", "")).casefold() == image.casefold()]
        shown = {w["pid"] for w in facts.get("windows", []) if w.get("visible")}
        if not procs or any(p["pid"] in shown for p in procs) or time.monotonic() > deadline:
            return procs
        time.sleep(0.5)


def check_owner_exited(verdict: Verdict, owner: str, running: list[dict], key: str) -> Verdict:
    """`verdict` on the registry's values, failed when the program `owner` that writes them on exit still runs:
    whatever the key holds now, that program overwrites it with its own values when it exits."""
    if not running:
        return verdict
    want, _, found = verdict.reason.removeprefix("expected ").partition(", found ")
    pids = ", ".join(str(p["pid"]) for p in running)
    return Verdict.check(False, f"{want}, and {owner} exited (it writes its settings to {long_key(key)} when it "
                         "exits)", f"{owner} still running (pid {pids}): on exit it writes the values it holds over "
                         f"what the key holds now ({found})")


def _judge(state: FinalState, key: str, values: dict[str, Any], absent: list[str], only: bool,
           baseline: str | None, branch: str | None, may_change: list[str] | None, means: dict | None,
           owner: str | None, platform: str | None) -> Verdict:
    try:
        expected = _expected(values, means)
    except ValueError as exc:
        return Verdict(False, f"bad evaluator arguments: {exc}")
    scope = branch or key
    before, problem = baseline_branch(state, baseline, scope, platform)
    if problem:
        return Verdict.check(False, f"{long_key(key)} changed as asked, the rest as set up", problem)
    running = still_running(state, owner, platform) if owner else []
    now, how = read_branch(state, scope, platform)
    verdict = check_values(now, how, key, expected, absent, only, before, scope, may_change or [])
    return check_owner_exited(verdict, owner, running, key) if owner else verdict


@evaluator("registry_values_are")
def registry_values_are(state: FinalState, key: str, values: dict[str, list], absent: list[str] | None = None,
                        only: bool = False, baseline: str | None = None, branch: str | None = None,
                        may_change: list[str] | None = None, means: dict[str, Any] | None = None,
                        owner: str | None = None, platform: str | None = None) -> Verdict:
    """The key `key` holds `values` ({name: [type, data]}; the name "(Default)" or "@" is the unnamed value) with
    exactly these types and data, and none of `absent`; with `only`, no other value. `means` maps a word of the
    instruction to the data it stands for (e.g. {"show": 0, "hide": 1}). With `baseline` (a snapshot `.reg` of
    `branch` — default `key` — made at set-up and listed under `baseline`), every other key and value of the branch
    is as set up (`may_change`: value-name patterns Windows may rewrite along with the asked change). `owner`: the
    image name of a program that writes these values when it exits (e.g. winemine.exe); it must have exited, since
    while it runs the registry is not final (the instruction asks to quit it)."""
    return _judge(state, key, values, absent or [], only, baseline, branch, may_change, means, owner, platform)


@evaluator("registry_value_is")
def registry_value_is(state: FinalState, key: str, name: str, type: str, data: Any, only: bool = False,
                      baseline: str | None = None, branch: str | None = None, may_change: list[str] | None = None,
                      means: dict[str, Any] | None = None, owner: str | None = None,
                      platform: str | None = None) -> Verdict:
    """One value `name` of `key` is of `type` with `data` (see `registry_values_are`)."""
    return _judge(state, key, {name: [type, data]}, [], only, baseline, branch, may_change, means, owner, platform)


@evaluator("registry_value_absent")
def registry_value_absent(state: FinalState, key: str, name: str, baseline: str | None = None,
                          branch: str | None = None, may_change: list[str] | None = None,
                          owner: str | None = None, platform: str | None = None) -> Verdict:
    """The key `key` still exists but has no value `name`; with `baseline`, the rest of the branch is as set up
    (the other values of the key kept with their types and data); `owner` as for `registry_values_are`."""
    return _judge(state, key, {}, [name], False, baseline, branch, may_change, None, owner, platform)


# -- the desktop wallpaper ---------------------------------------------------------------------------------------------
DESKTOP_KEY = "HKEY_CURRENT_USER\\Control Panel\\Desktop"
# what Windows' Settings app and SystemParametersInfo(SPI_SETDESKWALLPAPER) rewrite along with `Wallpaper`
WALLPAPER_COMPANIONS = ["Wallpaper", "WallpaperStyle", "TileWallpaper", "Transcoded*", "WallpaperOrigin*",
                        "WallpaperSource", "ConvertedWallpaper*", "OriginalWallpaper"]


def same_picture(a: bytes | None, b: bytes | None) -> tuple[bool, str]:
    """Whether two image files show the same picture (same size, pixel by pixel within the image evaluators'
    tolerance: a re-encoded copy such as Windows' TranscodedWallpaper passes)."""
    from jarvis_pytest.evaluators.images import found_words, matches, open_image

    ia, ib = open_image(a), open_image(b)
    if ia is None or ib is None:
        return False, "no readable image"
    if ia.size != ib.size:
        return False, f"a {ia.width}×{ia.height} picture, not {ib.width}×{ib.height}"
    ok, mean, off = matches(ia, ib)
    return ok, found_words(mean, off)


@evaluator("registry_wallpaper_is")
def registry_wallpaper_is(state: FinalState, image: str, baseline: str | None = None,
                          platform: str | None = None) -> Verdict:
    """The desktop wallpaper (`Wallpaper` of HKCU\\Control Panel\\Desktop, REG_SZ, as Settings > Personalization >
    Background and SystemParametersInfo write it) is the picture `image`: its path (compared as Windows compares
    paths: case-insensitively, `/` or `\\`), or a copy Windows made of it (Windows 7 and some Settings versions
    point the value at `...\\Themes\\TranscodedWallpaper`) showing the same picture. `image` must still be there as
    set up (when listed under `baseline`). With `baseline` (a snapshot of the Desktop key), the key's other values
    are as set up, except those Windows rewrites with the wallpaper (`WALLPAPER_COMPANIONS`)."""
    want = f"the wallpaper {image}"
    before, problem = baseline_branch(state, baseline, DESKTOP_KEY, platform)
    if problem:
        return Verdict.check(False, want, problem)
    now, how = read_branch(state, DESKTOP_KEY, platform)
    k = norm_key(DESKTOP_KEY)
    if now is None or k not in now:
        return Verdict.check(False, want, how)
    entry = now[k].values.get("wallpaper")
    if entry is None:
        return Verdict.check(False, want, "no Wallpaper value")
    value = entry[1]
    if value.type not in STRING_TYPES:
        return Verdict.check(False, want, f"Wallpaper = {value.show()}, not a string")
    path = str(value.data).strip()
    original = state.baseline(image, platform)
    current = state.pull(image, platform)
    if current is None:
        return Verdict.check(False, want, f"Wallpaper = {path!r}, and no file at {image} any more")
    if original is not None and current != original:
        ok, words = same_picture(current, original)
        if not ok:
            return Verdict.check(False, want, f"{image} changed since set-up ({words})")
    if not path:
        return Verdict.check(False, want, "Wallpaper = '' (no wallpaper)")
    if not WINDOWS.is_absolute(path):
        return Verdict.check(False, want, f"Wallpaper = {path!r}, not a full path")
    if WINDOWS.normalise(path) != WINDOWS.normalise(image):
        try:
            shown = state.pull(path, platform) if state.exists(path, platform) else None
        except InfrastructureError:  # a folder, or a file the device may not read: no picture either way
            shown = None
        ok, words = same_picture(shown, original if original is not None else current)
        if not ok:
            return Verdict.check(False, want, f"Wallpaper = {path!r}" + (f" ({words})" if shown is not None else
                                                                           " (no picture file there)"))
    if before is not None:
        changes = branch_changes(before, _subtree(now, DESKTOP_KEY), {(k, "wallpaper")}, (), WALLPAPER_COMPANIONS)
        if changes:
            return Verdict.check(False, want + ", the other desktop settings as set up", "damage: " + _said(changes))
    return Verdict.check(True, want, f"Wallpaper = {path!r} (read with {how})")


# -- .reg export files ------------------------------------------------------------------------------------------------
def check_reg_export(data: bytes, key: str, expected: Branch, live: Branch | None = None) -> Verdict:
    """`data` is a `.reg` export of the branch `key`: a registration file (version 5.00 in UTF-16 LE with its byte
    order mark as regedit's File > Export and `reg export` write it, or the older REGEDIT4 in ANSI that regedit
    offers as "Win9x/NT4"), holding exactly the keys and values of `expected` (the branch as set up), nothing
    outside the branch (not the whole registry) and no deletions."""
    want = f"a registration file (.reg) of {long_key(key)} with its {len(expected)} key(s) and their values"
    try:
        reg = parse_reg_file(data)
    except (ValueError, UnicodeDecodeError) as exc:
        return Verdict.check(False, want, f"no .reg file ({exc}; starts {data[:12]!r})")
    if reg.version == "5.00" and reg.encoding not in ("UTF-16 LE with BOM",):
        return Verdict.check(False, want, f"a version 5.00 file in {reg.encoding} (regedit writes UTF-16 LE with "
                                          "a byte order mark; Windows' regedit cannot import this one)")
    if reg.deletions:
        return Verdict.check(False, want, f"a file that deletes {_said(reg.deletions)}")
    root = norm_key(key)
    outside = [k.path for n, k in reg.branch.items() if not (n == root or n.startswith(root + "\\"))]
    if outside:
        return Verdict.check(False, want, f"{len(outside)} key(s) outside the branch, e.g. {outside[0]}")
    diff = branch_changes(expected, reg.branch)
    if diff:
        return Verdict.check(False, want, "a file that differs from the key as set up: " + _said(
            [d.replace(" deleted", " missing").replace(" added", " extra") for d in diff]))
    if live is not None and branch_changes(expected, live):
        return Verdict.check(False, want + ", the key itself left as it was",
                             "the file as asked, but the key changed since: " + _said(branch_changes(expected, live)))
    nvalues = sum(len(k.values) for k in reg.branch.values())
    return Verdict.check(True, want, f"{reg.version} ({reg.encoding}), {len(reg.branch)} key(s), {nvalues} value(s)")


@evaluator("reg_file_exports")
def reg_file_exports(state: FinalState, path: str, key: str, baseline: str, platform: str | None = None) -> Verdict:
    """`path` is a `.reg` export of `key` (see `check_reg_export`) equal to the branch as the set-up's snapshot
    `baseline` recorded it, and the key itself is still as set up (exporting is not moving)."""
    want = f"a .reg export of {long_key(key)} at {path}"
    before, problem = baseline_branch(state, baseline, key, platform)
    if before is None:
        return Verdict.check(False, want, problem or "no set-up snapshot")
    data = state.pull(path, platform)
    if data is None:
        return Verdict.check(False, want, f"no file at {path}")
    live, _ = read_branch(state, key, platform)
    if live is None:
        return Verdict.check(False, want + ", the key itself kept", f"the key {long_key(key)} is gone")
    return check_reg_export(data, key, before, live)


__all__ = ["RegValue", "RegKey", "RegFile", "Branch", "parse_reg_query", "parse_reg_file", "read_branch",
           "branch_changes", "check_values", "check_reg_export", "same_picture", "typed_value", "norm_key"]
