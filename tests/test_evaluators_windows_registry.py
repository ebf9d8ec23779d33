"""The evaluators of `jarvis_pytest/evaluators/windows_registry.py`, run on the host (no container): `reg query`
output and `.reg` files as Windows and Wine write them, parsed; a fake Windows device whose registry lives in memory
answers `reg query` (the way a real Windows does, or with no output as under Wine, where the evaluator falls back to
`reg export`) and whose files live in a dict. For each template of this module the result a careful person leaves
passes, and each near-miss state of its `negatives` fails with a reason naming what is wrong; the templates that
run only on a real Windows (Paint, Edge) are checked the same way on files made here as their oracles and negatives
would leave them (Edge's download and PowerShell's hash are judged by the neutral evaluators:
test_evaluators_windows_files.py)."""

from __future__ import annotations

import io
import json
import re
from pathlib import Path

import pytest
from PIL import Image, ImageOps

from jarvis_pytest.devices.base import CommandResult
from jarvis_pytest.devices.platforms import PLATFORMS
from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.evaluators import get_evaluator
from jarvis_pytest.evaluators.state import FinalState
from jarvis_pytest.evaluators import windows_registry as wr
from jarvis_pytest.evaluators.windows_registry import (Branch, RegKey, RegValue, branch_changes, check_reg_export,
                                                       norm_key, parse_reg_file, parse_reg_query, typed_value)
from jarvis_pytest.generators import generate
from jarvis_pytest.tasks.instances import materialise
from jarvis_pytest.tasks.model import Subtask, TaskTemplate

LIBRARY = Path(__file__).resolve().parents[1] / "tasks" / "windows"
WIN = PLATFORMS["windows"]

# What Wine 8's `reg query HKCU\Software\T /s` printed (captured through a pipe on the Wine device)
WINE_QUERY = ("\r\nHKEY_CURRENT_USER\\Software\\T\r\n    (Default)    REG_SZ    def\r\n    b    REG_BINARY    0AFF00\r\n"
              "    d    REG_DWORD    0x1f4\r\n    e    REG_SZ    \r\n    m    REG_MULTI_SZ    one\\0two\r\n"
              "    s    REG_SZ    a  b\r\n    sp ace    REG_SZ    v\r\n    x    REG_EXPAND_SZ    C:\\users\\user\\x\r\n"
              "\r\nHKEY_CURRENT_USER\\Software\\T\\Sub\r\n    in    REG_SZ    y\r\n\r\n")

# What Wine 8's regedit (File > Export, selected branch) and `reg export` wrote, decoded
WINE_EXPORT = ("Windows Registry Editor Version 5.00\r\n\r\n[HKEY_CURRENT_USER\\Software\\Imp]\r\n\r\n"
               "[HKEY_CURRENT_USER\\Software\\Imp\\App]\r\n"
               "\"Cache\"=hex(2):25,00,4c,00,4f,00,43,00,41,00,4c,00,41,00,50,00,50,00,44,00,41,\\\r\n"
               "  00,54,00,41,00,25,00,5c,00,41,00,00,00\r\n\"Layout\"=hex:0a,0b,0c\r\n"
               "\"Recent\"=hex(7):61,00,2e,00,74,00,78,00,74,00,00,00,62,00,00,00,00,00\r\n\"Theme\"=\"Dark\"\r\n"
               "\"Width\"=dword:00000500\r\n\r\n[HKEY_CURRENT_USER\\Software\\Imp\\App\\Sub]\r\n@=\"dflt\"\r\n\r\n")


# -- writing the formats the way Windows does (for the fake device) -------------------------------------------------
def _hex(raw: bytes) -> str:
    return ",".join(f"{b:02x}" for b in raw)


def reg_line(name: str, v: RegValue, wide: bool = True) -> str:
    head = "@" if name == "" else '"' + name.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if v.type == "REG_SZ":
        return head + '="' + str(v.data).replace("\\", "\\\\").replace('"', '\\"') + '"'
    if v.type == "REG_DWORD":
        return head + f"=dword:{v.data:08x}"
    enc = "utf-16-le" if wide else "cp1252"  # REGEDIT4 files hold strings in the ANSI code page
    raw = {"REG_EXPAND_SZ": lambda: (str(v.data) + "\0").encode(enc),
           "REG_MULTI_SZ": lambda: ("".join(x + "\0" for x in v.data) + "\0").encode(enc),
           "REG_QWORD": lambda: int(v.data).to_bytes(8, "little"),
           "REG_BINARY": lambda: bytes(v.data), "REG_NONE": lambda: bytes(v.data)}[v.type]()
    kind = {"REG_EXPAND_SZ": "hex(2)", "REG_MULTI_SZ": "hex(7)", "REG_QWORD": "hex(b)", "REG_BINARY": "hex",
            "REG_NONE": "hex(0)"}[v.type]
    line = f"{head}={kind}:{_hex(raw)}"
    out, rest = [], line  # regedit wraps hex lists at 80 columns, continuing lines with a backslash
    while len(rest) > 78 and "," in rest[:78]:
        cut = rest[:78].rindex(",") + 1
        out.append(rest[:cut] + "\\")
        rest = "  " + rest[cut:]
    return "\r\n".join(out + [rest])


