"""The Android device over ADB, without an Android device (none can run on this machine: no system image, no
binder in the kernel).

What runs for real: Debian's `adb` binary (its server on a port of its own on 127.0.0.1, `adb devices`, `adb
connect` to a refused and to a silent port, commands killed at their deadline); the shell command lines of every
typing path through real shells (`sh` = dash, and `mksh`, Android's `/system/bin/sh`), with the argument
decoding of AOSP's `input text` applied to what the shell hands over; the drive upload/download commands through
mksh and toybox's `nc` against an HTTP server on 127.0.0.1. What runs on recorded data: the uiautomator parser on
dumps taken from real devices by public projects (tests/data/android/README.md), the focused-window parser on a
recorded `dumpsys window`. What runs on data built from AOSP's own definitions: screencap frames with the header
each Android version writes, `content query` rows. Tests that need a device use `ReplayAdb`, a fake *device*
that replays recorded or AOSP-format outputs (never a fake adb binary).
"""

from __future__ import annotations

import base64
import http.server
import io
import json
import os
import re
import shutil
import socket
import socketserver
import struct
import subprocess
import threading
import time
from pathlib import Path

import pytest
from PIL import Image

from jarvis_pytest.devices import actions as A
from jarvis_pytest.devices.android import adb as adbmod
from jarvis_pytest.devices.android import backend as B
from jarvis_pytest.devices.android import commands as C
from jarvis_pytest.devices.android import image as I
from jarvis_pytest.devices.android import outputs, screencap, uiautomator
from jarvis_pytest.devices.android.adb import Adb, ShellResult, unwrap_shell, wrap_shell
from jarvis_pytest.devices.android.device import AdbDevice, action_error
from jarvis_pytest.devices.android.http import get_command, put_command
from jarvis_pytest.devices.platforms import spec
from jarvis_pytest.errors import InfrastructureError

DATA = Path(__file__).parent / "data" / "android"
DUMPS = sorted((DATA / "uiautomator").glob("*.xml"))
MKSH = shutil.which("mksh")
TOYBOX = shutil.which("toybox")
SHELLS = [pytest.param("sh", id="dash")] + [
    pytest.param(MKSH, id="mksh") if MKSH else
    pytest.param("mksh", id="mksh", marks=pytest.mark.skip(reason="mksh not installed: apt-get install mksh"))]
HARD_TEXTS = [
    "hello world", "  leading and trailing  ", "it's \"quoted\" & done; a|b $HOME `id` $(id)",
    "()<>|;&*\\~\"'$`", "100%sure", "%s", "%%s", "a%%%sb%s", "ends with %", "s%", "-n", "--", "-e foo",
    "tab\there", "two\nlines\n", "\\n is not a newline", "!#{}[]^?=+,.:/@",
]
NON_ASCII = ["Grüße, 東京 ✓", "emoji 😸 + ZWJ 👩‍💻", "עברית right-to-left", "e\u0301 combining", "日本語" * 2000]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# -- the real adb binary ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def adb_port():
    """Our own adb server on a free port of 127.0.0.1 for this module (killed afterwards: only this one)."""
    port = free_port()
    mp = pytest.MonkeyPatch()
    mp.setenv("JARVIS_ADB_SERVER_PORT", str(port))
    try:
        yield port
    finally:
        try:
            Adb(port=port).kill_server()
        finally:
            mp.undo()


def listeners(port: int) -> set[str]:
    """Local addresses listening on `port` (from /proc/net/tcp{,6})."""
    found = set()
    for name in ("/proc/net/tcp", "/proc/net/tcp6"):
        try:
            lines = Path(name).read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            local, state = line.split()[1], line.split()[3]
            addr, hexport = local.rsplit(":", 1)
            if state == "0A" and int(hexport, 16) == port:
                found.add(addr)
    return found


def test_adb_server_starts_on_its_own_port_on_loopback_only(adb_port):
    Adb(port=adb_port).ensure_server()
    addrs = listeners(adb_port)
    assert addrs, f"no adb server listens on port {adb_port}"
    assert addrs <= {"0100007F", "00000000000000000000000001000000"}, f"adb listens beyond loopback: {addrs}"
    with socket.create_connection(("127.0.0.1", adb_port), timeout=2):
        pass


def test_adb_devices_lists_nothing_here(adb_port):
    assert Adb(port=adb_port).devices() == {}


def test_adb_connect_to_a_refused_port_is_a_clear_error_at_once(adb_port):
    closed = free_port()
    t0 = time.monotonic()
    with pytest.raises(InfrastructureError, match=rf"could not connect to 127\.0\.0\.1:{closed}.*refused"):
        Adb(port=adb_port).connect(f"127.0.0.1:{closed}")
    assert time.monotonic() - t0 < 5
    assert f"127.0.0.1:{closed}" not in Adb(port=adb_port).devices()  # the half-made transport is dropped


