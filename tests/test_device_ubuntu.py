"""The Ubuntu device through its control server, on a real container booted straight from the image: observation,
every action by its effect, exact typing into a real editor, files, commands, applications, desktop settings,
accessibility, bad input. The container is created with the docker SDK here (not through `infra/`), so these tests
check the device alone; they fail (never skip) when no engine or image can be had."""

from __future__ import annotations

import io
import json
import time
from pathlib import Path

import httpx
import pytest
from filelock import FileLock
from PIL import Image, ImageStat

from device_checks import check_concurrent_requests, check_refusals_keep_the_server_usable
from jarvis_pytest.devices import actions as A
from jarvis_pytest.bench.probe import boot

pytestmark = pytest.mark.containers
RECORDER = Path(__file__).parent / "data" / "device" / "event_recorder.py"


@pytest.fixture(scope="session")
def ubuntu_image(tmp_path_factory) -> str:
    """The `ubuntu` device image, built when missing or stale (one builder at a time across xdist workers)."""
    from jarvis_pytest.infra import engine, images

    engine.ensure_engine()  # raises with the fix when no engine can be had: the tests error, loudly
    with FileLock(str(tmp_path_factory.getbasetemp().parent / "jarvis-images.lock")):
        return images.build_all(["ubuntu"])["ubuntu"]


@pytest.fixture(scope="module")
def booted(ubuntu_image):
    with boot(ubuntu_image, timeout=120) as b:
        yield b


@pytest.fixture(scope="module")
def device(booted):
    return booted.device


def wait_for(predicate, timeout: float = 20.0, what: str = "condition"):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"{what} not met within {timeout} s")


def screen(device) -> Image.Image:
    return Image.open(io.BytesIO(device.screenshot())).convert("RGB")


def window_box(device, cls: str, timeout: float = 60) -> tuple[int, int, int, int]:
    """(x, y, w, h) of the newest visible window of X class `cls`, waited for (windows that appear and go
    while an application starts, such as splash screens, are retried)."""
    def box():
        r = device.run(f"wid=$(xdotool search --onlyvisible --class {cls} | tail -1) && [ -n \"$wid\" ] && "
                       "xdotool getwindowgeometry --shell $wid")
        return r.returncode == 0 and dict(line.split("=") for line in r.stdout.split())

    g = wait_for(box, timeout, f"a visible {cls} window")
    return int(g["X"]), int(g["Y"]), int(g["WIDTH"]), int(g["HEIGHT"])


@pytest.fixture
def launch(device):
    """Launch an application for one test; its process (`process`, default the command) is ended after it."""
    processes: list[str] = []

    def start(app: str, *args: str, process: str | None = None, window_wait: float = 20.0) -> bool:
        processes.append(process or app)
        return device.launch(app, *args, window_wait=window_wait)

    yield start
    for name in processes:  # gone before the next test starts it again (a single-instance app would hand over)
        device.run(f"pkill -x {name}; for i in $(seq 100); do pgrep -x {name} >/dev/null || exit 0; sleep 0.05; "
                   f"done; pkill -KILL -x {name}")


@pytest.fixture
def recorder(device):
    """A full-screen window inside the device that logs the input events it gets; yields a reader."""
    device.upload("/tmp/recorder.py", RECORDER.read_bytes())
    device.run("rm -f /tmp/events.log")
    device.launch("python3", "/tmp/recorder.py", "/tmp/events.log", window_wait=0)  # no managed window: waited below
    events = lambda: [json.loads(l) for l in device.download("/tmp/events.log").decode().splitlines()]  # noqa: E731
    wait_for(lambda: device.run("test -s /tmp/events.log").returncode == 0 and events(), what="recorder ready")

    def read() -> list[dict]:
        """Every event logged so far: a sentinel move is sent last and waited for (X delivers in order)."""
        device.act(A.MoveTo(x=1919, y=1079))
        is_sentinel = lambda e: e["type"] == "motion" and (e["x"], e["y"]) == (1919, 1079)  # noqa: E731
        logged = wait_for(lambda: (ev := events()) and any(map(is_sentinel, ev)) and ev, what="sentinel event")
        return [e for e in logged if not is_sentinel(e)]

    # the window gets pointer events now (on a busy machine it is drawn before it gets them); the pointer is left
    # next to the sentinel's place, so the first sentinel of a test is a real move
    device.act(A.MoveTo(x=1918, y=1078))
    wait_for(lambda: any(e["type"] == "motion" and (e["x"], e["y"]) == (1918, 1078) for e in events()),
             what="first pointer event")
    device.run("truncate -s 0 /tmp/events.log")
    yield read
    device.run("pkill -f /tmp/recorder.py")


