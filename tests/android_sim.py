"""A simulated Android device for the offline quality gate of the Android task library (no Android can run here).

What is real: the commands of the templates' set-up, oracles and negatives run in `mksh` (Android's
/system/bin/sh) with toybox's applets (`sed`, `date`, `stat`, `find`, `sha256sum`, `nc`, `printf`, ...: Android's
userland), on a folder that stands in for the device's storage (`/sdcard`, `/data/local/tmp`, `/data/data` are
mapped into it); the HTTP pages of the Chrome templates are served by the templates' own `toybox nc -L` server; the
evaluators, baselines, set-up steps and negatives run through the harness's own functions.

What is simulated: the platform's command-line tools (`content`, `settings`, `cmd uimode`, `dumpsys`, `svc`, `am`,
`pm`, `appops`, `wm`, `input`, `screencap`, `getprop`) — this module run as a script, keeping the providers and
services in one SQLite file — with the semantics their AOSP sources give them: `content` prints rows as
`Content.java` does (`Row: n col=value, ...`, `NULL`, `No result found.`); the SMS provider ignores writes from a
caller without the WRITE_SMS app op (AOSP `SmsProvider` with `setAppOps(OP_READ_SMS, OP_WRITE_SMS)`: MODE_IGNORED
fakes the insert); the call log refuses the shell (READ/WRITE_CALL_LOG) but not root; calendars can only be
inserted by a sync adapter; a non-sync-adapter event delete marks the row deleted; the Clock's ACTION_SET_ALARM
handler needs the SET_ALARM permission (root has it); `dumpsys alarm` and `dumpsys bluetooth_manager` print what
AlarmManagerService and BluetoothManagerService print. Apps are reduced to what the templates' oracles and negatives
make them do (a call ended with KEYCODE_ENDCALL is logged as outgoing; KEYCODE_CAMERA saves a JPEG in DCIM/Camera;
Ctrl+D in Chrome bookmarks the page in the Bookmarks JSON with Chrome's checksum). A pass here says the templates'
commands, evaluators and negatives agree with each other and with those semantics — not that the real apps behave
so: that needs a device (`make test-android`).
"""

from __future__ import annotations

import json
import os
import re
import shlex
import sqlite3
import subprocess
import sys
import time
from datetime import datetime, timedelta
from pathlib import Path
from zoneinfo import ZoneInfo

TZ = "America/New_York"
TOYBOX_APPLETS = ("sed", "date", "stat", "head", "tail", "ls", "find", "sha256sum", "printf", "cat", "rm", "mv",
                  "cp", "mkdir", "grep", "nc", "touch", "chmod", "nohup", "tr", "wc", "cut", "sort", "test", "echo",
                  "true", "false", "id", "basename", "dirname", "ln", "toybox", "setsid", "env", "seq")
TOOLS = ("content", "settings", "cmd", "dumpsys", "svc", "am", "pm", "appops", "wm", "input", "screencap",
         "getprop", "sleep")