def test_adb_connect_to_a_silent_listener_ends_at_its_deadline(adb_port):
    """A port that accepts and never speaks adb makes `adb connect` wait ~10 s by itself; ours ends at 1.5 s."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(4)
    port = srv.getsockname()[1]
    try:
        t0 = time.monotonic()
        with pytest.raises(InfrastructureError, match=r"did not finish within 1\.5 s"):
            Adb(port=adb_port).connect(f"127.0.0.1:{port}", timeout=1.5)
        assert time.monotonic() - t0 < 4
    finally:
        srv.close()
    assert Adb(port=adb_port).devices().get(f"127.0.0.1:{port}") != "device"


def test_a_stuck_adb_command_is_killed_at_its_deadline(adb_port):
    """`adb wait-for-device` on a serial that never comes waits forever by itself."""
    t0 = time.monotonic()
    with pytest.raises(InfrastructureError, match=r"wait-for-device.*did not finish within 1 s"):
        Adb(serial=f"127.0.0.1:{free_port()}", port=adb_port).call("wait-for-device", timeout=1)
    assert time.monotonic() - t0 < 3


def test_shell_and_readiness_on_a_missing_device_are_infrastructure_errors(adb_port):
    serial = f"127.0.0.1:{free_port()}"
    with pytest.raises(InfrastructureError, match="not found"):
        Adb(serial=serial, port=adb_port).shell("echo hi")
    assert Adb(serial=serial, port=adb_port).state() == "missing"
    t0 = time.monotonic()
    with pytest.raises(InfrastructureError, match=r"refused"):
        B.wait_ready(f"adb://{serial}", 1.0)       # one readiness check, as wait_until_ready calls it
    with pytest.raises(InfrastructureError, match=r"not online after 2 s"):
        Adb(serial=serial, port=adb_port).wait_online(2.0)
    assert time.monotonic() - t0 < 8


def test_a_missing_adb_binary_says_how_to_get_one(monkeypatch):
    monkeypatch.setenv("JARVIS_ADB", "/nonexistent/adb")
    with pytest.raises(InfrastructureError, match=r"apt-get install adb"):
        Adb()
    assert "apt-get install adb" in B.ATTACH.unavailable()
    assert "apt-get install adb" in B.EMULATOR.unavailable()


def test_the_adb_command_line_always_names_port_and_serial(adb_port):
    argv = Adb(serial="emulator-5554", port=adb_port).argv("shell", "echo 'a b'")
    assert argv[1:] == ["-P", str(adb_port), "-s", "emulator-5554", "shell", "echo 'a b'"]
    assert Path(argv[0]).name == "adb"


# -- command lines through real shells -------------------------------------------------------------------------
def sendtext_decode(arg: str) -> str:
    """AOSP `InputShellCommand.sendText` (and the older `Input.java`): `%s` becomes a space, scanning left to
    right (a port of its loop, to apply to what the shell hands `input`)."""
    buff = list(arg)
    escape = False
    i = 0
    while i < len(buff):
        if escape:
            escape = False
            if buff[i] == "s":
                buff[i] = " "
                i -= 1
                del buff[i]
        if buff[i] == "%":
            escape = True
        i += 1
    return "".join(buff)


def run_in_shell(shell: str, script: str, tmp_path: Path) -> list[list[str]]:
    """Run `script` in a real shell with `input`, `am` and `ime` as functions recording their arguments
    exactly as the shell passes them; returns one argv list per call."""
    prelude = ("input() { printf '\\001input'; printf '\\002%s' \"$@\"; }; "
               "am() { printf '\\001am'; printf '\\002%s' \"$@\"; }; "
               "ime() { printf '\\001ime'; printf '\\002%s' \"$@\"; }; ")
    proc = subprocess.run([shell, "-c", prelude + script], capture_output=True, timeout=20)
    assert proc.returncode == 0, proc.stderr
    calls = []
    for chunk in proc.stdout.decode("utf-8").split("\x01")[1:]:
        name, *args = chunk.split("\x02")
        calls.append([name, *args])
    return calls


def typed_by(calls: list[list[str]]) -> str:
    """What the device would type for these `input`/`am` calls."""
    out = ""
    for name, *args in calls:
        if name == "input" and args[0] == "text":
            assert len(args) == 2, f"input text got {len(args)-1} arguments: {args}"
            assert " " not in args[1], "spaces travel as %s (what `adb shell input text` users rely on)"
            out += sendtext_decode(args[1])
        elif name == "input" and args[0] == "keyevent":
            out += {"KEYCODE_ENTER": "\n", "KEYCODE_TAB": "\t"}[args[1]]
        elif name == "am":
            assert args[:7] == ["broadcast", "-a", "ADB_INPUT_B64", "-p", C.IME_PACKAGE, "--es", "msg"]
            out += base64.b64decode(args[7]).decode("utf-8")
    return out


@pytest.mark.parametrize("shell", SHELLS)
def test_ascii_typing_round_trips_through_a_real_shell(shell, tmp_path):
    for text in HARD_TEXTS:
        cmds = C.commands_for(A.Typing(text=text), C.InputState(width=1080, height=2400))
        assert all(c.startswith("input ") for c in cmds), cmds
        assert typed_by(run_in_shell(shell, " && ".join(cmds), tmp_path)) == text, text


@pytest.mark.parametrize("shell", SHELLS)
def test_non_ascii_typing_goes_through_the_ime_exactly(shell, tmp_path):
    state = C.InputState(width=1080, height=2400, ime_installed=True, ime_active=True)
    for text in NON_ASCII:
        cmds = C.commands_for(A.Typing(text=text), state)
        assert typed_by(run_in_shell(shell, " && ".join(cmds), tmp_path)) == text
    assert len(C.commands_for(A.Typing(text=NON_ASCII[-1]), state)) > 1  # chunked


def test_non_ascii_typing_selects_the_ime_first_or_says_what_is_missing():
    cmds = C.commands_for(A.Typing(text="東京"), C.InputState(1080, 2400, ime_installed=True))
    assert cmds[:2] == [f"ime enable {C.IME_ID} >/dev/null", f"ime set {C.IME_ID} >/dev/null"]
    with pytest.raises(C.Unsupported, match="ADBKeyBoard"):
        C.commands_for(A.Typing(text="東京"), C.InputState(1080, 2400))


@pytest.mark.parametrize("shell", SHELLS)
def test_the_exit_status_survives_the_shell_wrapper(shell):
    """What `Adb.shell` sends: the command in a subshell, then a marker with `$?` (older adb shells lose it)."""
    cases = {"true": (0, b""), "false": (1, b""), "exit 3": (3, b""), "printf 'no newline'": (0, b"no newline"),
             "echo a; (exit 7)": (7, b"a\n"), "echo 'it''s'; echo \"$((6*7))\"": (0, b"its\n42\n"),
             "# a comment": (0, b""), "printf '%s' __JARVIS_RC_fake__": (0, b"__JARVIS_RC_fake__")}
    for command, (code, out) in cases.items():
        mark = "__JARVIS_RC_0123456789ab__"
        raw = subprocess.run([shell, "-c", wrap_shell(command, mark)], capture_output=True, timeout=10).stdout
        assert unwrap_shell(raw, mark) == (code, out), command
    assert unwrap_shell(b"error: closed", "__JARVIS_RC_x__") == (None, b"error: closed")


# -- the drive's upload and download commands (mksh + toybox nc, against 127.0.0.1) --------------------------
class _Drive(http.server.BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.0"
    files: dict[str, bytes] = {}

    def do_PUT(self):
        if self.headers.get("PW") != "agentPassword":
            self.send_response(401)
            self.end_headers()
            return
        self.files[self.path] = self.rfile.read(int(self.headers["Content-Length"]))
        self.send_response(201)
        self.end_headers()

    def do_GET(self):
        body = self.files.get(self.path)
        if self.headers.get("PW") != "agentPassword" or body is None:
            self.send_response(404)
            self.end_headers()
            return
        self.send_response(200)
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, *args):
        pass


@pytest.mark.skipif(not (MKSH and TOYBOX), reason="needs mksh and toybox (apt-get install mksh toybox)")
def test_drive_commands_move_bytes_exactly_with_toybox_nc(tmp_path):
    bindir = tmp_path / "bin"
    bindir.mkdir()
    for tool in ("nc", "stat", "cat", "printf"):  # what Android's toybox provides
        (bindir / tool).symlink_to(TOYBOX)
    srv = socketserver.ThreadingTCPServer(("127.0.0.1", 0), _Drive)
    threading.Thread(target=srv.serve_forever, daemon=True).start()
    env = {**os.environ, "PATH": f"{bindir}:/usr/bin:/bin"}
    try:
        url = f"http://127.0.0.1:{srv.server_address[1]}/data/report's file.bin"
        payload = bytes(range(256)) * 40 + b"\r\n\r\nHTTP/1.0 200 OK\r\n\x00tail"
        (tmp_path / "up.bin").write_bytes(payload)
        up = put_command(str(tmp_path / "up.bin"), url.replace(" ", "%20"), "agentPassword")
        r = subprocess.run([MKSH, "-c", up], env=env, capture_output=True, timeout=20)
        assert r.returncode == 0, r.stderr
        assert _Drive.files["/data/report's%20file.bin"] == payload
        down = get_command(url.replace(" ", "%20"), str(tmp_path / "down.bin"), "agentPassword")
        r = subprocess.run([MKSH, "-c", down], env=env, capture_output=True, timeout=20)
        assert r.returncode == 0, r.stderr
        assert (tmp_path / "down.bin").read_bytes() == payload
        missing = get_command(url.replace("report", "nothing").replace(" ", "%20"), str(tmp_path / "no.bin"),
                              "agentPassword")
        r = subprocess.run([MKSH, "-c", missing], env=env, capture_output=True, timeout=20)
        assert r.returncode != 0 and b"404" in r.stderr and not (tmp_path / "no.bin").exists()
        r = subprocess.run([MKSH, "-c", put_command(str(tmp_path / "up.bin"), url.replace(" ", "%20"), "wrong")],
                           env=env, capture_output=True, timeout=20)
        assert r.returncode != 0 and b"401" in r.stderr
    finally:
        srv.shutdown()
    assert "nc " in spec("android").drive_put_command("/sdcard/a.txt", "http://transfer:5244/data/a.txt", "pw")
    assert "nc " in spec("android").drive_get_command("http://transfer:5244/data/a.txt", "/sdcard/a.txt", "pw")


# -- screencap: frames built as AOSP's screencap.cpp writes them -----------------------------------------------
# 2x2 frames; (pixel format, bytes of the four pixels, the RGB a viewer sees)
FRAMES = {
    1: (bytes([255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255, 10, 20, 30, 128]),
        [(255, 0, 0), (0, 255, 0), (0, 0, 255), (10, 20, 30)]),                     # RGBA_8888
    2: (bytes([255, 0, 0, 0, 0, 255, 0, 7, 0, 0, 255, 9, 10, 20, 30, 0]),
        [(255, 0, 0), (0, 255, 0), (0, 0, 255), (10, 20, 30)]),                     # RGBX_8888
    3: (bytes([255, 0, 0, 0, 255, 0, 0, 0, 255, 10, 20, 30]),
        [(255, 0, 0), (0, 255, 0), (0, 0, 255), (10, 20, 30)]),                     # RGB_888
    4: (struct.pack("<4H", 0xF800, 0x07E0, 0x001F, 0xFFFF),
        [(255, 0, 0), (0, 255, 0), (0, 0, 255), (255, 255, 255)]),                 # RGB_565
    5: (bytes([0, 0, 255, 255, 0, 255, 0, 255, 255, 0, 0, 255, 30, 20, 10, 255]),
        [(255, 0, 0), (0, 255, 0), (0, 0, 255), (10, 20, 30)]),                     # BGRA_8888
}


def frame(fmt: int, sdk: int, colorspace: int = 1) -> bytes:
    pixels = FRAMES[fmt][0]
    if sdk >= 26:   # screencap.cpp since Android 8.0: w, h, f, c
        return struct.pack("<IIII", 2, 2, fmt, colorspace) + pixels
    return struct.pack("<III", 2, 2, fmt) + pixels   # Android 7.x and older: w, h, f


@pytest.mark.parametrize("sdk", [21, 25, 26, 28, 33, 35])
@pytest.mark.parametrize("fmt", sorted(FRAMES))
def test_screencap_frames_of_each_android_version_decode_to_the_right_pixels(sdk, fmt):
    assert screencap.header_size(sdk) == (16 if sdk >= 26 else 12)
    shot = screencap.parse(frame(fmt, sdk), sdk)
    assert (shot.width, shot.height, shot.pixel_format) == (2, 2, fmt)
    assert shot.header_size == (16 if sdk >= 26 else 12)
    assert shot.colorspace == (1 if sdk >= 26 else None)
    img = Image.open(io.BytesIO(screencap.to_png(shot)))
    assert img.mode == "RGB" and img.size == (2, 2)
    assert [img.getpixel((i % 2, i // 2)) for i in range(4)] == FRAMES[fmt][1]
    assert screencap.parse(frame(fmt, sdk)).header_size == shot.header_size  # SDK unknown: from the length


def test_screencap_rejects_what_is_not_a_frame():
    assert screencap.parse(frame(1, 25), 33).header_size == 12   # the length decides, not the SDK's guess
    assert screencap.parse(frame(1, 33), 25).header_size == 16
    with pytest.raises(InfrastructureError, match="truncated"):
        screencap.parse(frame(1, 33)[:-3], 33)
    with pytest.raises(InfrastructureError, match="not a raw frame"):
        screencap.parse(b"/system/bin/sh: screencap: inaccessible or not found\n", 33)
    with pytest.raises(InfrastructureError, match="colorspace field is 7"):
        screencap.parse(frame(1, 33, colorspace=7), 33)
    with pytest.raises(screencap.UnsupportedFormat):   # RGBA_FP16 (0x16) on a wide-colour display
        screencap.parse(struct.pack("<IIII", 2, 2, 0x16, 2) + bytes(32), 33)
    assert screencap.parse(frame(2, 33, colorspace=2), 33).colorspace == 2   # Display P3


def test_a_phone_sized_frame_parses_and_encodes_quickly():
    data = struct.pack("<IIII", 1080, 2400, 1, 1) + bytes([40, 80, 120, 255]) * (1080 * 2400)
    t0 = time.perf_counter()
    png = screencap.to_png(screencap.parse(data, 33))
    assert time.perf_counter() - t0 < 5
    img = Image.open(io.BytesIO(png))
    assert img.size == (1080, 2400) and img.getpixel((1079, 2399)) == (40, 80, 120)


# -- uiautomator dumps recorded from real devices --------------------------------------------------------------
def walk(node):
    yield node
    for child in node.get("children", []):
        yield from walk(child)


@pytest.mark.parametrize("path", DUMPS, ids=lambda p: p.stem)
def test_recorded_dumps_map_every_node_to_the_shared_shape(path):
    text = path.read_text(encoding="utf-8")
    tree, errors = uiautomator.parse_output(text)
    assert errors == [] and not tree["truncated"]
    assert tree["nodes"] == len(re.findall(r"<node\b", text)) > 0
    nodes = list(walk(tree["tree"]))[1:]
    assert len(nodes) == tree["nodes"]
    for n in nodes:
        assert isinstance(n["role"], str) and n["role"] and isinstance(n["name"], str)
        assert len(n["box"]) == 4 and all(isinstance(v, int) for v in n["box"]) and min(n["box"][2:]) >= 0
        assert "showing" in n["states"] and n["class"]
    json.dumps(tree)  # what Observation.a11y_tree carries


def find(tree, **want):
    return [n for n in walk(tree["tree"]) if all(n.get(k) == v for k, v in want.items())]


def test_recorded_dump_contents_are_read_correctly():
    msgs, _ = uiautomator.parse_output((DATA / "uiautomator/messages_720x1536.xml").read_text(encoding="utf-8"))
    send = find(msgs, name="Send message")
    assert send and send[0]["box"] == [611, 1491, 95, 45]
    bubble = find(msgs, text="Hiii")[0]
    assert bubble["role"] == "label" and bubble["name"].startswith("You said  Hiii")
    assert find(msgs, name="Compose:Draft:Send")[0]["states"] == ["clickable", "enabled", "focusable",
                                                                   "long-clickable", "showing"]
    talos, _ = uiautomator.parse_output((DATA / "uiautomator/talos_1080x2160.xml").read_text(encoding="utf-8"))
    assert find(talos, name="NEXT")[0]["role"] == "push button"
    assert find(talos, name="Increase accessibility volume")[0]["class"] == "android.widget.ImageButton"
    assert any(n["name"].startswith("Run\nadb shell settings put secure") for n in walk(talos["tree"]))  # &#10;
    assert find(talos, name="Heading 3")[0]["box"] == [0, 0, 0, 0]
    assert find(talos, role="scroll pane")[0]["states"][:2] == ["enabled", "focusable"]
    zh, _ = uiautomator.parse_output((DATA / "uiautomator/systemui_api17_zh.xml").read_text(encoding="utf-8"))
    assert find(zh, name="语言")[0]["states"] == ["enabled", "selected", "showing"]
    launcher, _ = uiautomator.parse_output((DATA / "uiautomator/launcher_api27.xml").read_text(encoding="utf-8"))
    assert [n["name"] for n in find(launcher, role="label") if n["box"][1] == 1479] == \
        ["Phone", "Messages", "Play Store", "Chrome"]


def test_an_idle_state_error_before_a_real_dump_is_parsed_and_reported():
    """No public repository keeps a dump with this prefix: it is built by prefixing a real dump with the exact
    message AOSP's DumpCommand prints (which `adb exec-out` merges into the stream)."""
    real = (DATA / "uiautomator/talos_1080x2160.xml").read_text(encoding="utf-8")
    tree, errors = uiautomator.parse_output(uiautomator.IDLE_ERROR + "\n" + real +
                                            "\nUI hierchary dumped to: /data/local/tmp/x.xml\n")
    assert errors == [uiautomator.IDLE_ERROR] and tree["nodes"] == 34
    assert uiautomator.parse_output(uiautomator.IDLE_ERROR + "\n") == (None, [uiautomator.IDLE_ERROR])
    assert uiautomator.parse_output(uiautomator.NULL_ROOT_ERROR) == (None, [uiautomator.NULL_ROOT_ERROR])