def reg_file(branch: Branch, version: str = "5.00") -> bytes:
    lines = ["Windows Registry Editor Version 5.00" if version == "5.00" else "REGEDIT4", ""]
    for _, key in sorted(branch.items()):
        lines.append(f"[{key.path}]")
        lines += [reg_line(name, v, version == "5.00") for _, (name, v) in sorted(key.values.items())]
        lines.append("")
    text = "\r\n".join(lines) + "\r\n"
    return b"\xff\xfe" + text.encode("utf-16-le") if version == "5.00" else text.encode("cp1252")


def query_text(branch: Branch) -> str:
    """`reg query <key> /s` as a real Windows prints it."""
    out = [""]
    for _, key in sorted(branch.items()):
        out.append(key.path)
        for _, (name, v) in sorted(key.values.items()):
            data = {"REG_DWORD": lambda: hex(v.data), "REG_QWORD": lambda: hex(v.data),
                    "REG_BINARY": lambda: bytes(v.data).hex().upper(), "REG_NONE": lambda: bytes(v.data).hex().upper(),
                    "REG_MULTI_SZ": lambda: "\\0".join(v.data)}.get(v.type, lambda: str(v.data))()
            out.append(f"    {name or '(Default)'}    {v.type}    {data}")
        out.append("")
    return "\r\n".join(out) + "\r\n"


class FakeWindows:
    """A Windows device whose registry is a Branch in memory and whose files are a dict (paths compared as Windows
    does). `wine=True`: `reg query` succeeds without output, as under the Wine device's console-less `cmd`."""

    platform = "windows"

    def __init__(self, registry: Branch | None = None, wine: bool = False):
        self.registry: Branch = registry if registry is not None else {}
        self.files: dict[str, bytes] = {}
        self.wine = wine
        self.commands: list[str] = []

    def put(self, path: str, data: bytes) -> None:
        self.files[WIN.normalise(path)] = data

    def download(self, path: str) -> bytes:
        n = WIN.normalise(path)
        if n not in self.files and self.exists(path):  # the control server refuses to read a folder
            raise InfrastructureError(f"windows device: GET /files failed (403): cannot read {path}")
        return self.files[n]

    def exists(self, path: str) -> bool:
        n = WIN.normalise(path)
        return n in self.files or any(k.startswith(n + "\\") for k in self.files)

    def branch(self, key: str) -> Branch:
        root = norm_key(key)
        return {k: v for k, v in self.registry.items() if k == root or k.startswith(root + "\\")}

    def run(self, command: str, *, timeout: float = 60.0, user: str | None = None) -> CommandResult:
        self.commands.append(command)
        m = re.fullmatch(r'reg query "([^"]+)" /s', command)
        if m:
            found = self.branch(m.group(1))
            if not found:
                return CommandResult(1, "", "ERROR: The system was unable to find the specified registry key or value.")
            return CommandResult(0, "" if self.wine else query_text(found), "")
        m = re.search(r'reg export "([^"]+)" "([^"]+)" /y', command)
        if m:
            found = self.branch(m.group(1))
            if not found:
                return CommandResult(1, "", "")
            self.put(m.group(2), reg_file(found))
            return CommandResult(0, "", "")
        m = re.fullmatch(r'del /f /q "([^"]+)" 2>nul', command)
        if m:
            self.files.pop(WIN.normalise(m.group(1)), None)
            return CommandResult(0, "", "")
        raise AssertionError(f"the fake device does not know {command!r}")

    # registry edits, as `reg add` / `reg delete` / regedit make them
    def set(self, key: str, name: str, type_: str, data) -> None:
        k = norm_key(key)
        for i in range(1, key.count("\\") + 1):  # parents exist as keys too
            parent = key.rsplit("\\", i)[0]
            if parent.count("\\") >= 1:
                self.registry.setdefault(norm_key(parent), RegKey(parent, {}))
        self.registry.setdefault(k, RegKey(key, {})).values[name.casefold()] = (name, typed_value(type_, data))

    def delete(self, key: str, name: str | None = None) -> None:
        if name is None:
            root = norm_key(key)
            for k in [k for k in self.registry if k == root or k.startswith(root + "\\")]:
                del self.registry[k]
        else:
            del self.registry[norm_key(key)].values[name.casefold()]


def state_of(dev: FakeWindows, baselines: dict[str, bytes] | None = None) -> FinalState:
    return FinalState(platform="windows", devices={"windows": dev},
                      baselines={("windows", p): b for p, b in (baselines or {}).items()})


def instance(template: str, /, **values) -> Subtask:
    tpl = TaskTemplate.model_validate(json.loads((LIBRARY / f"{template}.json").read_text(encoding="utf-8")))
    return materialise(tpl, values)


def run_evaluators(sub: Subtask, dev: FakeWindows, baselines: dict[str, bytes]):
    state = state_of(dev, baselines)
    return [get_evaluator(spec.func)(state, **spec.args) for spec in sub.evaluate]


def passed(verdicts) -> bool:
    return all(v.passed for v in verdicts)


def reasons(verdicts) -> str:
    return " | ".join(v.reason for v in verdicts if not v.passed)