# -- readiness and observation ----------------------------------------------------------------------------------

def test_ready_means_a_drawn_xfce_desktop(booted, device):
    print(f"create → ready: {booted.ready_s:.2f} s")
    assert device.health().desktop
    ps = device.run("ps -eo user=,comm=").stdout.split("\n")
    for proc in ("Xvfb", "xfwm4", "xfdesktop", "xfce4-panel", "xfsettingsd", "at-spi2-registr"):
        assert any(line.split()[-1:] == [proc] for line in ps), f"{proc} does not run: {ps}"
    server = device.run("ps -o user= -C python3").stdout.split()
    assert server and set(server) == {"user"}, "the control server must run as the desktop user"


def test_screenshot_is_the_desktop(device):
    obs = device.observe()
    img = Image.open(io.BytesIO(obs.screenshot_png))
    assert img.size == (1920, 1080) == (obs.width, obs.height) == device.screen_size()
    assert max(ImageStat.Stat(img.convert("L")).stddev) > 5, "the screenshot is blank"


ENCODE_CHECK = """
import io, os, random
from PIL import Image
from jarvis_pytest.devices.png import PngEncoder
enc = PngEncoder()
for w, h in ((1920, 1080), (1920, 1080), (1, 1), (7, 3), (333, 211)):
    img = Image.frombytes("RGB", (w, h), os.urandom(w * h * 3))
    back = Image.open(io.BytesIO(enc.encode(img.tobytes(), w, h)))
    assert back.mode == "RGB" and back.size == (w, h) and back.tobytes() == img.tobytes(), (w, h)
img = Image.new("RGB", (1920, 1080), "#3a6ea5")
for _ in range(5):  # a few changed rows: the other bands are reused, every pixel still right
    img.paste(Image.frombytes("RGB", (50, 3), os.urandom(450)), (random.randrange(1870), random.randrange(1077)))
    assert Image.open(io.BytesIO(enc.encode(img.tobytes(), 1920, 1080))).tobytes() == img.tobytes()
from jarvis_pytest.devices.png import packed_rgb
from jarvis_pytest.devices.ubuntu.server.screen import bgrx_to_rgb, draw_on_bgrx
for w, rows, stride in ((1920, 32, 7680), (7, 3, 28), (5, 4, 24)):  # Pillow converts as the standard library does
    data = os.urandom(stride * rows)
    assert bytes(bgrx_to_rgb(data, w, rows, stride)) == bytes(packed_rgb("BGRX")(data, w, rows, stride)), w
cursor = Image.frombytes("RGBA", (24, 24), os.urandom(24 * 24 * 4))
screen = Image.frombytes("RGB", (300, 200), os.urandom(300 * 200 * 3))
for x, y in ((10, 10), (-5, -7), (290, 190), (-30, 5), (0, 199), (300, 0)):  # inside, clipped, off the screen
    want = screen.copy()
    want.paste(cursor, (x, y), cursor)
    bgrx = bytearray(screen.tobytes("raw", "BGRX"))
    draw_on_bgrx(bgrx, 300, 200, 1200, cursor, x, y)
    assert Image.frombytes("RGB", (300, 200), bytes(bgrx), "raw", "BGRX").tobytes() == want.tobytes(), (x, y)
from jarvis_pytest.devices.ubuntu.server.screen import Screen
live = Screen(":0")
assert live._shm is not None
for x in (0, 900, 1915):  # the screenshots are what Pillow grabs, cursor and all (again if a clock ticked)
    live.root.warp_pointer(x, 500)
    live.display.sync()
    assert any(Image.open(io.BytesIO(live.png())).tobytes() == live.grab().tobytes() for _ in range(3)), x
print("same")
"""