SCHEMA = """
CREATE TABLE IF NOT EXISTS settings (ns TEXT, key TEXT, value TEXT, PRIMARY KEY (ns, key));
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT);
CREATE TABLE IF NOT EXISTS raw_contacts (_id INTEGER PRIMARY KEY AUTOINCREMENT, starred INTEGER DEFAULT 0,
    deleted INTEGER DEFAULT 0, account_name TEXT, account_type TEXT);
CREATE TABLE IF NOT EXISTS data (_id INTEGER PRIMARY KEY AUTOINCREMENT, raw_contact_id INTEGER, mimetype TEXT,
    data1 TEXT, data2 TEXT);
CREATE VIEW IF NOT EXISTS raw_contacts_v AS SELECT r.*, (SELECT d.data1 FROM data d WHERE d.raw_contact_id = r._id
    AND d.mimetype = 'vnd.android.cursor.item/name' ORDER BY d._id LIMIT 1) AS display_name FROM raw_contacts r;
CREATE TABLE IF NOT EXISTS sms (_id INTEGER PRIMARY KEY AUTOINCREMENT, thread_id INTEGER, address TEXT, body TEXT,
    type INTEGER, date INTEGER, read INTEGER DEFAULT 0);
CREATE TABLE IF NOT EXISTS calls (_id INTEGER PRIMARY KEY AUTOINCREMENT, number TEXT, type INTEGER, date INTEGER,
    duration INTEGER, new INTEGER DEFAULT 1);
CREATE TABLE IF NOT EXISTS calendars (_id INTEGER PRIMARY KEY AUTOINCREMENT, name TEXT, account_name TEXT,
    account_type TEXT, calendar_displayName TEXT, calendar_color INTEGER, calendar_access_level INTEGER,
    ownerAccount TEXT, visible INTEGER, sync_events INTEGER, calendar_timezone TEXT);
CREATE TABLE IF NOT EXISTS events (_id INTEGER PRIMARY KEY AUTOINCREMENT, calendar_id INTEGER, title TEXT,
    dtstart INTEGER, dtend INTEGER, allDay INTEGER DEFAULT 0, deleted INTEGER DEFAULT 0, eventTimezone TEXT);
CREATE TABLE IF NOT EXISTS alarms (_id INTEGER PRIMARY KEY AUTOINCREMENT, hour INTEGER, minutes INTEGER);
"""
DEFAULT_SETTINGS = [("system", "screen_brightness", "102"), ("system", "screen_brightness_mode", "0"),
                    ("system", "screen_off_timeout", "2147483647"), ("system", "font_scale", "1.0"),
                    ("secure", "ui_night_mode", "1"), ("global", "bluetooth_on", "0"), ("global", "wifi_on", "1"),
                    ("global", "airplane_mode_on", "0")]


