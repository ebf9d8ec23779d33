"""`AdbDevice`: an Android device (emulator, phone, redroid) behind an adb serial, serving the `Device` protocol.

Observation: `adb exec-out screencap` raw pixels encoded to PNG on the host (`screencap.py`); the accessibility
tree from `uiautomator dump` into a file under /data/local/tmp that is then `cat` in the same `exec-out`
(`uiautomator.py`), retried when the UI does not go idle. Actions: `commands.py`. Files: `adb push`/`pull`.
Commands: `adb shell` with the exit status kept (`adb.py`). Apps: `am start -W`, `monkey` for a package's launcher
activity, then the focused window from `dumpsys window` until it is the app's. State for evaluators:
`settings get/put`, `content query` rows as dicts, and app SQLite databases pulled with root (`adb root` on
userdebug builds such as the google_apis emulator images) and read with Python's sqlite3 on the host.
"""

from __future__ import annotations

import json
import mimetypes
import posixpath
import shlex
import sqlite3
import tempfile
import time
from pathlib import Path

from jarvis_pytest.devices import actions as A
from jarvis_pytest.devices.android import commands as C
from jarvis_pytest.devices.android import outputs, screencap, uiautomator
from jarvis_pytest.devices.android.adb import Adb
from jarvis_pytest.devices.base import ActionOutcome, CommandResult, Observation
from jarvis_pytest.errors import InfrastructureError

PLATFORM = "android"
DUMP_PATH = "/data/local/tmp/jarvis_window_dump.xml"
DUMP_ATTEMPTS = 3
DUMP_TIMEOUT = 30.0           # uiautomator waits up to 10 s for idle before giving up
LAUNCH_WINDOW_WAIT = 20.0
ACTION_TIMEOUT = 60.0
ANIMATION_SETTINGS = ("window_animation_scale", "transition_animation_scale", "animator_duration_scale")
q = shlex.quote