def test_the_screenshot_encoder_keeps_every_pixel(device):
    """The control server's PNG writer (`devices/png.py`), run where it runs: random images of several sizes,
    then one screen with a few rows changed at a time, decode (with Pillow) to exactly their pixels; the cursor
    drawn into the X server's pixels is what Pillow draws, clipped at the screen's edges, Pillow's conversion of
    those pixels is the shared encoder's own, and a live screenshot is the screen Pillow grabs."""
    out = device.run(f"python3 -c '{ENCODE_CHECK}'")
    assert out.returncode == 0 and out.stdout.strip() == "same", out


def test_the_cursor_is_drawn_where_the_pointer_is(device):
    device.act(A.MoveTo(x=900, y=500))
    near = screen(device).crop((900, 500, 916, 520))
    device.act(A.MoveTo(x=100, y=900))
    after = screen(device).crop((900, 500, 916, 520))
    assert near.tobytes() != after.tobytes()


# -- actions, checked by the X events they cause ------------------------------------------------------------------

def presses(events, kind="press"):
    return [(e["button"], e["x"], e["y"]) for e in events if e["type"] == kind]


def test_clicks(device, recorder):
    assert device.act(A.Click(x=300, y=400)).ok
    assert device.act(A.RightClick(x=310, y=410)).ok
    assert device.act(A.DoubleClick(x=320, y=420)).ok
    assert device.act(A.Click(x=330, y=430, button="middle", clicks=3)).ok
    assert device.act(A.Click()).ok  # where the pointer is
    assert presses(recorder()) == [(1, 300, 400), (3, 310, 410), (1, 320, 420), (1, 320, 420),
                                   (2, 330, 430), (2, 330, 430), (2, 330, 430), (1, 330, 430)]


def test_mouse_down_up_move_and_drag(device, recorder):
    device.act(A.MoveTo(x=500, y=500))
    device.act(A.MouseDown(button="left"))
    device.act(A.MoveTo(x=600, y=550))
    device.act(A.MouseUp(button="left"))
    device.act(A.DragTo(start_x=700, start_y=300, x=800, y=350))
    ev = recorder()
    assert presses(ev) == [(1, 500, 500), (1, 700, 300)]
    assert presses(ev, "release") == [(1, 600, 550), (1, 800, 350)]
    assert any(e["type"] == "motion" and (e["x"], e["y"]) == (600, 550) for e in ev)


def test_scroll_swipe_long_press(device, recorder):
    device.act(A.Scroll(dx=0, dy=2, x=400, y=400))
    device.act(A.Scroll(dx=-1, dy=-1))
    device.act(A.Swipe(x=900, y=600, dx=-200, dy=0, duration=100))
    device.act(A.LongPress(x=1000, y=700, duration=400))
    ev = recorder()
    buttons = [b for b, _, _ in presses(ev)]
    assert buttons[:4] == [5, 5, 4, 6] and buttons[4:] == [1, 1]
    assert presses(ev, "release")[-2][1:] == (700, 600)  # the swipe ends at its offset
    long_down = [e for e in ev if e["type"] == "press" and (e["x"], e["y"]) == (1000, 700)][0]
    long_up = [e for e in ev if e["type"] == "release" and (e["x"], e["y"]) == (1000, 700)][0]
    assert long_up["time"] - long_down["time"] >= 380


def test_keys_and_hotkey(device, recorder):
    device.act(A.KeyDown(key="shift"))
    device.act(A.KeyUp(key="shift"))
    device.act(A.Hotkey(keys=["ctrl", "shift", "a"]))
    ev = [(e["type"], e["key"]) for e in recorder() if e["type"].startswith("key")]
    assert ev == [("key_down", "Shift_L"), ("key_up", "Shift_L"), ("key_down", "Control_L"),
                  ("key_down", "Shift_L"), ("key_down", "a"), ("key_up", "a"), ("key_up", "Shift_L"),
                  ("key_up", "Control_L")]