# -- the device (host side) ------------------------------------------------------------------------------------
class SimAndroid:
    """A device object for the harness (run, upload, download, exists, launch, open, act, query_database) whose
    storage is `root` and whose platform tools are the simulated ones."""

    platform = "android"

    def __init__(self, root: Path, ports: dict[int, int] | None = None):
        self.root = Path(root)
        self.is_root = False
        self.ports = dict(ports or {})   # the task's port → a free one here (parallel tests, a busy host)
        for d in ("sdcard/Download", "sdcard/Documents", "sdcard/DCIM", "sdcard/Pictures", "data/local/tmp",
                  "data/data/com.android.chrome/app_chrome/Default", "bin"):
            (self.root / d).mkdir(parents=True, exist_ok=True)
        self.bin = self.root / "bin"
        toybox = _which("toybox")
        for applet in TOYBOX_APPLETS:
            link = self.bin / applet
            if not link.exists():
                link.symlink_to(toybox)
        if not (self.bin / "sh").exists():
            (self.bin / "sh").symlink_to(_which("mksh"))
        for tool in TOOLS:
            script = self.bin / tool
            flags = "" if tool in ("input", "screencap") else "-S "   # no site-packages: starts in 20 ms
            script.write_text(f"#!/bin/sh\nexec {shlex.quote(sys.executable)} {flags}{shlex.quote(__file__)} {tool} "
                              "\"$@\"\n")
            script.chmod(0o755)
        con = self.db()
        con.executescript(SCHEMA)
        con.executemany("INSERT OR IGNORE INTO settings VALUES (?, ?, ?)", DEFAULT_SETTINGS)
        con.commit()
        con.close()
        self.launched: list[str] = []

    # paths -------------------------------------------------------------------------------------------------
    def map_text(self, text: str) -> str:
        for a, b in self.ports.items():   # the server's listening port and the oracle's own `nc` requests
            text = text.replace(f"-p {a} ", f"-p {b} ").replace(f"nc 127.0.0.1 {a}", f"nc 127.0.0.1 {b}")
        r = str(self.root)
        return (text.replace("/data/local/tmp", f"{r}/data/local/tmp").replace("/data/data/", f"{r}/data/data/")
                .replace("/sdcard", f"{r}/sdcard"))

    def unmap_text(self, text: str) -> str:
        return text.replace(str(self.root), "")

    def host(self, path: str) -> Path:
        return Path(self.map_text(path))

    def db(self) -> sqlite3.Connection:
        con = sqlite3.connect(self.root / "sim.db")
        con.execute("PRAGMA synchronous = OFF")
        return con

    def env(self, user: str | None) -> dict[str, str]:
        return {"PATH": f"{self.bin}", "HOME": str(self.root / "data/local/tmp"), "TZ": TZ,
                "SIM_ROOT": str(self.root), "SIM_USER": "root" if (self.is_root or user == "root") else "shell",
                "SIM_PORTS": ",".join(f"{a}={b}" for a, b in self.ports.items()),
                "LANG": "C.UTF-8"}

    # the harness's device API ------------------------------------------------------------------------------
    def run(self, command: str, *, timeout: float = 60.0, user: str | None = None):
        from jarvis_pytest.devices.base import CommandResult

        if user == "root":
            self.is_root = True   # `adb root` restarts adbd as root: later shells are root too
        res = subprocess.run([_which("mksh"), "-c", self.map_text(command)], capture_output=True,
                             env=self.env(user), timeout=timeout, cwd=self.root / "data/local/tmp")
        out = res.stdout.decode("utf-8", "replace")
        err = res.stderr.decode("utf-8", "replace")
        return CommandResult(res.returncode, self.unmap_text(out), self.unmap_text(err))

    def upload(self, path: str, data: bytes) -> None:
        p = self.host(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(data)

    def download(self, path: str) -> bytes:
        return self.host(path).read_bytes()

    def exists(self, path: str) -> bool:
        return os.path.lexists(self.host(path))

    def launch(self, app: str, *args: str, window_wait: float = 20.0) -> bool:
        self.launched.append(app)
        if "-d" in args:
            _set_meta(self.db(), "chrome_url", args[list(args).index("-d") + 1])
        return True

    def open(self, path: str, *, window_wait: float = 20.0) -> bool:
        self.launched.append(f"open {path}")
        return True

    def act(self, action):
        from jarvis_pytest.devices.base import ActionOutcome

        if action.type == "HOTKEY" and [k.lower() for k in action.keys] == ["ctrl", "d"]:
            chrome_bookmark_current(self)
        return ActionOutcome(ok=True, error=None, elapsed_ms=0.0)

    def query_database(self, package: str, database: str, sql: str, params: tuple = ()) -> list[dict]:
        assert (package, database) == ("com.android.providers.telephony", "mmssms.db"), (package, database)
        self.is_root = True
        con = self.db()
        con.row_factory = sqlite3.Row
        try:
            return [dict(r) for r in con.execute(sql, params)]
        finally:
            con.close()

    def close(self) -> None:
        """Stop the HTTP servers the set-up started (only those serving from this device's folder, by pid)."""
        for pid in server_pids(self.root):
            try:
                os.kill(pid, 15)
            except ProcessLookupError:
                pass


def server_pids(root: Path) -> list[int]:
    """Processes whose command line names a file under `root` (the `toybox nc -L ... serve.sh` servers)."""
    pids = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode("utf-8", "replace")
        except OSError:
            continue
        if str(root) in cmdline and "serve.sh" in cmdline:
            pids.append(int(entry.name))
    return pids


def chrome_bookmark_current(dev: SimAndroid) -> None:
    """Chrome's Ctrl+D: bookmark the current page (its <title> fetched from the page) in the Bookmarks file, with
    the checksum Chrome's bookmark codec computes."""
    from jarvis_pytest.evaluators.browser import bookmarks_checksum

    con = dev.db()
    url = _get_meta(con, "chrome_url") or ""
    con.close()
    import urllib.request

    with urllib.request.urlopen(_served(url, dev.ports), timeout=10) as r:   # the task's own server, 127.0.0.1
        html = r.read().decode("utf-8", "replace")
    m = re.search(r"<title>(.*?)</title>", html, re.S)
    title = m.group(1).strip() if m else url
    path = dev.root / "data/data/com.android.chrome/app_chrome/Default/Bookmarks"
    data = json.loads(path.read_text()) if path.exists() else {"roots": {
        "bookmark_bar": {"children": [], "id": "1", "name": "Bookmarks bar", "type": "folder"},
        "other": {"children": [], "id": "2", "name": "Other bookmarks", "type": "folder"},
        "synced": {"children": [], "id": "3", "name": "Mobile bookmarks", "type": "folder"}}, "version": 1}
    mobile = data["roots"]["synced"]["children"]
    mobile.append({"id": str(4 + len(mobile)), "name": title, "type": "url", "url": url})
    data["checksum"] = bookmarks_checksum(data)
    path.write_text(json.dumps(data, indent=3))


def _served(url: str, ports: dict[int, int]) -> str:
    """Where the test serves the task's URL (its port renamed to the free one)."""
    for a, b in ports.items():
        url = url.replace(f"127.0.0.1:{a}/", f"127.0.0.1:{b}/")
    return url


def _which(name: str) -> str:
    for d in ("/usr/bin", "/bin", "/usr/local/bin"):
        if os.access(f"{d}/{name}", os.X_OK):
            return f"{d}/{name}"
    raise FileNotFoundError(name)


def _get_meta(con: sqlite3.Connection, key: str) -> str | None:
    row = con.execute("SELECT value FROM meta WHERE key = ?", (key,)).fetchone()
    return None if row is None else row[0]


def _set_meta(con: sqlite3.Connection, key: str, value: str | None) -> None:
    con.execute("INSERT OR REPLACE INTO meta VALUES (?, ?)", (key, value))
    con.commit()


# -- the platform tools (run as `python3 android_sim.py TOOL ARGS...` inside the device's shell) ---------------
class Exit(Exception):
    def __init__(self, code: int, err: str = ""):
        self.code, self.err = code, err


def _con() -> sqlite3.Connection:
    con = sqlite3.connect(Path(os.environ["SIM_ROOT"]) / "sim.db", timeout=10)
    con.row_factory = sqlite3.Row
    con.execute("PRAGMA synchronous = OFF")   # a test's state: no fsync per write
    return con


def _root() -> bool:
    return os.environ.get("SIM_USER") == "root"


def _now_ms() -> int:
    return int(time.time() * 1000)


def tool_settings(args: list[str]) -> str:
    con = _con()
    verb, ns, key = args[0], args[1], args[2]
    if verb == "get":
        row = con.execute("SELECT value FROM settings WHERE ns=? AND key=?", (ns, key)).fetchone()
        return ("null" if row is None or row[0] is None else row[0]) + "\n"
    if verb == "put":
        con.execute("INSERT OR REPLACE INTO settings VALUES (?, ?, ?)", (ns, key, args[3]))
    elif verb == "delete":
        con.execute("DELETE FROM settings WHERE ns=? AND key=?", (ns, key))
    con.commit()
    if (ns, key) == ("global", "bluetooth_on"):
        pass  # the flag alone does not switch the adapter (BluetoothManagerService does not watch it)
    return ""


def _put(con, ns, key, value):
    con.execute("INSERT OR REPLACE INTO settings VALUES (?, ?, ?)", (ns, key, value))


def tool_cmd(args: list[str]) -> str:
    con = _con()
    if args[:2] == ["uimode", "night"]:
        modes = {"no": "1", "yes": "2", "auto": "0", "custom": "3"}
        if len(args) > 2:
            _put(con, "secure", "ui_night_mode", modes[args[2]])
            _set_meta(con, "night", args[2])
            con.commit()
        mode = _get_meta(con, "night") or "no"
        return f"Night mode: {mode}\n"
    raise Exit(1, f"cmd: unknown {args}")


def tool_svc(args: list[str]) -> str:
    con = _con()
    what, verb = args[0], args[1] if len(args) > 1 else ""
    if what == "bluetooth":
        on = verb == "enable"
        _set_meta(con, "bt", "1" if on else "0")
        _put(con, "global", "bluetooth_on", "1" if on else "0")
    elif what == "wifi":
        _put(con, "global", "wifi_on", "1" if verb == "enable" else "0")
    con.commit()
    return ""


def tool_dumpsys(args: list[str]) -> str:
    con = _con()
    if args[0] == "bluetooth_manager":
        on = (_get_meta(con, "bt") or "0") == "1"
        return f"Bluetooth Status\n  enabled: {'true' if on else 'false'}\n  state: {'ON' if on else 'OFF'}\n" \
               "  address: 3C:5A:B4:01:02:03\n  name: sdk_gphone64_x86_64\n"
    if args[0] == "alarm":
        tz = ZoneInfo(TZ)
        now = datetime.now(tz)
        fmt = "%Y-%m-%d %H:%M:%S.000"
        lines = ["Current Alarm Manager state:", f"  nowRTC={int(now.timestamp() * 1000)}={now.strftime(fmt)} "
                 "nowELAPSED=123456", "", "  Next alarm clock information: "]
        nexts = []
        for row in con.execute("SELECT hour, minutes FROM alarms"):
            t = now.replace(hour=row[0], minute=row[1], second=0, microsecond=0)
            if t <= now:
                t += timedelta(days=1)
            nexts.append(t)
        if nexts:
            t = min(nexts)
            lines.append(f"    user:0 pendingSend:false time:{int(t.timestamp() * 1000)} = {t.strftime(fmt)} = "
                         "+1h0m0s0ms")
        return "\n".join(lines + ["", "  Pending user blocked background alarms: ", "    none", ""]) + "\n"
    return ""


def _intent(args: list[str]) -> dict:
    out = {"extras": {}, "action": None, "data": None, "target": None}
    i = 0
    while i < len(args):
        a = args[i]
        if a == "-a":
            out["action"] = args[i + 1]; i += 2
        elif a == "-d":
            out["data"] = args[i + 1]; i += 2
        elif a in ("-t", "-c", "-f", "--user"):
            i += 2
        elif a == "-n":
            out["target"] = args[i + 1]; i += 2
        elif a in ("--ei", "--es", "--ez", "--el"):
            out["extras"][args[i + 1]] = args[i + 2]; i += 3
        elif a.startswith("-"):
            i += 1
        else:
            out["target"] = a; i += 1
    return out


def tool_am(args: list[str]) -> str:
    con = _con()
    if args[0] == "set-debug-app":
        return ""
    if args[0] != "start":
        raise Exit(1, f"am: unknown {args}")
    it = _intent(args[1:])
    action = it["action"]
    if action == "android.intent.action.SET_ALARM":
        if not _root():
            return ("Starting: Intent { act=android.intent.action.SET_ALARM }\nSecurity exception: Permission "
                    "Denial: starting Intent { act=android.intent.action.SET_ALARM } requires "
                    "com.android.alarm.permission.SET_ALARM\n")
        ex = it["extras"]
        con.execute("INSERT INTO alarms (hour, minutes) VALUES (?, ?)",
                    (int(ex["android.intent.extra.alarm.HOUR"]), int(ex.get("android.intent.extra.alarm.MINUTES", 0))))
    elif action == "android.intent.action.CALL":
        _set_meta(con, "call", (it["data"] or "").removeprefix("tel:"))
    elif action == "android.intent.action.VIEW" and (it["data"] or "").startswith("http"):
        _set_meta(con, "chrome_url", it["data"])
    con.commit()
    return f"Starting: Intent {{ act={action} }}\nStatus: ok\n"


def tool_input(args: list[str]) -> str:
    con = _con()
    if args[:1] == ["keyevent"]:
        key = args[1]
        if key == "KEYCODE_ENDCALL":
            number = _get_meta(con, "call")
            if number:
                con.execute("INSERT INTO calls (number, type, date, duration, new) VALUES (?, 2, ?, 8, 0)",
                            (number, _now_ms()))
                _set_meta(con, "call", None)
        elif key == "KEYCODE_CAMERA":
            import io

            from PIL import Image, ImageDraw

            folder = Path(os.environ["SIM_ROOT"]) / "sdcard/DCIM/Camera"
            folder.mkdir(parents=True, exist_ok=True)
            img = Image.new("RGB", (1280, 960), "#3b5b7a")
            ImageDraw.Draw(img).text((20, 20), str(time.time()), fill="white")
            buf = io.BytesIO()
            img.save(buf, "JPEG", quality=90)
            n = len(list(folder.glob("IMG_*.jpg")))
            (folder / f"IMG_20231015_1534{n:02d}.jpg").write_bytes(buf.getvalue())
    con.commit()
    return ""


def tool_pm(args: list[str]) -> str:
    con = _con()
    if args[0] == "clear":
        pkg = args[1]
        if pkg == "com.android.providers.contacts":
            con.execute("DELETE FROM raw_contacts")
            con.execute("DELETE FROM data")
            con.execute("DELETE FROM sqlite_sequence WHERE name IN ('raw_contacts', 'data')")
        elif pkg == "com.google.android.deskclock":
            con.execute("DELETE FROM alarms")
        con.commit()
        return "Success\n"
    return ""


def tool_appops(args: list[str]) -> str:
    con = _con()
    rest = [a for a in args[1:] if a != "--uid"]
    if args[0] == "set" and len(rest) == 3:
        _set_meta(con, f"appop:{rest[0]}:{rest[1]}", rest[2])
    return ""


def tool_wm(args: list[str]) -> str:
    con = _con()
    if args[0] == "density":
        _put(con, "secure", "display_density_forced", "" if args[1] == "reset" else args[1])
        con.commit()
    return ""


def tool_getprop(args: list[str]) -> str:
    return (TZ if args and args[0] == "persist.sys.timezone" else "") + "\n"


def tool_screencap(args: list[str]) -> str:
    if args[:1] == ["-p"] and len(args) > 1:
        import io

        from PIL import Image

        buf = io.BytesIO()
        Image.new("RGB", (1080, 2400), "#202124").save(buf, "PNG")
        Path(args[1]).write_bytes(buf.getvalue())
    return ""


def tool_sleep(args: list[str]) -> str:
    time.sleep(min(float(args[0] or 0), 0.05) if args else 0)
    return ""


# `content`: AOSP cmds/content/.../Content.java
def _binds(args: list[str]) -> dict:
    out = {}
    for i, a in enumerate(args):
        if a == "--bind":
            col, typ, val = args[i + 1].split(":", 2)
            out[col] = None if typ == "n" else int(val) if typ in "il" else float(val) if typ in "fd" else \
                (val.lower() == "true") if typ == "b" else val
    return out


def _opt(args: list[str], name: str) -> str | None:
    return args[args.index(name) + 1] if name in args else None


URI = re.compile(r"^content://([^/?]+)(/[^?]*)?(\?.*)?$")


def _route(uri: str) -> tuple[str, str, dict, str]:
    """(table to write, view to read, fixed values, extra where) of a content URI."""
    m = URI.match(uri)
    if not m:
        raise Exit(1, f"Error while accessing provider: bad uri {uri}")
    auth, path, query = m.group(1), (m.group(2) or "").strip("/"), m.group(3) or ""
    if auth == "com.android.contacts" and path == "raw_contacts":
        return "raw_contacts", "raw_contacts_v", {}, ""
    if auth == "com.android.contacts" and path == "data":
        return "data", "data", {}, ""
    if auth == "sms":
        types = {"inbox": 1, "sent": 2, "draft": 3, "outbox": 4}
        if path in types:
            return "sms", "sms", {"type": types[path]}, f"type = {types[path]}"
        return "sms", "sms", {}, ""
    if auth == "call_log" and path == "calls":
        return "calls", "calls", {}, ""
    if auth == "com.android.calendar" and path == "calendars":
        return "calendars", "calendars", {"_syncadapter": "caller_is_syncadapter=true" in query}, ""
    if auth == "com.android.calendar" and path == "events":
        return "events", "events", {}, ""
    raise Exit(1, f"Error while accessing provider:{auth} java.lang.IllegalArgumentException: Unknown URL {uri}")


def _format_rows(rows: list[sqlite3.Row], cols: list[str]) -> str:
    if not rows:
        return "No result found.\n"
    out = []
    for n, r in enumerate(rows):
        vals = []
        for c in cols:
            v = r[c]
            vals.append(f"{c}={'NULL' if v is None else v}")
        out.append(f"Row: {n} " + ", ".join(vals))
    return "\n".join(out) + "\n"


def tool_content(args: list[str]) -> str:
    con = _con()
    verb, uri = args[0], _opt(args, "--uri")
    table, view, fixed, extra = _route(uri)
    if table == "calls" and not _root():
        raise Exit(1, "Error while accessing provider:call_log java.lang.SecurityException: Permission Denial: "
                      "opening provider com.android.providers.contacts.CallLogProvider requires "
                      "android.permission.READ_CALL_LOG or android.permission.WRITE_CALL_LOG")
    where = _opt(args, "--where")
    conds = " AND ".join(f"({c})" for c in (where, extra) if c) or "1"
    if verb == "query":
        proj = (_opt(args, "--projection") or "").split(":") if "--projection" in args else None
        cols = proj or [d[1] for d in con.execute(f"PRAGMA table_info({view})")]
        sort = _opt(args, "--sort") or "_id"
        rows = con.execute(f"SELECT {', '.join(cols)} FROM {view} WHERE {conds} ORDER BY {sort}").fetchall()
        return _format_rows(rows, cols)
    if table == "sms" and verb in ("insert", "update", "delete"):
        who = "root" if _root() else "com.android.shell"
        if _get_meta(con, f"appop:{who}:WRITE_SMS") != "allow":
            return ""   # MODE_IGNORED: the provider fakes success and writes nothing
    if verb == "insert":
        values = {**_binds(args)}
        if table == "calendars":
            if not fixed.pop("_syncadapter"):
                raise Exit(1, "Error while accessing provider:com.android.calendar java.lang.IllegalArgumentException"
                              ": only sync adapters may insert calendars")
        elif table == "sms":
            values = {**values, **fixed}
            values.setdefault("type", 1)
            values.setdefault("date", _now_ms())
            if values["type"] == 3:   # SmsProvider: a new draft replaces the thread's draft
                con.execute("DELETE FROM sms WHERE type = 3 AND address = ?", (values.get("address"),))
        elif table == "events":
            missing = [c for c in ("calendar_id", "dtstart", "eventTimezone") if values.get(c) is None]
            if missing:
                raise Exit(1, f"Error while accessing provider:com.android.calendar java.lang."
                              f"IllegalArgumentException: {missing[0]} is required")
        cols = list(values)
        con.execute(f"INSERT INTO {table} ({', '.join(cols) or '_id'}) VALUES "
                    f"({', '.join('?' for _ in cols) or 'NULL'})", [values[c] for c in cols])
    elif verb == "update":
        values = _binds(args)
        con.execute(f"UPDATE {table} SET {', '.join(f'{c} = ?' for c in values)} WHERE _id IN "
                    f"(SELECT _id FROM {view} WHERE {conds})", list(values.values()))
    elif verb == "delete":
        ids = [r[0] for r in con.execute(f"SELECT _id FROM {view} WHERE {conds}")]
        marks = ",".join(str(i) for i in ids) or "NULL"
        if table == "events":   # not a sync adapter: the row is marked deleted, the sync adapter removes it
            con.execute(f"UPDATE events SET deleted = 1 WHERE _id IN ({marks})")
        else:
            con.execute(f"DELETE FROM {table} WHERE _id IN ({marks})")
            if table == "raw_contacts":
                con.execute(f"DELETE FROM data WHERE raw_contact_id IN ({marks})")
    else:
        raise Exit(1, f"content: unknown verb {verb}")
    con.commit()
    return ""


def main(argv: list[str]) -> int:
    tool, args = argv[0], argv[1:]
    try:
        out = globals()[f"tool_{tool}"](args)
    except Exit as exc:
        sys.stderr.write(exc.err + "\n")
        return exc.code
    sys.stdout.write(out)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