def test_a_cut_off_or_oversized_dump_keeps_what_was_read():
    real = (DATA / "uiautomator/messages_720x1536.xml").read_text(encoding="utf-8")
    cut, _ = uiautomator.parse_output(real[: len(real) * 6 // 10])
    assert cut["truncated"] and 0 < cut["nodes"] < 110
    capped, _ = uiautomator.parse_output(real, max_nodes=25)
    assert capped["truncated"] and capped["nodes"] == 25 == len(list(walk(capped["tree"]))) - 1


class ReplayAdb(Adb):
    """A fake *device* (not a fake adb): answers `exec_out`/`shell` from recorded or AOSP-format outputs and
    records the command lines it was given."""

    def __init__(self, exec_out=(), shell=None):
        super().__init__(serial="replay", port=5137, binary="/bin/false")
        self.replies = list(exec_out)
        self.shell_reply = shell or (lambda cmd: ShellResult(0, "", ""))
        self.sent: list[str] = []

    def for_serial(self, serial):
        return self

    def exec_out(self, command, timeout=60.0):
        self.sent.append(command)
        return self.replies.pop(0)

    def shell(self, command, timeout=60.0):
        self.sent.append(command)
        return self.shell_reply(command)


def test_a11y_tree_retries_after_the_idle_error(monkeypatch):
    monkeypatch.setattr("jarvis_pytest.devices.android.device.time.sleep", lambda s: None)
    real = (DATA / "uiautomator/talos_1080x2160.xml").read_bytes()
    replay = ReplayAdb(exec_out=[(uiautomator.IDLE_ERROR + "\n").encode(), b"UI hierchary dumped to: x\n" + real])
    tree = AdbDevice("replay", adb=replay).a11y_tree()
    assert tree["nodes"] == 34 and tree["tree"]["children"]
    assert len(replay.sent) == 2 and all("uiautomator dump" in c and "rm -f" in c for c in replay.sent)
    failing = ReplayAdb(exec_out=[(uiautomator.IDLE_ERROR + "\n").encode()] * 3)
    tree = AdbDevice("replay", adb=failing).a11y_tree()
    assert tree["tree"] is None and uiautomator.IDLE_ERROR in tree["error"] and len(failing.sent) == 3


def test_observe_decodes_a_replayed_frame(monkeypatch):
    replay = ReplayAdb(exec_out=[frame(4, 33)])
    dev = AdbDevice("replay", adb=replay)
    dev._sdk = 33
    obs = dev.observe()
    assert (obs.platform, obs.width, obs.height) == ("android", 2, 2) and obs.screenshot_png.startswith(b"\x89PNG")
    assert replay.sent == ["screencap 2>/dev/null"]


# -- every action type → its command lines ---------------------------------------------------------------------
def state(**kw) -> C.InputState:
    return C.InputState(**{"width": 1080, "height": 2400, "sdk": 33, **kw})


EXPECTED = [
    (A.Click(x=10, y=20), ["input tap 10 20"]),
    (A.Click(x=10, y=20, clicks=2), ["input tap 10 20", "input tap 10 20"]),
    (A.Click(x=10, y=20, button="right"), ["input swipe 10 20 10 20 800"]),
    (A.DoubleClick(x=5, y=6), ["input tap 5 6", "input tap 5 6"]),
    (A.RightClick(x=5, y=6), ["input swipe 5 6 5 6 800"]),
    (A.MoveTo(x=7, y=8), []),
    (A.LongPress(x=100, y=200, duration=1500), ["input swipe 100 200 100 200 1500"]),
    (A.Swipe(x=540, y=1800, dx=0, dy=-1200, duration=300), ["input swipe 540 1800 540 600 300"]),
    (A.DragTo(x=300, y=400, start_x=100, start_y=200), ["input draganddrop 100 200 300 400 1000"]),
    (A.Scroll(dy=3), ["input swipe 540 1560 540 840 400"]),
    (A.Scroll(dy=-2, x=100, y=1000), ["input swipe 100 760 100 1240 400"]),
    (A.Scroll(dx=1, x=540, y=1000), ["input swipe 594 1000 486 1000 400"]),
    (A.Typing(text="a b"), ["input text a%sb"]),
    (A.Typing(text="it's"), ["input text 'it'\"'\"'s'"]),
    (A.Hotkey(keys=["ctrl", "a"]), ["input keycombination KEYCODE_CTRL_LEFT KEYCODE_A"]),
    (A.Hotkey(keys=["enter"]), ["input keyevent KEYCODE_ENTER"]),
    (A.KeyDown(key="backspace"), ["input keyevent KEYCODE_DEL"]),
    (A.KeyUp(key="backspace"), []),
    (A.SystemButton(button="home"), ["input keyevent KEYCODE_HOME"]),
    (A.SystemButton(button="back"), ["input keyevent KEYCODE_BACK"]),
    (A.SystemButton(button="menu"), ["input keyevent KEYCODE_MENU"]),
    (A.SystemButton(button="enter"), ["input keyevent KEYCODE_ENTER"]),
    (A.SystemButton(button="volume_up"), ["input keyevent KEYCODE_VOLUME_UP"]),
    (A.SystemButton(button="volume_down"), ["input keyevent KEYCODE_VOLUME_DOWN"]),
    (A.SystemButton(button="power"), ["input keyevent KEYCODE_POWER"]),
    (A.Wait(seconds=0.1), []),
    (A.Done(), []),
    (A.Fail(), []),
]


@pytest.mark.parametrize("action,lines", EXPECTED, ids=lambda v: getattr(v, "type", None))
def test_action_to_command_lines(action, lines):
    assert C.commands_for(action, state()) == lines


def test_every_action_type_is_mapped_or_refused_with_a_reason():
    covered = {a.type for a, _ in EXPECTED} | {"MOUSE_DOWN", "MOUSE_UP", "PYAUTOGUI"}
    assert covered == set(A.ACTION_TYPES)
    s = state(x=50, y=60)
    assert C.commands_for(A.MouseDown(), s) == ["input motionevent DOWN 50 60"]
    assert C.commands_for(A.MoveTo(x=70, y=80), s) == ["input motionevent MOVE 70 80"]
    assert C.commands_for(A.MouseUp(), s) == ["input motionevent UP 70 80"]
    with pytest.raises(C.Unsupported, match="desktop"):
        C.commands_for(A.Pyautogui(script="pyautogui.click()"), s)
    with pytest.raises(C.Unsupported, match="outside the 1080x2400 screen"):
        C.commands_for(A.Click(x=1080, y=5), s)
    with pytest.raises(C.Unsupported, match="no position"):
        C.commands_for(A.Click(), state())
    with pytest.raises(C.Unsupported, match="unknown key"):
        C.commands_for(A.Hotkey(keys=["hyper"]), s)


def test_key_combinations_on_older_android_and_held_modifiers():
    assert C.commands_for(A.Hotkey(keys=["ctrl", "a"]), state(sdk=30, ime_installed=True, ime_active=True)) == \
        [f"am broadcast -a ADB_INPUT_TEXT -p {C.IME_PACKAGE} --es mcode 12288,29"]
    with pytest.raises(C.Unsupported, match="Android 12"):
        C.commands_for(A.Hotkey(keys=["ctrl", "a"]), state(sdk=30))
    s = state()
    assert C.commands_for(A.KeyDown(key="shift"), s) == []
    assert C.commands_for(A.KeyDown(key="a"), s) == ["input keycombination KEYCODE_SHIFT_LEFT KEYCODE_A"]
    assert C.commands_for(A.KeyUp(key="shift"), s) == [] and s.held == []
    assert C.commands_for(A.DragTo(x=3, y=4, start_x=1, start_y=2), state(sdk=28)) == ["input swipe 1 2 3 4 1500"]
    with pytest.raises(C.Unsupported, match="Android 10"):
        C.commands_for(A.MouseDown(), state(sdk=28, x=1, y=1))
    assert [C.keycode(k) for k in ("Enter", "f5", "KEYCODE_CAMERA", "7", "66", ",")] == \
        ["KEYCODE_ENTER", "KEYCODE_F5", "KEYCODE_CAMERA", "KEYCODE_7", "66", "KEYCODE_COMMA"]


def test_act_runs_the_lines_in_one_shell_and_reads_errors_from_output():
    """On a replayed device: `cmd input` prints its errors and may still exit 0."""
    replies = {"input tap 1 2 && input tap 1 2": ShellResult(0, "", ""),
               "input keycombination KEYCODE_CTRL_LEFT KEYCODE_A":
                   ShellResult(0, "", "Error: Unknown command: keycombination\n")}
    replay = ReplayAdb(shell=lambda cmd: replies[cmd])
    dev = AdbDevice("replay", adb=replay)
    dev._input = state()
    assert dev.act(A.DoubleClick(x=1, y=2)).ok
    out = dev.act(A.Hotkey(keys=["ctrl", "a"]))
    assert not out.ok and "Unknown command" in out.error
    out = dev.act(A.Typing(text="東京"))
    assert not out.ok and "ADBKeyBoard" in out.error and len(replay.sent) == 2
    assert action_error(0, "Broadcasting: Intent { act=ADB_INPUT_B64 }\nBroadcast completed: result=0") is None
    assert action_error(255, "") == "command failed with exit status 255: "


# -- parsers of other tools' output ----------------------------------------------------------------------------
def test_content_query_rows_with_commas_newlines_and_nulls():
    """Rows as AOSP Content.java's QueryCommand prints them (`Row: n col=value, col=value`)."""
    text = ("Row: 0 _id=12, address=+14155550123, body=Hi, see you at 5, ok?, date=1700000000000\n"
            "Row: 1 _id=13, address=NULL, body=line one\nline two, x=y, date=0\n"
            "Row: 2 _id=14, address=555, body=, date=1\n")
    rows = outputs.parse_content_rows(text, ["_id", "address", "body", "date"])
    assert rows == [{"_id": "12", "address": "+14155550123", "body": "Hi, see you at 5, ok?", "date": "1700000000000"},
                    {"_id": "13", "address": None, "body": "line one\nline two, x=y", "date": "0"},
                    {"_id": "14", "address": "555", "body": "", "date": "1"}]
    assert outputs.parse_content_rows("No result found.\n") == []
    loose = outputs.parse_content_rows("Row: 0 name=volume_ring, value=5\nRow: 1 name=x, value=NULL\n")
    assert loose == [{"name": "volume_ring", "value": "5"}, {"name": "x", "value": None}]


def test_focused_window_from_recorded_and_current_dumpsys():
    recorded = (DATA / "dumpsys/window_windows_android4.txt").read_text(encoding="utf-8")
    assert outputs.focused_activity(recorded) == ("com.dtmilano.android.sampleui",
                                                  "com.dtmilano.android.sampleui.MainActivity")
    current = ("  mCurrentFocus=Window{6f3c1a0 u0 com.android.settings/com.android.settings.Settings}\n"
               "  mFocusedApp=ActivityRecord{d2c3a3f u0 com.android.settings/.Settings t12}\n")
    assert outputs.focused_activity(current) == ("com.android.settings", "com.android.settings.Settings")
    assert outputs.focused_activity("  mFocusedApp=ActivityRecord{d2c3a3f u0 com.android.deskclock/"
                                    ".DeskClock t3}\n  mCurrentFocus=null\n") == \
        ("com.android.deskclock", "com.android.deskclock.DeskClock")
    assert outputs.focused_activity("  mCurrentFocus=Window{1 u0 NotificationShade}\n") is None


def test_small_parsers():
    assert outputs.resolved_activity("priority=0 preferredOrder=0 match=0x108000 specificIndex=-1 "
                                     "isDefault=true\ncom.android.settings/.Settings\n") == \
        "com.android.settings/.Settings"
    assert outputs.resolved_activity("No activity found\n") is None
    assert outputs.am_start_error("Starting: Intent { cmp=a/.B }\nError type 3\nError: Activity class {a/a.B} "
                                  "does not exist.\n") == "Error type 3"
    assert outputs.am_start_error("Starting: Intent { cmp=a/.B }\nStatus: ok\nLaunchState: COLD\n") is None
    assert outputs.wm_size("Physical size: 1080x2400\n") == (1080, 2400)
    assert outputs.wm_size("Physical size: 1080x2400\nOverride size: 720x1600\n") == (720, 1600)
    assert outputs.settings_value("null\n") is None and outputs.settings_value("0.5\n") == "0.5"
    assert adbmod.parse_devices("List of devices attached\nemulator-5554\tdevice\n127.0.0.1:6555\toffline\n\n") \
        == {"emulator-5554": "device", "127.0.0.1:6555": "offline"}
    assert adbmod.is_tcp_serial("127.0.0.1:5556") and not adbmod.is_tcp_serial("emulator-5554")
    assert B.serial_of("adb://R58M123") == "R58M123" and B.serial_of("http://127.0.0.1:32768") == "127.0.0.1:32768"


# -- the backends on this machine ------------------------------------------------------------------------------
def test_backends_say_why_they_cannot_run_here_and_how_to(monkeypatch):
    monkeypatch.delenv(B.SERIAL_ENV, raising=False)
    monkeypatch.delenv(B.IMAGE_ENV, raising=False)
    assert "android.serial=SERIAL" in B.ATTACH.configure({}).unavailable()
    attach = B.ATTACH.configure({"serial": "127.0.0.1:5999"})  # the option (--backend-option android.serial=...)
    assert attach.unavailable() is None and attach.values == {"serial": "127.0.0.1:5999"}
    assert B.ATTACH.unavailable() is not None  # the backend as defined is untouched: no module-wide setting
    monkeypatch.setenv(B.SERIAL_ENV, "emulator-5554")  # the older variable, when the option is not given
    assert B.ATTACH.configure({}).values == {"serial": "emulator-5554"}
    why = B.EMULATOR.unavailable()
    assert why and ("jarvis images build --only android" in why or "/dev/kvm" in why or "Docker" in why), why
    assert "jarvis images build --only android" in B.EMULATOR.how_to_run
    assert "--android-serial" in B.ATTACH.how_to_run and "android.serial" in B.ATTACH.how_to_run
    assert (B.EMULATOR.label, B.ATTACH.label) == ("android (emulator)", "android (attach)")
    from jarvis_pytest.infra.images import image_tag

    assert B.EMULATOR.image_ref == image_tag(I.IMAGE_NAME) == B.DEFAULT_IMAGE
    assert B.EMULATOR.configure({"image": "example/android:34"}).image_ref == "example/android:34"
    monkeypatch.setenv(B.IMAGE_ENV, "example/android:35")
    assert B.EMULATOR.configure({}).image_ref == "example/android:35"


def test_the_image_build_stops_here_with_what_it_needs(monkeypatch):
    monkeypatch.delenv(I.DOWNLOAD_ENV, raising=False)
    why = I.build_blocker()
    assert why and "dl.google.com" in why and "JARVIS_ANDROID_DOWNLOAD=1" in why
    monkeypatch.setenv(I.DOWNLOAD_ENV, "1")
    if I.kvm_problem() is None:
        assert I.build_blocker() is None
    else:
        assert "/dev/kvm" in I.build_blocker()
    monkeypatch.delenv(I.DOWNLOAD_ENV)
    with pytest.raises(InfrastructureError, match="dl.google.com"):
        I.build()                       # stops before Docker or any download is touched
    folder = Path(__file__).parents[1] / "fixtures/images/android"
    assert (folder / I.DOCKERFILE).is_file() and not (folder / "Dockerfile").exists()  # never in a build of all


def test_attach_allows_one_task_at_a_time_per_device(tmp_path, monkeypatch):
    monkeypatch.setattr(B.tempfile, "gettempdir", lambda: str(tmp_path))
    stop = threading.Event()
    B._acquire("R58M123", stop, 1)
    try:
        t0 = time.monotonic()
        with pytest.raises(InfrastructureError, match="busy"):
            B._acquire("R58M123", stop, 0.6)   # also from the same process
        assert time.monotonic() - t0 < 3
    finally:
        B._release("R58M123")
    B._acquire("R58M123", stop, 1)
    B._release("R58M123")


# -- device operations on a replayed device --------------------------------------------------------------------
class ScriptedDevice(ReplayAdb):
    """A fake *device* answering shell commands by pattern with AOSP-format outputs, and `pull` from files."""

    def __init__(self, answers: dict[str, ShellResult], files: dict[str, Path] | None = None, exec_out=()):
        super().__init__(exec_out=exec_out, shell=self._answer)
        self.answers, self.files = answers, files or {}

    def _answer(self, command: str) -> ShellResult:
        for pattern, result in self.answers.items():
            if re.search(pattern, command):
                return result
        raise AssertionError(f"unexpected command on the device: {command}")

    def pull(self, remote, local, timeout=120.0):
        self.sent.append(f"pull {remote}")
        if remote not in self.files:
            raise InfrastructureError(f"adb: error: failed to stat remote object '{remote}': No such file")
        shutil.copyfile(self.files[remote], local)


def test_launch_resolves_the_launcher_activity_and_waits_for_its_window():
    dev = AdbDevice("replay", adb=ScriptedDevice({
        r"^cmd package resolve-activity": ShellResult(0, "priority=0 preferredOrder=0 match=0x108000 "
                                                         "specificIndex=-1 isDefault=true\n"
                                                         "com.android.settings/.Settings\n", ""),
        r"^am start -W -n com\.android\.settings/\.Settings $": ShellResult(0, "Starting: Intent { cmp=com.android."
                                                                            "settings/.Settings }\nStatus: ok\n", ""),
        r"^dumpsys window": ShellResult(0, "  mCurrentFocus=Window{6f3c1a0 u0 com.android.settings/com.android."
                                           "settings.Settings}\n", ""),
    }))
    assert dev.launch("com.android.settings", window_wait=1) is True
    missing = AdbDevice("replay", adb=ScriptedDevice({
        r"^am start": ShellResult(0, "Starting: Intent { cmp=com.x/.Y }\nError type 3\nError: Activity class "
                                     "{com.x/com.x.Y} does not exist.\n", "")}))
    with pytest.raises(InfrastructureError, match="Error type 3"):
        missing.launch("com.x/.Y", window_wait=0)


def test_settings_content_and_files_on_a_replayed_device():
    dev = AdbDevice("replay", adb=ScriptedDevice({
        r"^settings get global window_animation_scale$": ShellResult(0, "0.0\n", ""),
        r"^settings get secure missing_key$": ShellResult(0, "null\n", ""),
        r"^content query --uri content://sms/inbox --projection _id:body$":
            ShellResult(0, "Row: 0 _id=3, body=see you, at 5\n", ""),
        r"^content query --uri content://call_log/calls$":
            ShellResult(0, "", "Error while accessing provider:call_log\njava.lang.SecurityException: Permission "
                               "Denial\n"),
        r"^test -e '/sdcard/a b\.txt'$": ShellResult(0, "", ""),
        r"^test -e /sdcard/none$": ShellResult(1, "", ""),
    }))
    assert dev.settings_get("global", "window_animation_scale") == "0.0"
    assert dev.settings_get("secure", "missing_key") is None
    assert dev.content_query("content://sms/inbox", ["_id", "body"]) == [{"_id": "3", "body": "see you, at 5"}]
    with pytest.raises(InfrastructureError, match="Permission Denial"):
        dev.content_query("content://call_log/calls")
    assert dev.exists("/sdcard/a b.txt") and not dev.exists("/sdcard/none")


def test_an_app_database_is_read_on_the_host_with_its_wal(tmp_path):
    """The replayed device holds a real SQLite database in WAL mode whose last insert is only in the -wal file."""
    import sqlite3

    db = tmp_path / "dev" / "calendar.db"
    db.parent.mkdir()
    con = sqlite3.connect(str(db))
    con.execute("PRAGMA journal_mode=WAL")
    con.execute("PRAGMA wal_autocheckpoint=0")
    con.execute("CREATE TABLE events (_id INTEGER PRIMARY KEY, title TEXT)")
    con.commit()
    con.execute("INSERT INTO events (title) VALUES ('Standup'), ('Zahnarzt – 14:00')")
    con.commit()
    snapshot = {p.name: p.read_bytes() for p in db.parent.iterdir()}   # while the writer still holds the WAL
    con.close()
    for name, data in snapshot.items():
        (db.parent / name).write_bytes(data)
    root = "/data/data/com.android.providers.calendar/databases/calendar.db"
    dev = AdbDevice("replay", adb=ScriptedDevice(
        {r"^id -u$": ShellResult(0, "0\n", ""), rf"^test -e {re.escape(root)}-wal$": ShellResult(0, "", ""),
         rf"^test -e {re.escape(root)}-journal$": ShellResult(1, "", "")},
        files={root: db, root + "-wal": db.parent / "calendar.db-wal"}))
    rows = dev.query_database("com.android.providers.calendar", "calendar.db", "SELECT title FROM events ORDER BY _id")
    assert [r["title"] for r in rows] == ["Standup", "Zahnarzt – 14:00"]


def test_screen_size_reads_only_the_frame_header():
    replay = ReplayAdb(exec_out=[struct.pack("<IIII", 2400, 1080, 1, 1)])
    assert AdbDevice("replay", adb=replay).screen_size() == (2400, 1080)   # landscape: as `input` sees it
    assert replay.sent == ["screencap 2>/dev/null | head -c 16"]


def test_prepare_turns_animations_off_and_selects_the_ime():
    dev = AdbDevice("replay", adb=ScriptedDevice({
        r"^settings put global window_animation_scale 0; .*wm dismiss-keyguard$": ShellResult(0, "", ""),
        r"^pm list packages com\.android\.adbkeyboard$": ShellResult(0, "package:com.android.adbkeyboard\n", ""),
        r"^settings get secure default_input_method$": ShellResult(0, "com.google.android.inputmethod.latin/"
                                                                      "com.android.inputmethod.latin.LatinIME\n", ""),
        r"^ime enable": ShellResult(0, "", ""),
        r"^getprop ro\.build\.version\.sdk$": ShellResult(0, "33\n", ""),
    }, exec_out=[struct.pack("<IIII", 1080, 2400, 1, 1)]))
    dev.prepare()
    sent = dev.adb.sent
    assert all(f"settings put global {k} 0" in sent[0] for k in
               ("window_animation_scale", "transition_animation_scale", "animator_duration_scale"))
    assert sent[-1].startswith(f"ime enable {C.IME_ID}") and f"ime set {C.IME_ID}" in sent[-1]
    assert dev.input_state().ime_active and (dev.input_state().width, dev.input_state().sdk) == (1080, 33)


def test_the_emulator_container_matches_its_image():
    folder = Path(__file__).parents[1] / "fixtures/images/android"
    entry = (folder / "entrypoint.sh").read_text()
    assert subprocess.run(["bash", "-n", str(folder / "entrypoint.sh")]).returncode == 0
    for flag in ("-no-window", "-no-audio", "-no-boot-anim", "-gpu swiftshader_indirect", "-read-only",
                 "-no-snapshot-save", "-snapshot golden", "snapshot save golden", C.IME_ID):
        assert flag in entry, flag
    assert f"TCP-LISTEN:{B.ADB_FORWARD_PORT}," in entry and f"EXPOSE {B.ADB_FORWARD_PORT}" in \
        (folder / I.DOCKERFILE).read_text()
    assert B.EMULATOR.port == B.ADB_FORWARD_PORT and "/dev/kvm:/dev/kvm:rwm" in B.EMULATOR.container_options["devices"]
    assert "system-images;android-33;google_apis;x86_64" in (folder / I.DOCKERFILE).read_text()