def test_pyautogui_script(device, recorder):
    script = ("import pyautogui, time\npyautogui.moveTo(200, 210)\npyautogui.click(220, 230, button='right')\n"
              "pyautogui.doubleClick(240, 250)\npyautogui.scroll(-2)\npyautogui.hotkey('ctrl', 'a')\n")
    assert device.act(A.Pyautogui(script=script)).ok
    ev = recorder()
    assert presses(ev) == [(3, 220, 230), (1, 240, 250), (1, 240, 250), (5, 240, 250), (5, 240, 250)], \
        " ".join(f"{e['type']}:{e.get('button', e.get('key', ''))}@{e['x']},{e['y']}t{e['time']}" for e in ev)
    assert [e["key"] for e in ev if e["type"] == "key_down"] == ["Control_L", "a"]
    bad = device.act(A.Pyautogui(script="pyautogui.nosuchcall()"))
    assert not bad.ok and "AttributeError" in bad.error and device.health().desktop


def test_wait_done_fail(device):
    t0 = time.monotonic()
    assert device.act(A.Wait(seconds=0.3)).ok and time.monotonic() - t0 >= 0.3
    assert device.act(A.Done()).ok and device.act(A.Fail()).ok


TEXT = "Exact: <tag attr='1'> {braces} [x] & | ~ ` \\ — Zoë, naïve, ß, €5, 中文, ё\tend\nline 2 ~!@#$%^&*()_+"


def in_mousepad(device, launch, path: str) -> None:
    """Mousepad on a new file at `path`, the active window."""
    device.run(f"rm -f {path}; mkdir -p /home/user/Documents")
    launch("mousepad", path)
    r = device.run("for i in $(seq 600); do xdotool search --onlyvisible --class mousepad windowactivate "
                   "2>/dev/null; xdotool getactivewindow getwindowname | grep -q Mousepad && exit 0; sleep 0.05;"
                   " done; exit 1", timeout=60)
    assert r.returncode == 0, "mousepad never became the active window"


def test_typing_is_exact_in_a_real_editor(device, launch):
    path = "/home/user/Documents/typed.txt"
    in_mousepad(device, launch, path)
    assert device.act(A.Typing(text=TEXT)).ok
    # KEY_DOWN/KEY_UP of a character the layout lacks press and release one key; HOTKEY shift+a is "A".
    assert device.act(A.KeyDown(key="ü")).ok and device.act(A.KeyUp(key="ü")).ok
    assert device.act(A.Hotkey(keys=["shift", "a"])).ok
    assert device.act(A.Hotkey(keys=["ctrl", "s"])).ok
    want = TEXT + "üA"
    wait_for(lambda: device.run(f"cat {path}").stdout == want, what="the typed file saved")
    assert device.download(path).decode("utf-8") == want


def test_typing_stays_exact_after_a_script_rebound_the_spare_keys(device, launch):
    """A PYAUTOGUI script runs in a child process with an X connection of its own, and binds the characters it
    types to the server's spare keycodes too (300 distinct ones: every spare keycode anew): the server's typing
    afterwards still types what it is asked, not what the script left bound."""
    path = "/home/user/Documents/rebound.txt"
    in_mousepad(device, launch, path)
    by_script = "".join(chr(0x5000 + i) for i in range(300))
    assert device.act(A.Typing(text="中")).ok
    assert device.act(A.Pyautogui(script=f"import pyautogui\npyautogui.write({by_script!r})\n")).ok
    assert device.act(A.Typing(text="中文")).ok
    assert device.act(A.Hotkey(keys=["ctrl", "s"])).ok
    want = "中" + by_script + "中文"
    wait_for(lambda: device.run(f"cat {path}").stdout == want, what="the typed file saved")


# -- files, commands, applications ------------------------------------------------------------------------------

def test_files_round_trip(device):
    data = bytes(range(256)) * 1000
    device.upload("/home/user/Downloads/sub/blob.bin", data)
    assert device.download("/home/user/Downloads/sub/blob.bin") == data
    assert device.run("stat -c %U /home/user/Downloads/sub/blob.bin").stdout.strip() == "user"
    device.upload("/opt/rootonly/x.txt", b"root")  # a path the desktop user cannot write: through sudo
    assert device.download("/opt/rootonly/x.txt") == b"root"


def test_run_command(device):
    r = device.run("echo out; echo err >&2; exit 3")
    assert (r.returncode, r.stdout, r.stderr) == (3, "out\n", "err\n")
    assert device.run("id -un").stdout.strip() == "user"
    assert device.run("id -un", user="root").stdout.strip() == "root"
    assert device.run("printf %s 'ünï <>{}'").stdout == "ünï <>{}"