def setup_registry(sub: Subtask) -> Branch:
    """The keys and values the template's set-up imports (its REGEDIT4 upload), parsed."""
    for step in sub.config:
        if step.type == "upload_file" and step.content and step.content.startswith("REGEDIT4"):
            return parse_reg_file(step.content.encode("cp1252")).branch
    raise KeyError("no .reg set-up in the template")


def snapshot(dev: FakeWindows, key: str) -> bytes:
    return reg_file(dev.branch(key))


# -- parsing ---------------------------------------------------------------------------------------------------------
def test_reg_query_output_of_wine_and_windows_parses_every_type():
    branch = parse_reg_query(WINE_QUERY)
    t = branch[norm_key(r"HKCU\Software\T")].values
    assert t[""][1] == RegValue("REG_SZ", "def")
    assert t["b"][1] == RegValue("REG_BINARY", b"\x0a\xff\x00")
    assert t["d"][1] == RegValue("REG_DWORD", 500)
    assert t["e"][1] == RegValue("REG_SZ", "")
    assert t["m"][1] == RegValue("REG_MULTI_SZ", ("one", "two"))
    assert t["s"][1] == RegValue("REG_SZ", "a  b") and t["sp ace"][1] == RegValue("REG_SZ", "v")
    assert t["x"][1] == RegValue("REG_EXPAND_SZ", r"C:\users\user\x")
    assert branch[norm_key(r"HKEY_CURRENT_USER\software\t\SUB")].values["in"][1] == RegValue("REG_SZ", "y")
    # a real Windows lists an unset default as "(value not set)": no value
    win = parse_reg_query("\r\nHKEY_CURRENT_USER\\Software\\W\r\n    (Default)    REG_SZ    (value not set)\r\n"
                          "    Q    REG_QWORD    0x2540be3ff\r\n\r\nHKEY_CURRENT_USER\\Software\\W\\Child\r\n")
    w = win[norm_key(r"HKCU\Software\W")].values
    assert "" not in w and w["q"][1] == RegValue("REG_QWORD", 9999999999)
    assert norm_key(r"HKCU\Software\W\Child") in win  # a listed sub-key is a key


def test_reg_files_parse_as_wine_writes_them_and_as_regedit4():
    reg = parse_reg_file(b"\xff\xfe" + WINE_EXPORT.encode("utf-16-le"))
    assert (reg.version, reg.encoding, reg.deletions) == ("5.00", "UTF-16 LE with BOM", [])
    app = reg.branch[norm_key(r"HKCU\Software\Imp\App")].values
    assert app["cache"][1] == RegValue("REG_EXPAND_SZ", r"%LOCALAPPDATA%\A")  # continued over two lines
    assert app["recent"][1] == RegValue("REG_MULTI_SZ", ("a.txt", "b"))
    assert app["layout"][1] == RegValue("REG_BINARY", b"\x0a\x0b\x0c")
    assert app["width"][1] == RegValue("REG_DWORD", 1280) and app["theme"][1] == RegValue("REG_SZ", "Dark")
    assert reg.branch[norm_key(r"HKCU\Software\Imp\App\Sub")].values[""][1] == RegValue("REG_SZ", "dflt")
    assert reg.branch[norm_key(r"HKCU\Software\Imp")].values == {}
    old = parse_reg_file(b'REGEDIT4\r\n\r\n[-HKEY_CURRENT_USER\\Software\\Gone]\r\n\r\n[HKEY_CURRENT_USER\\Software\\A]\r\n'
                         b'"Path"="C:\\\\x \\"q\\""\r\n"Exp"=hex(2):25,54,45,4d,50,25,00\r\n"Q"=hex(b):01,00,00,00,00,00,00,00\r\n'
                         b'"Del"=-\r\n')
    a = old.branch[norm_key(r"HKCU\Software\A")].values
    assert old.version == "REGEDIT4" and old.encoding == "UTF-8"
    assert a["path"][1] == RegValue("REG_SZ", 'C:\\x "q"') and a["exp"][1] == RegValue("REG_EXPAND_SZ", "%TEMP%")
    assert a["q"][1] == RegValue("REG_QWORD", 1)
    assert old.deletions == [r"HKEY_CURRENT_USER\Software\Gone", r"HKEY_CURRENT_USER\Software\A\Del"]
    for bad in (b"", b"[HKEY_CURRENT_USER\\Software\\A]\r\n", b"REGEDIT4\r\n\"x\"=\"outside a key\"\r\n",
                b"REGEDIT4\r\n[HKEY_CURRENT_USER\\A]\r\n\"x\"=word:1\r\n"):
        with pytest.raises(ValueError):
            parse_reg_file(bad)


def test_the_writers_here_round_trip_through_both_parsers():
    dev = FakeWindows()
    for name, t, d in [("s", "REG_SZ", 'a "b" \\c'), ("d", "REG_DWORD", 7), ("x", "REG_EXPAND_SZ", "%TEMP%\\long" * 9),
                       ("m", "REG_MULTI_SZ", ["one", "two"]), ("b", "REG_BINARY", "00ff" * 40), ("@", "REG_SZ", "def")]:
        dev.set(r"HKEY_CURRENT_USER\Software\R", "" if name == "@" else name, t, d)
    branch = dev.branch(r"HKCU\Software\R")
    assert branch_changes(branch, parse_reg_file(reg_file(branch)).branch) == []
    assert branch_changes(branch, parse_reg_file(reg_file(branch, "REGEDIT4")).branch) == []
    assert branch_changes(branch, parse_reg_query(query_text(branch))) == []