class AdbDevice:
    """One Android device reached through our adb server by its serial."""

    platform = PLATFORM

    def __init__(self, serial: str, adb: Adb | None = None):
        self.serial = serial
        self.adb = (adb or Adb()).for_serial(serial)
        self._sdk: int | None = None
        self._input: C.InputState | None = None
        self._root: bool | None = None

    def __repr__(self) -> str:
        return f"AdbDevice({self.serial!r})"

    # -- facts -------------------------------------------------------------------------------------------------
    @property
    def sdk(self) -> int:
        """The device's API level (`ro.build.version.sdk`)."""
        if self._sdk is None:
            raw = self.adb.getprop("ro.build.version.sdk")
            if not raw.isdigit():
                raise InfrastructureError(f"android device {self.serial}: cannot read its SDK level ({raw!r})")
            self._sdk = int(raw)
        return self._sdk

    def screen_size(self) -> tuple[int, int]:
        """The screen in its current orientation, as `input` coordinates and screenshots use it (from the raw
        screencap header: the frame is taken on the device, 16 bytes cross the wire)."""
        head = self.adb.exec_out("screencap 2>/dev/null | head -c 16", timeout=20)
        if len(head) >= 12:
            import struct

            w, h, fmt = struct.unpack_from("<III", head, 0)
            if fmt in screencap.PIXEL_FORMATS and 0 < w <= screencap.MAX_SIDE and 0 < h <= screencap.MAX_SIDE:
                return w, h
        size = outputs.wm_size(self._sh("wm size").stdout)
        if not size:
            raise InfrastructureError(f"android device {self.serial}: cannot read the screen size")
        return size

    def input_state(self) -> C.InputState:
        if self._input is None:
            w, h = self.screen_size()
            installed = self.package_installed(C.IME_PACKAGE)
            active = installed and (self.settings_get("secure", "default_input_method") or "") == C.IME_ID
            self._input = C.InputState(width=w, height=h, sdk=self.sdk, ime_installed=installed, ime_active=active)
        return self._input

    # -- set-up ------------------------------------------------------------------------------------------------
    def prepare(self) -> None:
        """Make the device fit for agents: animations off (uiautomator then finds the UI idle), screen awake and
        unlocked, and the ADBKeyBoard IME selected where it is installed (exact non-ASCII typing)."""
        lines = [f"settings put global {k} 0" for k in ANIMATION_SETTINGS]
        lines += ["svc power stayon true", "input keyevent KEYCODE_WAKEUP", "wm dismiss-keyguard"]
        r = self._sh("; ".join(lines), timeout=60)
        if r.returncode != 0:
            raise InfrastructureError(f"android device {self.serial}: set-up failed: {r.stdout} {r.stderr}")
        self._input = None
        state = self.input_state()
        if state.ime_installed and not state.ime_active:
            self._sh("; ".join(C.ime_activation_commands()))
            state.ime_active = True

    # -- observation -------------------------------------------------------------------------------------------
    def screenshot(self) -> tuple[bytes, int, int]:
        """(PNG, width, height) of the screen."""
        raw = self.adb.exec_out("screencap 2>/dev/null", timeout=30)
        try:
            shot = screencap.parse(raw, self.sdk)
        except screencap.UnsupportedFormat:
            png = self.adb.exec_out("screencap -p 2>/dev/null", timeout=60)
            if not png.startswith(b"\x89PNG"):
                raise InfrastructureError(f"android device {self.serial}: screencap -p returned no PNG") from None
            return png, int.from_bytes(png[16:20], "big"), int.from_bytes(png[20:24], "big")
        if self._input is not None:  # the screen may have rotated since: actions use what the agent sees
            self._input.width, self._input.height = shot.width, shot.height
        return screencap.to_png(shot), shot.width, shot.height

    def a11y_tree(self, max_nodes: int = uiautomator.MAX_NODES) -> dict:
        """The accessibility tree; retried while uiautomator reports no idle state or no root node. After the
        last attempt, `tree` is None and `error` says why."""
        errors: list[str] = []
        t0 = time.perf_counter()
        cmd = f"rm -f {DUMP_PATH}; uiautomator dump {DUMP_PATH} 2>&1; cat {DUMP_PATH} 2>/dev/null"
        for attempt in range(DUMP_ATTEMPTS):
            raw = self.adb.exec_out(cmd, timeout=DUMP_TIMEOUT).decode("utf-8", "replace")
            tree, errs = uiautomator.parse_output(raw, max_nodes=max_nodes)
            errors += errs
            if tree is not None and tree["nodes"]:
                tree["elapsed_ms"] = round((time.perf_counter() - t0) * 1000, 1)
                if errs:
                    tree["warnings"] = errs
                return tree
            if not errs:
                errors.append(f"uiautomator dump printed no XML: {raw.strip()[:200]!r}")
            time.sleep(0.5 * (attempt + 1))
        return {"tree": None, "nodes": 0, "truncated": True, "error": "; ".join(dict.fromkeys(errors)),
                "elapsed_ms": round((time.perf_counter() - t0) * 1000, 1)}

    def observe(self, *, a11y: bool = False) -> Observation:
        png, w, h = self.screenshot()
        tree = json.dumps(self.a11y_tree(), ensure_ascii=False) if a11y else None
        return Observation(platform=PLATFORM, screenshot_png=png, width=w, height=h, a11y_tree=tree)

    # -- actions -----------------------------------------------------------------------------------------------
    def act(self, action: A.Action) -> ActionOutcome:
        t0 = time.perf_counter()
        try:
            lines = C.commands_for(action, self.input_state())
        except C.Unsupported as exc:
            return ActionOutcome(ok=False, error=str(exc), elapsed_ms=(time.perf_counter() - t0) * 1000)
        if action.type == "WAIT":
            time.sleep(action.seconds)
        error = None
        if lines:
            r = self._sh(" && ".join(lines), timeout=ACTION_TIMEOUT)
            error = action_error(r.returncode, r.stdout + r.stderr)
        return ActionOutcome(ok=error is None, error=error, elapsed_ms=(time.perf_counter() - t0) * 1000)

    # -- files and commands ------------------------------------------------------------------------------------
    def upload(self, path: str, data: bytes) -> None:
        self._sh(f"mkdir -p {q(posixpath.dirname(path) or '/')}")
        with tempfile.TemporaryDirectory(prefix="jarvis-adb-") as tmp:
            local = Path(tmp) / "upload"
            local.write_bytes(data)
            self.adb.push(local, path)

    def download(self, path: str) -> bytes:
        with tempfile.TemporaryDirectory(prefix="jarvis-adb-") as tmp:
            local = Path(tmp) / "download"
            self.adb.pull(path, local)
            return local.read_bytes()

    def run(self, command: str, *, timeout: float = 60.0, user: str | None = None) -> CommandResult:
        """`command` in the device's `sh` as the shell user, or as root (`user="root"`: adbd as root where the
        build allows it, else `su 0`)."""
        if user in (None, "", "shell"):
            r = self.adb.shell(command, timeout=timeout)
        elif user == "root":
            r = self.adb.shell(command if self.has_root() else f"su 0 sh -c {q(command)}", timeout=timeout)
        else:
            raise InfrastructureError(f"android device: cannot run commands as user {user!r} (shell or root)")
        return CommandResult(returncode=r.returncode, stdout=r.stdout, stderr=r.stderr)

    def exists(self, path: str) -> bool:
        r = self._sh(f"test -e {q(path)}")
        if r.returncode not in (0, 1):
            raise InfrastructureError(f"android device {self.serial}: test -e {path} failed: {r.stderr}")
        return r.returncode == 0

    # -- apps --------------------------------------------------------------------------------------------------
    def focused(self) -> tuple[str, str] | None:
        """(package, activity) of the focused window."""
        r = self._sh("dumpsys window | grep -E 'mCurrentFocus|mFocusedApp'", timeout=20)
        return outputs.focused_activity(r.stdout)

    def launch(self, app: str, *args: str, window_wait: float = LAUNCH_WINDOW_WAIT) -> bool:
        """Start `app` (a package, or `package/activity`) with `am start` options `args`; True once its window
        has focus, False after `window_wait` s."""
        component = app if "/" in app else self.launcher_activity(app)
        package = app.split("/", 1)[0]
        if component:
            r = self._sh(f"am start -W -n {q(component)} " + " ".join(q(a) for a in args), timeout=60)
            err = outputs.am_start_error(r.stdout + r.stderr)
            if err or r.returncode != 0:
                raise InfrastructureError(f"android device {self.serial}: cannot start {app}: "
                                          f"{err or (r.stdout + r.stderr).strip()[:300]}")
        else:
            r = self._sh(f"monkey -p {q(package)} -c android.intent.category.LAUNCHER 1", timeout=60)
            if r.returncode != 0 or "Events injected: 1" not in r.stdout:
                raise InfrastructureError(f"android device {self.serial}: no launchable app {app!r}: "
                                          f"{(r.stdout + r.stderr).strip()[-300:]}")
        return self._wait_focus(lambda f: f is not None and f[0] == package, window_wait)

    def launcher_activity(self, package: str) -> str | None:
        r = self._sh(f"cmd package resolve-activity --brief -a android.intent.action.MAIN "
                     f"-c android.intent.category.LAUNCHER {q(package)}", timeout=30)
        return outputs.resolved_activity(r.stdout) if r.returncode == 0 else None

    def open(self, path: str, *, window_wait: float = LAUNCH_WINDOW_WAIT) -> bool:
        """Open a file (VIEW intent with its MIME type) or a folder (the Files app) with the default app; True
        once another window has focus."""
        before = self.focused()
        if self._sh(f"test -d {q(path)}").returncode == 0:
            rel = path
            for root in ("/sdcard/", "/storage/emulated/0/"):
                if path.startswith(root):
                    rel = path[len(root):]
            doc = "primary%3A" + rel.strip("/").replace("/", "%2F")
            cmd = (f"am start -W -a android.intent.action.VIEW -t vnd.android.document/directory "
                   f"-d {q('content://com.android.externalstorage.documents/document/' + doc)}")
        else:
            mime = mimetypes.guess_type(path)[0] or "*/*"
            cmd = (f"am start -W -a android.intent.action.VIEW --grant-read-uri-permission "
                   f"-d {q('file://' + path)} -t {q(mime)}")
        r = self._sh(cmd, timeout=60)
        err = outputs.am_start_error(r.stdout + r.stderr)
        if err or r.returncode != 0:
            raise InfrastructureError(f"android device {self.serial}: cannot open {path}: "
                                      f"{err or (r.stdout + r.stderr).strip()[:300]}")
        return self._wait_focus(lambda f: f is not None and f != before, window_wait)

    def _wait_focus(self, ok, window_wait: float) -> bool:
        deadline = time.monotonic() + window_wait
        while True:
            if ok(self.focused()):
                return True
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.3)

    def package_installed(self, package: str) -> bool:
        r = self._sh(f"pm list packages {q(package)}", timeout=30)
        return f"package:{package}" in r.stdout.split()

    def go_home(self) -> None:
        self._sh("input keyevent KEYCODE_HOME")

    # -- state for evaluators ----------------------------------------------------------------------------------
    def settings_get(self, namespace: str, key: str) -> str | None:
        """`settings get <system|secure|global> key`; None when unset."""
        r = self._sh(f"settings get {q(namespace)} {q(key)}", timeout=30)
        if r.returncode != 0:
            raise InfrastructureError(f"android device {self.serial}: settings get {namespace} {key}: {r.stderr}")
        return outputs.settings_value(r.stdout)

    def settings_put(self, namespace: str, key: str, value: str) -> None:
        r = self._sh(f"settings put {q(namespace)} {q(key)} {q(value)}", timeout=30)
        if r.returncode != 0:
            raise InfrastructureError(f"android device {self.serial}: settings put {namespace} {key}: {r.stderr}")

    def content_query(self, uri: str, projection: list[str] | None = None, where: str | None = None,
                      sort: str | None = None) -> list[dict[str, str | None]]:
        """`content query --uri ...` rows as dicts (values as text, SQL NULL as None)."""
        cmd = f"content query --uri {q(uri)}"
        if projection:
            cmd += f" --projection {q(':'.join(projection))}"
        if where:
            cmd += f" --where {q(where)}"
        if sort:
            cmd += f" --sort {q(sort)}"
        r = self._sh(cmd, timeout=60)
        text = r.stdout + r.stderr
        if r.returncode != 0 or "Error while accessing provider" in text or "Exception" in r.stderr:
            raise InfrastructureError(f"android device {self.serial}: content query {uri} failed: "
                                      f"{text.strip()[:500]}")
        return outputs.parse_content_rows(r.stdout, projection)

    def has_root(self) -> bool:
        """Whether adbd runs as root (restarting it as root where the build allows)."""
        if self._root is None:
            self._root = self._sh("id -u").stdout.strip() == "0" or self.adb.root()
        return self._root

    def pull_app_file(self, package: str, relative: str, local: Path) -> None:
        """Copy `/data/data/<package>/<relative>` to `local`: with root, else `run-as` (debuggable apps)."""
        src = f"/data/data/{package}/{relative}"
        if self.has_root():
            self.adb.pull(src, local)
            return
        data = self.adb.exec_out(f"run-as {q(package)} cat {q(relative)} 2>/dev/null")
        if not data:
            raise InfrastructureError(f"android device {self.serial}: reading {src} needs root (`adb root`, "
                                      "userdebug/eng builds such as the google_apis emulator images) or a "
                                      "debuggable app; this device allows neither")
        local.write_bytes(data)

    def query_database(self, package: str, database: str, sql: str, params: tuple = ()) -> list[dict]:
        """Rows of `sql` on the app's SQLite database `databases/<database>` (its -wal and -journal files with
        it, so recent writes are seen), read on the host."""
        with tempfile.TemporaryDirectory(prefix="jarvis-db-") as tmp:
            local = Path(tmp) / database
            self.pull_app_file(package, f"databases/{database}", local)
            for suffix in ("-wal", "-journal"):
                rel = f"databases/{database}{suffix}"
                probe = f"/data/data/{package}/{rel}"
                if self.has_root() and self._sh(f"test -e {q(probe)}").returncode == 0:
                    self.pull_app_file(package, rel, Path(tmp) / f"{database}{suffix}")
            con = sqlite3.connect(str(local))
            try:
                con.row_factory = sqlite3.Row
                return [dict(row) for row in con.execute(sql, params)]
            finally:
                con.close()

    def reverse(self, device_port: int, host_port: int) -> None:
        """Let the device reach this machine's 127.0.0.1:host_port at its own 127.0.0.1:device_port."""
        self.adb.reverse(device_port, host_port)

    def close(self) -> None:
        """Nothing to release: the adb server keeps no per-client state."""

    # -- helpers -----------------------------------------------------------------------------------------------
    def _sh(self, command: str, timeout: float = 60.0):
        return self.adb.shell(command, timeout=timeout)


def action_error(returncode: int, output: str) -> str | None:
    """Why the commands of an action failed (None: they did not). `input`/`am` print errors and often still
    exit 0, so their output is read too."""
    for line in output.splitlines():
        s = line.strip()
        if s.startswith(("Error:", "Exception", "java.lang.", "Usage: input", "usage: input")) or \
                "Exception occurred" in s or s.startswith("Security exception"):
            return s[:300]
    if returncode != 0:
        return f"command failed with exit status {returncode}: {output.strip()[:300]}"
    return None