@pytest.mark.parametrize("user", [None, "root"])
def test_a_command_that_times_out_is_killed_with_its_children(device, user):
    t0 = time.monotonic()
    r = device.run("sleep 41 & sleep 42; echo never", timeout=1, user=user)
    assert r.returncode == 124 and "never" not in r.stdout and "timed out" in r.stderr
    assert time.monotonic() - t0 < 5
    assert device.run("pgrep -f 'sleep 4[12]'").stdout == ""


def test_launch_shows_a_window(device, launch):
    launch("ristretto")
    assert window_box(device, "ristretto")[2] > 100
    with pytest.raises(Exception, match="no application 'nosuchapp'"):
        device.launch("nosuchapp")


def test_launch_returns_once_the_window_is_there(device, launch):
    """A launch answers when the application's window shows (not a splash screen), so the screenshot after it
    shows the application; a file opened into a tab of an existing window counts by its changed title; a
    program without a window makes it give up after the wait."""
    # one name at a time: a window that closes between the search and the read (a transient one, under load) is
    # skipped rather than ending the whole listing with BadWindow, as `getwindowname %@` did once in CI
    shown = "for w in $(xdotool search --onlyvisible --name .); do xdotool getwindowname $w 2>/dev/null; done; true"
    device.run("touch /tmp/launch_a.txt /tmp/launch_b.txt", user="user")  # unmodified: nothing to restore later
    assert launch("mousepad", "/tmp/launch_a.txt")
    assert "launch_a.txt - Mousepad" in device.run(shown, user="user").stdout  # at once: no polling here
    assert launch("mousepad", "/tmp/launch_b.txt")
    assert "launch_b.txt - Mousepad" in device.run(shown, user="user").stdout
    # GIMP shows a splash screen for seconds before its main window (no file given: a missing one's error message
    # is a window of its own, which under load came before the main window and rightly ended the wait)
    assert launch("gimp")
    assert "GNU Image Manipulation Program" in device.run(shown, user="user").stdout
    device.run("pkill -x gimp-2.10; pkill -x gimp; true")
    wait_for(lambda: "GIMP" not in device.run(shown, user="user").stdout, 20, "GIMP gone")
    t0 = time.monotonic()
    assert launch("sleep", "30", window_wait=1.0) is False
    assert 1.0 <= time.monotonic() - t0 < 10


def test_chromium_runs_without_background_networking_and_shows_pages_to_accessibility(device, launch):
    launch("chromium", "data:text/html,<title>Jarvis page</title><button>Press me</button>")
    window_box(device, "chromium")
    flags = device.run("tr '\\0' ' ' </proc/$(pgrep -o -x chromium)/cmdline").stdout
    for flag in ("--disable-background-networking", "--disable-component-update", "--no-first-run",
                 "--disable-sync"):
        assert flag in flags, f"chromium runs without {flag}: {flags}"
    wait_for(lambda: "Press me" in json.dumps(device.a11y_tree(max_nodes=3000, timeout=10)), 60,
             "the page's button in the accessibility tree")


def app_node(tree: dict, name: str) -> dict | None:
    return next((c for c in tree["tree"].get("children", []) if c["name"] == name), None)


def test_libreoffice_writer_is_accessible(device, launch):
    launch("libreoffice", "--writer", "--norestore", process="soffice.bin")
    window_box(device, "libreoffice-writer", timeout=90)
    soffice = wait_for(lambda: app_node(device.a11y_tree(max_nodes=3000, timeout=15), "soffice"), 60,
                       "LibreOffice in the accessibility tree")
    assert '"role": "document text"' in json.dumps(soffice), "no Writer document in LibreOffice's tree"


