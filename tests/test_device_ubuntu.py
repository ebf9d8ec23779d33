"""The Ubuntu device through its control server, on a real container: observation, every action by its
effect, exact typing into a real editor, files, commands, applications, accessibility, bad input."""

from __future__ import annotations

import io
import json
import time
from pathlib import Path

import httpx
import pytest
from PIL import Image, ImageStat

from jarvis_pytest.devices import actions as A

pytestmark = pytest.mark.containers
RECORDER = Path(__file__).parent / "data" / "device" / "event_recorder.py"


@pytest.fixture(scope="module")
def device(ubuntu_env):
    return ubuntu_env.devices["ubuntu"]


def wait_for(predicate, timeout: float = 10.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError("condition not met in time")


@pytest.fixture
def recorder(device):
    """A full-screen window inside the device that logs the input events it gets; yields a reader."""
    device.upload("/tmp/recorder.py", RECORDER.read_bytes())
    device.run("rm -f /tmp/events.log")
    device.launch("python3", "/tmp/recorder.py", "/tmp/events.log")
    events = lambda: [json.loads(l) for l in device.download("/tmp/events.log").decode().splitlines()]  # noqa: E731
    wait_for(lambda: device.run("test -s /tmp/events.log").returncode == 0 and events())
    device.run("truncate -s 0 /tmp/events.log")

    def read() -> list[dict]:
        """Every event logged so far: a sentinel move is sent last and waited for (X delivers in order)."""
        device.act(A.MoveTo(x=1919, y=1079))
        is_sentinel = lambda e: e["type"] == "motion" and (e["x"], e["y"]) == (1919, 1079)  # noqa: E731
        logged = wait_for(lambda: (ev := events()) and any(map(is_sentinel, ev)) and ev, 10)
        return [e for e in logged if not is_sentinel(e)]

    yield read
    device.run("pkill -f /tmp/recorder.py")


def test_screenshot_is_the_desktop(device):
    obs = device.observe()
    img = Image.open(io.BytesIO(obs.screenshot_png))
    assert img.size == (1920, 1080) == (obs.width, obs.height) == device.screen_size()
    assert max(ImageStat.Stat(img.convert("L")).stddev) > 5, "the screenshot is blank"


def test_pointer_is_drawn(device):
    device.act(A.MoveTo(x=900, y=500))
    near = Image.open(io.BytesIO(device.observe().screenshot_png)).crop((900, 500, 912, 517)).convert("L")
    device.act(A.MoveTo(x=100, y=900))
    after = Image.open(io.BytesIO(device.observe().screenshot_png)).crop((900, 500, 912, 517)).convert("L")
    assert near.tobytes() != after.tobytes()


def presses(events, kind="press"):
    return [(e["button"], e["x"], e["y"]) for e in events if e["type"] == kind]


def test_clicks(device, recorder):
    assert device.act(A.Click(x=300, y=400)).ok
    assert device.act(A.RightClick(x=310, y=410)).ok
    assert device.act(A.DoubleClick(x=320, y=420)).ok
    assert device.act(A.Click(x=330, y=430, button="middle", clicks=3)).ok
    assert presses(recorder()) == [(1, 300, 400), (3, 310, 410), (1, 320, 420), (1, 320, 420),
                                   (2, 330, 430), (2, 330, 430), (2, 330, 430)]


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


TEXT = "Exact: <tag attr='1'> {braces} [x] & | ~ ` \\ — Zoë, naïve, ß, €5\tend"


def test_typing_is_exact_in_a_real_editor(device):
    path = "/home/user/Documents/typed.txt"
    device.run(f"rm -f {path}; mkdir -p /home/user/Documents")
    device.launch("mousepad", path)
    device.run("for i in $(seq 200); do xdotool search --onlyvisible --class mousepad windowactivate 2>/dev/null;"
               " xdotool getactivewindow getwindowname | grep -q Mousepad && exit 0; sleep 0.05; done; exit 1")
    assert device.act(A.Typing(text=TEXT)).ok
    assert device.act(A.Hotkey(keys=["ctrl", "s"])).ok
    wait_for(lambda: device.run(f"test -s {path}").returncode == 0)
    assert device.download(path).decode("utf-8") == TEXT
    device.run("pkill mousepad")


def test_pyautogui_script(device, recorder):
    script = ("import pyautogui, time\npyautogui.moveTo(200, 210)\npyautogui.click(220, 230, button='right')\n"
              "pyautogui.doubleClick(240, 250)\npyautogui.scroll(-2)\npyautogui.hotkey('ctrl', 'a')\n")
    assert device.act(A.Pyautogui(script=script)).ok
    ev = recorder()
    assert presses(ev) == [(3, 220, 230), (1, 240, 250), (1, 240, 250), (5, 240, 250), (5, 240, 250)]
    assert [e["key"] for e in ev if e["type"] == "key_down"] == ["Control_L", "a"]
    bad = device.act(A.Pyautogui(script="pyautogui.nosuchcall()"))
    assert not bad.ok and "AttributeError" in bad.error and device.health().desktop


def test_wait_done_fail(device):
    t0 = time.monotonic()
    assert device.act(A.Wait(seconds=0.3)).ok and time.monotonic() - t0 >= 0.3
    assert device.act(A.Done()).ok and device.act(A.Fail()).ok


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
    assert device.run("sleep 5", timeout=0.5).returncode == 124


def test_launch_shows_a_window(device):
    device.launch("ristretto")
    assert device.run("timeout 15 xdotool search --sync --onlyvisible --class ristretto").returncode == 0
    device.run("pkill ristretto")


def test_accessibility_tree(device):
    device.launch("mousepad")
    device.run("timeout 15 xdotool search --sync --onlyvisible --class mousepad")
    tree = wait_for(lambda: (t := device.a11y_tree(max_nodes=500)) and "mousepad" in json.dumps(t).lower() and t)
    assert tree["nodes"] <= 500 and tree["tree"]["role"] == "desktop frame"
    small = device.a11y_tree(max_nodes=5)
    assert small["nodes"] == 5 and small["truncated"]
    device.run("pkill mousepad")


@pytest.mark.parametrize("body, needle", [
    ({"type": "CLICK", "x": 5000, "y": 10}, "off the 1920x1080 screen"),
    ({"type": "CLIK", "x": 1, "y": 1}, "invalid request"),
    ({"type": "HOTKEY", "keys": ["ctrl", "nosuchkey"]}, "unknown key name"),
    ({"type": "SYSTEM_BUTTON", "button": "home"}, "Android"),
    ({"type": "TYPING"}, "text"),
])
def test_bad_actions_are_4xx_and_the_server_stays_up(ubuntu_env, device, body, needle):
    url = ubuntu_env.urls["ubuntu"]
    resp = httpx.post(f"{url}/action", json=body)
    assert 400 <= resp.status_code < 500 and needle in resp.json()["error"]
    assert httpx.post(f"{url}/action", content=b"{not json").status_code == 400
    assert httpx.get(f"{url}/files", params={"path": "relative"}).status_code == 400
    assert httpx.get(f"{url}/files", params={"path": "/no/such/file"}).status_code == 404
    assert httpx.post(f"{url}/run", json={"command": ""}).status_code == 400
    assert httpx.get(f"{url}/nowhere").status_code == 404
    assert device.health().desktop
    assert not device.act(A.SystemButton(button="home")).ok