def test_typed_values_from_template_arguments():
    assert typed_value("REG_DWORD", "0x1f") == typed_value("reg_dword", 31) == RegValue("REG_DWORD", 31)
    assert typed_value("REG_BINARY", "0a,0B 0c") == RegValue("REG_BINARY", b"\n\x0b\x0c")
    assert typed_value("REG_MULTI_SZ", ["a", "b"]) == RegValue("REG_MULTI_SZ", ("a", "b"))
    with pytest.raises(ValueError):
        typed_value("REG_FOO", 1)
    with pytest.raises(ValueError):
        typed_value("REG_DWORD", "twelve")


@pytest.mark.parametrize("wine", [False, True])
def test_the_registry_is_read_with_reg_query_and_with_reg_export_under_wine(wine):
    dev = FakeWindows(wine=wine)
    dev.set(r"HKEY_CURRENT_USER\Software\V", "Name", "REG_SZ", "x")
    verdict = get_evaluator("registry_value_is")(state_of(dev), key=r"HKCU\Software\V", name="name", type="REG_SZ",
                                                 data="x")
    assert verdict.passed, verdict.reason
    assert ("read with reg export" if wine else "read with reg query") in verdict.reason
    if wine:  # the evaluator's own export is removed again
        assert any(c.startswith("del ") for c in dev.commands) and not dev.files
    missing = get_evaluator("registry_value_is")(state_of(dev), key=r"HKCU\Software\Nope", name="a", type="REG_SZ",
                                                 data="x")
    assert not missing.passed and "no key HKEY_CURRENT_USER\\Software\\Nope" in missing.reason


def test_text_outside_ascii_is_read_from_an_export():
    dev = FakeWindows()
    dev.set(r"HKEY_CURRENT_USER\Software\U", "City", "REG_SZ", "Zürich")
    verdict = get_evaluator("registry_value_is")(state_of(dev), key=r"HKCU\Software\U", name="City", type="REG_SZ",
                                                 data="Zürich")
    assert verdict.passed and "reg export" in verdict.reason


# -- windows-regedit-create_string -------------------------------------------------------------------------------------
@pytest.fixture(params=[False, True], ids=["windows", "wine"])
def create(request):
    sub = instance("regedit_create_string", vendor="Fabrikam", subkey="Updater", name="Server",
                   data=r"D:\Backups\Weekly")
    dev = FakeWindows(setup_registry(sub), wine=request.param)
    base = {sub.baseline[0]: snapshot(dev, r"HKCU\Software\Fabrikam")}
    return sub, dev, base


def test_create_string_passes_the_new_key_with_its_value(create):
    sub, dev, base = create
    assert "no key" in reasons(run_evaluators(sub, dev, base))
    dev.set(r"HKEY_CURRENT_USER\Software\Fabrikam\Updater", "Server", "REG_SZ", r"D:\Backups\Weekly")
    assert passed(run_evaluators(sub, dev, base))
    dev.registry[norm_key(r"HKCU\Software\Fabrikam\Updater")].values.clear()
    dev.set(r"HKEY_CURRENT_USER\Software\Fabrikam\Updater", "server", "REG_SZ", r"D:\Backups\Weekly")
    assert passed(run_evaluators(sub, dev, base))  # value names are case-insensitive, as in Windows


@pytest.mark.parametrize("mistake,needle", [
    (lambda d: d.set(r"HKCU\Software\Fabrikam\Updater", "Server", "REG_SZ", ""), "Server = REG_SZ ''"),
    (lambda d: d.set(r"HKCU\Software\Fabrikam", "Server", "REG_SZ", r"D:\Backups\Weekly"), "no key"),
    (lambda d: d.set(r"HKCU\Software\Fabrikam\Updater", "Server", "REG_EXPAND_SZ", r"D:\Backups\Weekly"),
     "same text, wrong type"),
    (lambda d: (d.set(r"HKCU\Software\Fabrikam\Updater", "Server", "REG_SZ", r"D:\Backups\Weekly"),
                d.delete(r"HKCU\Software\Fabrikam\Tools")), "damage: key HKEY_CURRENT_USER\\Software\\Fabrikam\\Tools deleted"),
    (lambda d: (d.set(r"HKCU\Software\Fabrikam\Updater", "Server", "REG_SZ", r"D:\Backups\Weekly"),
                d.set(r"HKCU\Software\Fabrikam\Updater", "Server2", "REG_SZ", "x")), "other values too: Server2"),
    (lambda d: (d.set(r"HKCU\Software\Fabrikam\Updater", "Server", "REG_SZ", r"D:\Backups\Weekly"),
                d.set(r"HKCU\Software\Fabrikam", "Edition", "REG_SZ", "Home")), "Edition changed"),
])
def test_create_string_rejects_the_negatives(create, mistake, needle):
    sub, dev, base = create
    mistake(dev)
    assert needle in reasons(run_evaluators(sub, dev, base))