def test_dark_mode_and_wallpaper_through_xfconf(device, launch):
    """Desktop settings are xfconf properties that the running desktop applies (xfsettingsd, xfdesktop)."""
    assert device.run("convert -size 64x64 xc:'#e01010' /tmp/red.png").returncode == 0  # ImageMagick
    ws = "/backdrop/screen0/monitorscreen/workspace0"
    r = device.run(f"xfconf-query -c xfce4-desktop -p {ws}/image-style -s 5 && "
                   f"xfconf-query -c xfce4-desktop -p {ws}/last-image -n -t string -s /tmp/red.png")
    assert r.returncode == 0, r.stderr
    red = lambda: (p := screen(device).getpixel((1000, 600)))[0] > 200 and p[1] < 60  # noqa: E731
    wait_for(red, what="a red wallpaper")

    launch("mousepad")
    x, y, w, h = window_box(device, "mousepad")
    area = (x + w // 4, y + h // 2, x + 3 * w // 4, y + 3 * h // 4)  # inside the text view
    mean = lambda: ImageStat.Stat(screen(device).crop(area).convert("L")).mean[0]  # noqa: E731
    theme = device.run("xfconf-query -c xsettings -p /Net/ThemeName").stdout.strip()
    light = wait_for(lambda: (m := mean()) > 150 and m, what="a light text view")
    device.run("xfconf-query -c xsettings -p /Net/ThemeName -s Adwaita-dark")
    wait_for(lambda: mean() < light - 100, what="a dark text view")
    device.run(f"xfconf-query -c xsettings -p /Net/ThemeName -s {theme}")
    device.run(f"xfconf-query -c xfce4-desktop -p {ws}/image-style -r; "
               f"xfconf-query -c xfce4-desktop -p {ws}/last-image -r")
    wait_for(lambda: not red(), what="the default background back")


# -- accessibility ------------------------------------------------------------------------------------------------

def test_accessibility_tree(device, launch):
    launch("mousepad")
    window_box(device, "mousepad")
    tree = wait_for(lambda: (t := device.a11y_tree(max_nodes=500)) and app_node(t, "mousepad") and t,
                    what="mousepad in the accessibility tree")
    assert tree["nodes"] <= 500 and tree["tree"]["role"] == "desktop frame"
    assert app_node(tree, "xfdesktop") and app_node(tree, "xfce4-panel")
    frame = app_node(tree, "mousepad")["children"][0]
    assert frame["role"] == "frame" and "Mousepad" in frame["name"] and "showing" in frame["states"]
    x, y, w, h = frame["box"]
    assert w > 100 and h > 100 and 0 <= x < 1920 and 0 <= y < 1080
    everything = device.a11y_tree(max_nodes=5000, showing_only=False)
    assert everything["nodes"] > device.a11y_tree(max_nodes=5000)["nodes"], "hidden menus are not skipped"
    small = device.a11y_tree(max_nodes=5)
    assert small["nodes"] == 5 and small["truncated"]


def test_accessibility_limits_are_checked(booted):
    for params in ({"max_nodes": 0}, {"timeout": "soon"}, {"max_depth": -1}, {"timeout": 1000}):
        resp = httpx.get(f"{booted.url}/a11y", params=params)
        assert resp.status_code == 400 and "max_nodes" in resp.json()["error"]


# -- bad input and concurrency ----------------------------------------------------------------------------------

@pytest.mark.parametrize("body, needle", [
    ({"type": "CLICK", "x": 5000, "y": 10}, "off the 1920x1080 screen"),
    ({"type": "CLIK", "x": 1, "y": 1}, "invalid request"),
    ({"type": "HOTKEY", "keys": ["ctrl", "nosuchkey"]}, "unknown key name"),
    ({"type": "SYSTEM_BUTTON", "button": "home"}, "not supported on ubuntu"),
    ({"type": "TYPING"}, "text"),
    ({"type": "DRAG_TO", "x": -1, "y": 5}, "off the"),
])
def test_bad_actions_are_4xx_and_the_server_stays_up(booted, device, body, needle):
    url = booted.url
    resp = httpx.post(f"{url}/action", json=body)
    assert 400 <= resp.status_code < 500 and needle in resp.json()["error"]
    assert httpx.post(f"{url}/action", content=b"{not json").status_code == 400
    assert httpx.get(f"{url}/files", params={"path": "relative"}).status_code == 400
    assert httpx.get(f"{url}/files", params={"path": "/no/such/file"}).status_code == 404
    assert httpx.post(f"{url}/run", json={"command": ""}).status_code == 400
    assert httpx.get(f"{url}/nowhere").status_code == 404
    check_refusals_keep_the_server_usable(device, url)


def test_concurrent_requests(device):
    check_concurrent_requests(device, rounds=5)