def test_create_string_without_its_snapshot_says_so(create):
    sub, dev, _ = create
    dev.set(r"HKEY_CURRENT_USER\Software\Fabrikam\Updater", "Server", "REG_SZ", r"D:\Backups\Weekly")
    assert "no set-up snapshot" in reasons(run_evaluators(sub, dev, {}))


# -- windows-regedit-change_dword ----------------------------------------------------------------------------------------
@pytest.fixture
def dword():
    sub = instance("regedit_change_dword", vendor="Adatum", name="TimeoutSeconds", number=550)
    dev = FakeWindows(setup_registry(sub), wine=True)
    return sub, dev, {sub.baseline[0]: snapshot(dev, r"HKCU\Software\Adatum\Settings")}


def test_change_dword(dword):
    sub, dev, base = dword
    key = r"HKCU\Software\Adatum\Settings"
    assert "TimeoutSeconds = REG_DWORD 30" in reasons(run_evaluators(sub, dev, base))
    dev.set(key, "TimeoutSeconds", "REG_DWORD", 550)  # regedit's Modify with Base: Decimal
    assert passed(run_evaluators(sub, dev, base))
    for mistake, needle in [
        (lambda: dev.set(key, "TimeoutSeconds", "REG_SZ", "550"), "same text, wrong type"),
        (lambda: dev.set(key, "TimeoutSeconds", "REG_DWORD", 0x550), "REG_DWORD 1360 (0x550)"),
        (lambda: (dev.set(key, "TimeoutSeconds", "REG_DWORD", 30), dev.set(key, "RetryCount", "REG_DWORD", 550)),
         "RetryCount changed from REG_DWORD 3"),
        (lambda: (dev.set(key, "TimeoutSeconds", "REG_DWORD", 550), dev.delete(key, "LogLevel")), "LogLevel deleted"),
        (lambda: (dev.set(key, "LogLevel", "REG_SZ", "info"), dev.delete(key, "DataPath")), "DataPath deleted"),
    ]:
        mistake()
        assert needle in reasons(run_evaluators(sub, dev, base))
        dev.registry = setup_registry(sub)


# -- windows-regedit-delete_value ----------------------------------------------------------------------------------------
def test_delete_value_keeps_every_other_type_of_value():
    sub = instance("regedit_delete_value", vendor="Wingtip", app="Viewer", name="RecentFiles")
    key = r"HKCU\Software\Wingtip\Viewer"
    dev = FakeWindows(setup_registry(sub))
    base = {sub.baseline[0]: snapshot(dev, key)}
    assert "RecentFiles still there (REG_MULTI_SZ ['plan.txt', 'budget.csv'])" in reasons(run_evaluators(sub, dev, base))
    dev.delete(key, "RecentFiles")
    assert passed(run_evaluators(sub, dev, base))
    dev.set(key, "WindowLayout", "REG_BINARY", "01")
    assert "WindowLayout changed from REG_BINARY 01,00,00,00,2c,01" in reasons(run_evaluators(sub, dev, base))
    dev.registry = setup_registry(sub)
    dev.set(key, "RecentFiles", "REG_SZ", "")  # emptied, not deleted
    assert "RecentFiles still there (REG_SZ '')" in reasons(run_evaluators(sub, dev, base))
    dev.delete(key, "RecentFiles")
    dev.delete(key + r"\Plugins")
    assert "key HKEY_CURRENT_USER\\Software\\Wingtip\\Viewer\\Plugins deleted" in reasons(run_evaluators(sub, dev, base))
    dev.delete(key)
    assert "no key" in reasons(run_evaluators(sub, dev, base))  # the key itself must stay


# -- windows-regedit-export_key ---------------------------------------------------------------------------------------------
@pytest.fixture
def export():
    sub = instance("regedit_export_key", vendor="Lucerne", app="Mailer", folder=r"C:\Users\user\Documents",
                   name="settings_backup")
    key = r"HKEY_CURRENT_USER\Software\Lucerne\Mailer"
    dev = FakeWindows(setup_registry(sub), wine=True)
    return sub, dev, {sub.baseline[0]: snapshot(dev, key)}, key, sub.output["exported"].value


def test_export_key_accepts_regedits_file_in_both_formats(export):
    sub, dev, base, key, path = export
    assert "no file at" in reasons(run_evaluators(sub, dev, base))
    dev.put(path, reg_file(dev.branch(key)))  # File > Export, "Registration Files (*.reg)"
    assert passed(run_evaluators(sub, dev, base)), reasons(run_evaluators(sub, dev, base))
    dev.files.clear()
    dev.put(path, reg_file(dev.branch(key), "REGEDIT4"))  # "Win9x/NT4 Registration Files (REGEDIT4)"
    assert passed(run_evaluators(sub, dev, base))


@pytest.mark.parametrize("mistake,needle", [
    (lambda dev, key, path: dev.put(path, f"[{key}]\r\n".encode()), "no .reg file"),
    (lambda dev, key, path: dev.put(path, reg_file(dev.branch(key + r"\Accounts"))), "Mailer missing"),
    (lambda dev, key, path: dev.put(path, reg_file(dev.branch(r"HKCU\Software\Lucerne"))), "outside the branch"),
    (lambda dev, key, path: (dev.put(path, reg_file(dev.branch(key))), dev.delete(key)), "is gone"),
    (lambda dev, key, path: dev.put(path, reg_file(dev.branch(key)).decode("utf-16").encode("utf-8")),
     "version 5.00 file in UTF-8"),
    (lambda dev, key, path: (dev.set(key, "Port", "REG_DWORD", 1), dev.put(path, reg_file(dev.branch(key)))),
     "Port changed from REG_DWORD 993"),
    (lambda dev, key, path: dev.put(path, reg_file(dev.branch(key)) + "[-HKEY_CURRENT_USER\\Software]\r\n"
                                    .encode("utf-16-le")), "a file that deletes"),
])
def test_export_key_rejects_the_negatives(export, mistake, needle):
    sub, dev, base, key, path = export
    mistake(dev, key, path)
    assert needle in reasons(run_evaluators(sub, dev, base))


def test_check_reg_export_names_missing_and_extra_values():
    dev = FakeWindows()
    dev.set(r"HKCU\Software\E", "a", "REG_SZ", "1")
    expected = parse_reg_file(reg_file(dev.branch(r"HKCU\Software\E"))).branch  # a copy, as set up
    dev.set(r"HKCU\Software\E", "b", "REG_SZ", "2")
    verdict = check_reg_export(reg_file(dev.branch(r"HKCU\Software\E")), r"HKCU\Software\E", expected)
    assert not verdict.passed and "b extra" in verdict.reason


# -- windows-control-* and windows-minesweeper-custom_field -------------------------------------------------------------
DESKTOP = r"HKEY_CURRENT_USER\Control Panel\Desktop"


@pytest.fixture
def wallpaper():
    sub = instance("control_set_wallpaper", image=r"C:\Users\user\Pictures\lake.bmp")
    dev = FakeWindows(wine=True)
    for name, value in [("Wallpaper", ""), ("MenuShowDelay", "400"), ("WheelScrollLines", "3")]:
        dev.set(DESKTOP, name, "REG_SZ", value)
    dev.set(DESKTOP + r"\WindowMetrics", "BorderWidth", "REG_SZ", "1")
    for step in sub.config:
        if step.type == "upload_file":
            dev.put(step.path, generate(step.generator, step.args))
    image = sub.input["image"].value
    base = {sub.baseline[0]: snapshot(dev, DESKTOP), image: dev.download(image)}
    return sub, dev, base, image


def test_wallpaper_is_the_picture_by_path_or_a_copy_windows_made(wallpaper):
    sub, dev, base, image = wallpaper
    assert "Wallpaper = '' (no wallpaper)" in reasons(run_evaluators(sub, dev, base))
    dev.set(DESKTOP, "Wallpaper", "REG_SZ", image.upper().replace("\\", "/"))  # another spelling of the same path
    assert passed(run_evaluators(sub, dev, base))
    # Windows' Settings app: a transcoded copy, and its own companion values
    copy = r"C:\Users\user\AppData\Roaming\Microsoft\Windows\Themes\TranscodedWallpaper"
    img = Image.open(io.BytesIO(dev.download(image)))
    buf = io.BytesIO()
    img.convert("RGB").save(buf, "JPEG", quality=95)
    dev.put(copy, buf.getvalue())
    dev.set(DESKTOP, "Wallpaper", "REG_SZ", copy)
    dev.set(DESKTOP, "TranscodedImageCount", "REG_DWORD", 1)
    dev.set(DESKTOP, "WallpaperStyle", "REG_SZ", "10")
    assert passed(run_evaluators(sub, dev, base)), reasons(run_evaluators(sub, dev, base))
    fed = {sub.baseline[0]: base[sub.baseline[0]]}  # a fed picture has no baseline (the key's snapshot still has)
    assert passed(run_evaluators(sub, dev, fed))


def test_wallpaper_rejects_the_negatives(wallpaper):
    sub, dev, base, image = wallpaper
    other = r"C:\Users\user\Pictures\holiday.bmp"
    cases = [
        (lambda: dev.set(DESKTOP, "Wallpaper", "REG_SZ", r"C:\Users\user\Pictures"), "no picture file there"),
        (lambda: dev.set(DESKTOP, "Wallpaper", "REG_SZ", other), "pixels off"),
        (lambda: (dev.set(DESKTOP, "Wallpaper", "REG_SZ", image), dev.put(image, dev.download(other))),
         "changed since set-up"),
        (lambda: (dev.set(DESKTOP, "Wallpaper", "REG_SZ", image), dev.delete(DESKTOP, "MenuShowDelay")),
         "MenuShowDelay deleted"),
        (lambda: dev.set(DESKTOP, "Wallpaper", "REG_DWORD", 1), "not a string"),
        (lambda: dev.set(DESKTOP, "Wallpaper", "REG_SZ", "lake.bmp"), "not a full path"),
    ]
    original = dict(dev.files)
    for mistake, needle in cases:
        mistake()
        assert needle in reasons(run_evaluators(sub, dev, base))
        dev.files = dict(original)
        dev.set(DESKTOP, "Wallpaper", "REG_SZ", "")
        dev.set(DESKTOP, "MenuShowDelay", "REG_SZ", "400")


ADVANCED = r"HKEY_CURRENT_USER\Software\Microsoft\Windows\CurrentVersion\Explorer\Advanced"


@pytest.mark.parametrize("action,start,want", [("show", 1, 0), ("hide", 0, 1)])
def test_file_extensions_reads_hidefileext_as_explorer_does(action, start, want):
    sub = instance("control_file_extensions", action=action)
    dev = FakeWindows(setup_registry(sub))
    dev.set(ADVANCED, "HideFileExt", "REG_DWORD", start)
    base = {sub.baseline[0]: snapshot(dev, ADVANCED)}
    assert f"HideFileExt = REG_DWORD {start}" in reasons(run_evaluators(sub, dev, base))
    dev.set(ADVANCED, "HideFileExt", "REG_SZ", str(want))
    assert "same text, wrong type" in reasons(run_evaluators(sub, dev, base))
    dev.set(ADVANCED, "HideFileExt", "REG_DWORD", want)
    assert passed(run_evaluators(sub, dev, base))
    dev.set(ADVANCED, "Hidden", "REG_DWORD", 1)
    assert "Hidden changed from REG_DWORD 2" in reasons(run_evaluators(sub, dev, base))


def test_double_click_speed_is_the_string_windows_reads():
    sub = instance("control_double_click", speed=760)
    mouse = r"HKEY_CURRENT_USER\Control Panel\Mouse"
    dev = FakeWindows()
    for name, value in [("DoubleClickSpeed", "500"), ("SwapMouseButtons", "0"), ("MouseHoverTime", "400")]:
        dev.set(mouse, name, "REG_SZ", value)
    base = {sub.baseline[0]: snapshot(dev, mouse)}
    assert "DoubleClickSpeed = REG_SZ '500'" in reasons(run_evaluators(sub, dev, base))
    dev.set(mouse, "DoubleClickSpeed", "REG_DWORD", 760)
    assert "same text, wrong type" in reasons(run_evaluators(sub, dev, base))
    dev.set(mouse, "DoubleClickSpeed", "REG_SZ", "760")  # SystemParametersInfo(SPI_SETDOUBLECLICKTIME)
    assert passed(run_evaluators(sub, dev, base))
    dev.set(mouse, "SwapMouseButtons", "REG_SZ", "1")
    assert "SwapMouseButtons changed from REG_SZ '0' to REG_SZ '1'" in reasons(run_evaluators(sub, dev, base))


def probing(monkeypatch, procs: list[dict], windows: list[dict] | None = None, exits_after: int | None = None):
    """Make the Windows probe answer with `procs` and `windows` (a process list and its windows); with
    `exits_after`, the processes are gone from that many probes on. Returns how many probes were made."""
    calls = []

    def fake(state, **request):
        assert request.get("processes") and request.get("windows"), request
        calls.append(1)
        gone = exits_after is not None and len(calls) > exits_after
        return {"processes": [] if gone else procs, "windows": [] if gone else (windows or [])}

    monkeypatch.setattr(wr, "probe", fake)
    return calls


def test_minesweeper_custom_field_keeps_the_best_times(monkeypatch):
    probing(monkeypatch, [{"pid": 32, "ppid": 8, "name": "explorer.exe"}])  # Minesweeper has exited
    sub = instance("minesweeper_custom_field", rows=16, cols=30, mines=60)
    mine = r"HKEY_CURRENT_USER\Software\Microsoft\WinMine"
    dev = FakeWindows(setup_registry(sub), wine=True)
    base = {sub.baseline[0]: snapshot(dev, mine)}
    assert "Difficulty = REG_DWORD 0" in reasons(run_evaluators(sub, dev, base))
    for name, value in [("Difficulty", 3), ("Height", 16), ("Width", 30), ("Mines", 60), ("Xpos", 3), ("Ypos", 41)]:
        dev.set(mine, name, "REG_DWORD", value)  # what winemine saves on exit (its window position too)
    assert passed(run_evaluators(sub, dev, base))
    dev.set(mine, "Height", "REG_DWORD", 30)
    dev.set(mine, "Width", "REG_DWORD", 16)
    assert "Height = REG_DWORD 30" in reasons(run_evaluators(sub, dev, base))
    dev.set(mine, "Height", "REG_DWORD", 16)
    dev.set(mine, "Width", "REG_DWORD", 30)
    dev.set(mine, "Time1", "REG_DWORD", 999)
    assert "Time1 changed from REG_DWORD 41" in reasons(run_evaluators(sub, dev, base))


def test_minesweeper_must_have_exited_before_its_settings_count(monkeypatch):
    """The registry already right while winemine still runs with another field (it writes that one on exit):
    fails, and says so; a winemine that shows no window more is finishing its exit and is waited for."""
    sub = instance("minesweeper_custom_field", rows=16, cols=30, mines=60)
    mine = r"HKEY_CURRENT_USER\Software\Microsoft\WinMine"
    dev = FakeWindows(setup_registry(sub), wine=True)
    base = {sub.baseline[0]: snapshot(dev, mine)}
    for name, value in [("Difficulty", 3), ("Height", 16), ("Width", 30), ("Mines", 60)]:
        dev.set(mine, name, "REG_DWORD", value)  # `reg add` while the game runs
    game = {"pid": 52, "ppid": 8, "name": "winemine.exe"}
    probing(monkeypatch, [game], [{"title": "WineMine", "pid": 52, "visible": True}])
    found = reasons(run_evaluators(sub, dev, base))
    assert "winemine.exe still running (pid 52)" in found and "writes the values it holds over" in found, found
    assert "and winemine.exe exited" in found
    monkeypatch.setattr(wr, "EXIT_GRACE", 0.2)
    probing(monkeypatch, [game])  # no window, and it never goes: still running after the grace
    assert "still running" in reasons(run_evaluators(sub, dev, base))
    monkeypatch.setattr(wr, "EXIT_GRACE", 5.0)
    calls = probing(monkeypatch, [game], exits_after=1)  # no window, gone at the second look
    assert passed(run_evaluators(sub, dev, base)) and len(calls) == 2


# -- Edge (its favourites: test_evaluators_browser.py) --------------------------------------------------------------
def test_edge_save_pdf_reads_the_pdf():
    sub = instance("edge_save_pdf", title="Boarding Pass", code="REF-12345", folder=r"C:\Users\user\Desktop",
                   name="printout")
    dev = FakeWindows()
    pdf = sub.output["pdf"].value
    from pypdf import PdfWriter

    dev.put(pdf, b"<html><h1>Boarding Pass</h1></html>")  # the page saved as HTML under the PDF's name
    assert "no PDF" in reasons(run_evaluators(sub, dev, {}))
    blank = io.BytesIO()
    writer = PdfWriter()
    writer.add_blank_page(200, 200)
    writer.write(blank)
    dev.put(pdf, blank.getvalue())  # an empty page printed
    assert "lacking" in reasons(run_evaluators(sub, dev, {}))


# -- Paint (its evaluators are the image evaluators; these are the files its oracle and negatives leave) ------------------
def png(img: Image.Image) -> bytes:
    buf = io.BytesIO()
    img.save(buf, "PNG")
    return buf.getvalue()


def paint_case(name: str, **values):
    sub = instance(name, **values)
    dev = FakeWindows()
    step = next(s for s in sub.config if s.type == "upload_file")
    dev.put(step.path, generate(step.generator, step.args))
    return sub, dev, {step.path: dev.download(step.path)}, step.path


def test_paint_save_png():
    sub, dev, base, src = paint_case("paint_save_png", image=r"C:\Users\user\Pictures\receipt.jpg")
    out = sub.output["png"].value
    img = Image.open(io.BytesIO(dev.download(src)))
    dev.put(out, png(img))
    assert passed(run_evaluators(sub, dev, base))
    dev.put(out, dev.download(src))
    assert "JPEG data" in reasons(run_evaluators(sub, dev, base))
    bmp = io.BytesIO()
    img.save(bmp, "BMP")
    dev.put(out, bmp.getvalue())
    assert "BMP data" in reasons(run_evaluators(sub, dev, base))
    dev.put(out, png(img))
    del dev.files[WIN.normalise(src)]
    assert "deleted" in reasons(run_evaluators(sub, dev, base))


def test_paint_resize_percent():
    sub, dev, base, src = paint_case("paint_resize_percent", image=r"C:\Users\user\Pictures\garden.png", percent=50)
    out = sub.output["resized"].value
    img = Image.open(io.BytesIO(dev.download(src))).convert("RGB")
    dev.put(out, png(img.resize((320, 240), Image.Resampling.BILINEAR)))  # GDI+'s default resampling
    assert passed(run_evaluators(sub, dev, base)), reasons(run_evaluators(sub, dev, base))
    for bad in (img, img.resize((50, 38)), img.resize((320, 480))):
        dev.put(out, png(bad))
        assert not passed(run_evaluators(sub, dev, base))
    dev.put(out, png(img.resize((320, 240))))
    dev.put(src, png(img.resize((320, 240))))
    assert "original" in reasons(run_evaluators(sub, dev, base))


@pytest.mark.parametrize("direction", ["horizontal", "vertical"])
def test_paint_flip(direction):
    sub, dev, base, src = paint_case("paint_flip", image=r"C:\Users\user\Documents\diagram.png", direction=direction)
    out = sub.output["flipped"].value
    img = Image.open(io.BytesIO(dev.download(src))).convert("RGB")
    mirror, other = (ImageOps.mirror, ImageOps.flip) if direction == "horizontal" else (ImageOps.flip, ImageOps.mirror)
    dev.put(out, png(mirror(img)))
    assert passed(run_evaluators(sub, dev, base))
    for bad in (img, other(img), img.rotate(180)):
        dev.put(out, png(bad))
        assert not passed(run_evaluators(sub, dev, base))
    dev.put(out, png(mirror(img)))
    dev.put(src, png(mirror(img)))
    assert "original" in reasons(run_evaluators(sub, dev, base))
