"""The browser player without devices: a displayed point to the device pixel, a key to HOTKEY and text to TYPING
(`player/inputs.py`), the agent `human` waiting for a person's inputs in the step loop's thread (`player/agent.py`),
its server's guards (`player/server.py`), the loop not holding a person to --step-timeout, the replay keeping a
person's pace, a run saved as a GUI solution (`player/solution.py`) and the time rows of the summary. The
browser test (`test_player_browser.py`) plays a real task through the page."""

from __future__ import annotations

import ast
import json
import threading
import time
from pathlib import Path

import httpx
import pytest

from jarvis_pytest.agents.oracle import brief
from jarvis_pytest.agents.protocol import AgentStep, HistoryEntry, TaskContext
from jarvis_pytest.agents.registry import load_agent
from jarvis_pytest.devices import actions as A
from jarvis_pytest.devices.base import ActionOutcome, Observation
from jarvis_pytest.errors import ConfigError, InfrastructureError
from jarvis_pytest.llm.deadline import deadline_at
from jarvis_pytest.player import inputs as I
from jarvis_pytest.player.agent import HumanAgent, ScreenView
from jarvis_pytest.player.solution import gui_steps, save, with_placeholders
from jarvis_pytest.harness.loop import LoopLimits, StepDeadline, run_loop
from jarvis_pytest.report.rollup import render_markdown, render_terminal, rollup
from jarvis_pytest.results.model import StepRecord, TaskResult
from jarvis_pytest.results.writer import TaskRecorder

REPO = Path(__file__).resolve().parents[1]
SCREEN = (1920, 1080)
PNG = b"\x89PNG\r\n\x1a\n" + b"\0" * 8 + (1920).to_bytes(4, "big") + (1080).to_bytes(4, "big")
TASK = TaskContext(task_id="ubuntu-probe[seed0]", instruction="do it", platforms=("ubuntu",))


# -- a displayed point to a device pixel -------------------------------------------------------------------------

@pytest.mark.parametrize("shown, point, expected", [
    ((960, 540), (100.4, 50.9), (200, 101)),       # half size: doubled, floored
    ((960, 540), (959.9, 539.9), (1919, 1079)),    # the last displayed pixel is the last device pixel
    ((1100, 618.75), (550, 309.375), (960, 540)),  # a scale that is no whole ratio: the centre stays the centre
    ((1100, 618.75), (0.4, 0.4), (0, 0)),
    ((960, 540), (-5, 2000), (0, 1079)),           # past the image's edge: clamped to the screen
    ((1920, 1080), (1005.5, 481.5), (1005, 481)),  # shown at its own size: the same pixel
])
def test_a_displayed_point_maps_to_the_device_pixel_under_it(shown, point, expected):
    assert I.to_device(*point, *shown, *SCREEN) == expected


def test_every_device_pixel_is_reached_from_the_middle_of_its_displayed_area():
    """What the browser test relies on: aiming at ((x + 0.5)·w/W) hits device pixel x, for sizes a page shows."""
    for w, h in ((1257, 707), (960, 540), (1100, 618.75), (2400, 1350)):
        for x in range(0, 1920, 7):
            y = x * 1080 // 1920
            assert I.to_device((x + 0.5) * w / 1920, (y + 0.5) * h / 1080, w, h, *SCREEN) == (x, y)


@pytest.mark.parametrize("bad", [(float("nan"), 1, 10, 10), (1, 1, 0, 10), (1, float("inf"), 10, 10),
                                 (True, 1, 10, 10)])
def test_a_point_that_is_not_a_point_is_refused(bad):
    with pytest.raises(I.InputRefused):
        I.to_device(*bad, *SCREEN)


# -- keys --------------------------------------------------------------------------------------------------------

def key(k: str, code: str = "", **mods) -> dict:
    return {"kind": "key", "key": k, "code": code, **mods}


@pytest.mark.parametrize("event, keys", [
    (key("Enter", "Enter"), ["enter"]),
    (key("Tab", "Tab", shift=True), ["shift", "tab"]),
    (key("Escape", "Escape"), ["esc"]),
    (key("ArrowLeft", "ArrowLeft", shift=True), ["shift", "left"]),
    (key("Backspace", "Backspace"), ["backspace"]),
    (key("F5", "F5"), ["f5"]),
    (key("F4", "F4", alt=True), ["alt", "f4"]),
    (key("End", "End", ctrl=True), ["ctrl", "end"]),
    (key("s", "KeyS", ctrl=True), ["ctrl", "s"]),
    (key("S", "KeyS", ctrl=True, shift=True), ["ctrl", "shift", "s"]),   # by its key, not the capital it prints
    (key("!", "Digit1", ctrl=True, shift=True), ["ctrl", "shift", "1"]),
    (key("z", "KeyY", ctrl=True), ["ctrl", "y"]),                       # a German layout's Z is the Y key's place
    (key("ü", "BracketLeft", ctrl=True), ["ctrl", "ü"]),
    (key(" ", "Space", ctrl=True), ["ctrl", "space"]),
    (key("l", "KeyL", meta=True), ["super", "l"]),
    (key("t", "KeyT", ctrl=True, alt=True), ["ctrl", "alt", "t"]),
])
def test_a_key_press_is_a_hotkey_of_device_key_names(event, keys):
    assert I.key_action(event) == A.Hotkey(keys=keys)


@pytest.mark.parametrize("event", [
    key("a", "KeyA"), key("A", "KeyA", shift=True), key(" ", "Space"), key("é", "KeyE"),  # characters: text
    key("Control", "ControlLeft", ctrl=True), key("Shift", "ShiftLeft", shift=True), key("Dead", "BracketLeft"),
    key("@", "KeyQ", ctrl=True, alt=True, altgraph=True),  # AltGr's character comes as text
])
def test_a_key_that_types_or_only_modifies_sends_no_key(event):
    assert I.key_action(event) is None


def test_an_unknown_key_is_refused():
    with pytest.raises(I.InputRefused, match="unknown key 'Launch'"):
        I.key_action(key("Launch", "LaunchApp1"))


def _dict_literal(path: Path, name: str) -> dict:
    """A module-level dict literal of a device server (they import X11 or Win32 modules the host lacks)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == name for t in node.targets):
            return ast.literal_eval(node.value)
    raise LookupError(name)


def test_every_key_name_the_player_sends_is_one_the_devices_know():
    ubuntu = _dict_literal(REPO / "jarvis_pytest/devices/ubuntu/server/xinput.py", "KEY_ALIASES")
    windows = _dict_literal(REPO / "jarvis_pytest/devices/windows/server/input.py", "VK")
    from jarvis_pytest.devices.android.commands import _NAMED as android

    sent = set(I.NAMED_KEYS.values()) | {name for _, name in I.MODIFIER_ORDER} | {"space"}
    f_keys = {k for k in sent if k[0] == "f" and k[1:].isdigit()}
    assert sent - f_keys <= set(ubuntu) and sent - f_keys <= set(windows), (sent - set(ubuntu), sent - set(windows))
    assert (sent - f_keys) <= set(android) | {"super"} and "super" in android
    assert {f"f{n}" for n in range(1, 25)} == f_keys  # Ubuntu: keysym F<n>; Windows: VK.update(f1..f24)


def test_the_page_forwards_the_keys_the_server_names():
    """player.js sends a key press for exactly the keys inputs.NAMED_KEYS names (and no silent key)."""
    js = (REPO / "jarvis_pytest/player/static/player.js").read_text(encoding="utf-8")
    named = set(js.split("const NAMED = new Set([", 1)[1].split("...Array", 1)[0].replace("\n", "").split(","))
    named = {n.strip().strip('"') for n in named if n.strip()}
    assert named | {f"F{n}" for n in range(1, 25)} == set(I.NAMED_KEYS)
    silent = js.split("const SILENT = new Set([", 1)[1].split("]);", 1)[0]
    assert {s.strip().strip('"') for s in silent.replace("\n", "").split(",")} == set(I.SILENT_KEYS)


# -- events, and events that make one action -----------------------------------------------------------------------

def ev(kind: str, **fields) -> dict:
    return {"kind": kind, "platform": "ubuntu", **fields}


def test_events_become_actions_in_device_pixels():
    at = 10.0
    click = I.translate(ev("click", x=480, y=270, w=960, h=540, detail=1), SCREEN, at)
    assert click.action == A.Click(x=960, y=540) and click.merges == "click"
    assert I.translate(ev("click", button="right", x=10, y=10, w=960, h=540), SCREEN, at).action == \
        A.RightClick(x=20, y=20)
    assert I.translate(ev("click", button="middle", x=10, y=10, w=960, h=540), SCREEN, at).action == \
        A.Click(x=20, y=20, button="middle")
    drag = I.translate(ev("drag", start_x=10, start_y=20, x=110, y=220, w=960, h=540), SCREEN, at)
    assert drag.action == A.DragTo(start_x=20, start_y=40, x=220, y=440)
    assert I.translate(ev("scroll", x=480, y=270, w=960, h=540, dy=300), SCREEN, at).action == \
        A.Scroll(dx=0, dy=3, x=960, y=540)
    assert I.translate(ev("scroll", x=1, y=1, w=960, h=540, dy=-3, mode=1), SCREEN, at).action.dy == -1
    assert I.translate(ev("scroll", x=1, y=1, w=960, h=540, dy=40), SCREEN, at).action.dy == 1  # a touchpad's nudge
    assert I.translate(ev("text", text="Grüße\r\n東京"), SCREEN, at).action == A.Typing(text="Grüße\n東京")
    assert I.translate(ev("keys", combo="Ctrl+W"), SCREEN, at).action == A.Hotkey(keys=["ctrl", "w"])
    assert I.translate(ev("done"), SCREEN, at).action == A.Done()
    assert I.translate(ev("key", key="Shift", code="ShiftLeft", shift=True), SCREEN, at) is None
    with pytest.raises(I.InputRefused, match="no screen of ubuntu"):
        I.translate(ev("click", x=1, y=1, w=2, h=2), None, at)
    with pytest.raises(I.InputRefused, match="unknown input kind"):
        I.translate(ev("pinch", x=1, y=1, w=2, h=2), SCREEN, at)
    with pytest.raises(I.InputRefused, match="combo"):
        I.translate(ev("keys", combo="ctrl++"), SCREEN, at)
    with pytest.raises(I.InputRefused, match="not a valid TYPING"):
        I.translate(ev("text", text="x" * 10_001), SCREEN, at)


def test_text_typed_in_a_row_is_one_typing_until_a_pause():
    a = I.translate(ev("text", text="Fri"), SCREEN, 0.0)
    b = I.translate(ev("text", text="day"), SCREEN, 0.5)
    ab = I.merge(a, b)
    assert ab.action == A.Typing(text="Friday") and ab.events == 2 and ab.at == 0.5
    late = I.translate(ev("text", text="!"), SCREEN, 0.5 + I.TEXT_IDLE + 0.01)
    assert I.merge(ab, late) is None  # after a pause: a TYPING of its own
    other = {**ev("text", text="x"), "platform": "windows"}
    assert I.merge(ab, I.translate(other, SCREEN, 0.6)) is None  # another device


def test_a_second_click_in_place_is_a_double_click_and_wheel_turns_add_up():
    first = I.translate(ev("click", x=100, y=100, w=1920, h=1080, detail=1), SCREEN, 0.0)
    second = I.translate(ev("click", x=103, y=101, w=1920, h=1080, detail=2), SCREEN, 0.2)
    double = I.merge(first, second)
    assert double.action == A.Click(x=100, y=100, clicks=2)
    third = I.translate(ev("click", x=100, y=100, w=1920, h=1080, detail=3), SCREEN, 0.3)
    assert I.merge(double, third).action.clicks == 3
    away = I.translate(ev("click", x=300, y=100, w=1920, h=1080, detail=2), SCREEN, 0.2)
    assert I.merge(first, away) is None  # elsewhere: another click
    again = I.translate(ev("click", x=100, y=100, w=1920, h=1080, detail=1), SCREEN, 0.2)
    assert I.merge(first, again) is None  # the browser did not count it as the second click
    w1 = I.translate(ev("scroll", x=50, y=50, w=1920, h=1080, dy=60), SCREEN, 0.0)
    w2 = I.translate(ev("scroll", x=52, y=50, w=1920, h=1080, dy=60), SCREEN, 0.1)
    assert I.merge(w1, w2).action == A.Scroll(dy=1, x=50, y=50)  # 120 px: one notch, not two rounded up
    w3 = I.translate(ev("scroll", x=50, y=50, w=1920, h=1080, dy=100), SCREEN, 0.2)
    assert I.merge(I.merge(w1, w2), w3).action.dy == 2


def test_a_touch_screen_takes_gestures_and_system_buttons_and_a_desktop_a_resting_pointer():
    """Android's screen (`PlatformSpec.touch`): a drag is a SWIPE at its own speed, a press held 0.6 s or longer a
    LONG_PRESS, the page's buttons SYSTEM_BUTTON; a desktop's drag stays DRAG_TO, a held click a CLICK, and the
    mouse at rest a MOVE_TO, which a touch screen has no pointer for."""
    phone, shown = (1080, 2400), {"w": 108, "h": 240}
    swipe = I.translate({"platform": "android", "kind": "drag", "start_x": 54, "start_y": 200, "x": 54, "y": 40,
                         "held_ms": 250, **shown}, phone, 0.0)
    assert swipe.action == A.Swipe(x=540, y=2000, dx=0, dy=-1600, duration=250)
    held = {"platform": "android", "kind": "click", "x": 10, "y": 20, "held_ms": 900, **shown}
    assert I.translate(held, phone, 0.0).action == A.LongPress(x=100, y=200, duration=900)
    assert I.translate({**held, "held_ms": 200}, phone, 0.0).action == A.Click(x=100, y=200)
    assert I.translate({**held, "held_ms": 99_999}, phone, 0.0).action.duration == I.GESTURE_MS[1]
    assert I.translate({"platform": "android", "kind": "button", "button": "back"}, None, 0.0).action == \
        A.SystemButton(button="back")
    with pytest.raises(I.InputRefused, match="not a valid SYSTEM_BUTTON"):
        I.translate({"platform": "android", "kind": "button", "button": "recents"}, None, 0.0)
    with pytest.raises(I.InputRefused, match="has no system buttons"):
        I.translate({"platform": "ubuntu", "kind": "button", "button": "home"}, SCREEN, 0.0)
    desk = {"platform": "ubuntu", "x": 96, "y": 54, "w": 192, "h": 108}
    assert I.translate({**desk, "kind": "click", "held_ms": 900}, SCREEN, 0.0).action == A.Click(x=960, y=540)
    assert I.translate({**desk, "kind": "drag", "start_x": 0, "start_y": 0}, SCREEN, 0.0).action == \
        A.DragTo(start_x=0, start_y=0, x=960, y=540)
    assert I.translate({**desk, "kind": "hover"}, SCREEN, 0.0).action == A.MoveTo(x=960, y=540)
    assert I.translate({**desk, "platform": "android", "kind": "hover"}, phone, 0.0) is None


# -- the agent `human` in the loop's thread --------------------------------------------------------------------------

def observation(platform: str = "ubuntu") -> Observation:
    return Observation(platform=platform, screenshot_png=PNG, width=1920, height=1080)


class Step:
    """`agent.act` in a thread, as the loop calls it (under the step's deadline)."""

    def __init__(self, agent: HumanAgent, history: list[HistoryEntry] | None = None, seconds: float = 10.0):
        self.value: AgentStep | None = None
        self.thread = threading.Thread(target=self._run, args=(agent, history or [], seconds), daemon=True)
        self.thread.start()
        deadline = time.monotonic() + 5
        while not agent.player.waiting and self.thread.is_alive() and time.monotonic() < deadline:
            time.sleep(0.01)

    def _run(self, agent, history, seconds):
        with deadline_at(time.monotonic() + seconds):
            self.value = agent.act({"ubuntu": observation(), "android": Observation("android", b"", 1, 1,
                                                                                      available=False)}, history)

    def result(self) -> AgentStep:
        self.thread.join(10)
        assert self.value is not None
        return self.value


@pytest.fixture
def human():
    agent = load_agent("human", {})
    agent.reset(TASK)
    yield agent
    agent.close()


def test_the_person_input_is_the_step_and_the_time_they_took_is_recorded(human):
    step = Step(human)
    time.sleep(0.3)
    human.player.frame("ubuntu")  # the page shows the step's screen...
    time.sleep(0.4)  # ...and the person thinks
    assert human.player.receive(ev("click", seq=1, x=480, y=270, w=960, h=540, detail=1))["accepted"]
    got = step.result()
    assert got.platform == "ubuntu" and got.action == A.Click(x=960, y=540)
    said = got.extra["player"]
    assert 380 <= said["think_ms"] <= 1500 and said["queued"] is False and said["input"]["kind"] == "click"


def test_inputs_made_ahead_are_carried_out_in_order_and_done_ends_the_task(human):
    step = Step(human)
    p = human.player
    p.receive(ev("text", seq=1, text="Fri"))
    p.receive(ev("text", seq=2, text="day"))
    p.receive(ev("key", seq=3, key="s", code="KeyS", ctrl=True))
    assert p.receive(ev("text", seq=3, text="again")) == {"accepted": False, "duplicate": True}  # sent twice
    p.receive(ev("done", seq=4))
    with pytest.raises(I.InputRefused, match="has ended"):  # nothing after DONE
        p.receive(ev("text", seq=5, text="late"))
    first = step.result()
    assert first.action == A.Typing(text="Friday") and first.extra["player"]["events"] == 2
    second = Step(human, [HistoryEntry(0, "ubuntu", "", {"type": "TYPING"})]).result()
    assert second.action == A.Hotkey(keys=["ctrl", "s"])
    assert second.extra["player"]["queued"] is True and second.extra["player"]["think_ms"] == 0
    third = Step(human, [HistoryEntry(0, "ubuntu", "", {}), HistoryEntry(1, "ubuntu", "", {}, "no such key")])
    assert third.result().action == A.Done()
    state = p.state()
    assert state["ending"] == "done" and state["last_error"] == "no such key" and state["log"][1]["error"] == "no such key"


def test_text_is_sent_once_the_person_pauses(human):
    step = Step(human)
    human.player.receive(ev("text", seq=1, text="olive oil"))
    t0 = time.monotonic()
    got = step.result()
    assert got.action == A.Typing(text="olive oil") and time.monotonic() - t0 >= I.TEXT_IDLE - 0.05


def test_what_the_player_refuses(human):
    p = human.player
    with pytest.raises(I.InputRefused, match="does not use 'windows'"):
        p.receive({**ev("text", seq=1, text="x"), "platform": "windows"})
    with pytest.raises(I.InputRefused, match="sequence number"):
        p.receive(ev("text", text="x"))
    with pytest.raises(I.InputRefused, match="no screen of ubuntu"):  # no step has shown one yet
        p.receive(ev("click", seq=2, x=1, y=1, w=2, h=2))
    fresh = HumanAgent({})
    with pytest.raises(I.InputRefused, match="no task has started"):
        fresh.player.receive(ev("text", seq=1, text="x"))
    with pytest.raises(ConfigError, match="port"):
        HumanAgent({"port": "http"})


def test_a_person_who_does_not_act_by_the_deadline_gives_an_error_step(human):
    t0 = time.monotonic()
    got = Step(human, seconds=0.5).result()
    assert got.action is None and "no input" in got.error and time.monotonic() - t0 < 3


def test_a_closed_page_ends_the_task_as_the_persons_fail():
    """An abandoned tab held the task's devices until the task's time limit: once the page has asked anything, a
    silence of `abandon_after` seconds ends the task with the person's FAIL. A page that keeps asking, or one not
    opened yet, is waited for."""
    agent = HumanAgent({"abandon_after": "0.6"})
    agent.reset(TASK)
    try:
        step = Step(agent, seconds=30)
        time.sleep(1.0)  # no page yet: nothing is abandoned
        for _ in range(6):  # a page that keeps asking
            agent.player.state()
            time.sleep(0.2)
        assert step.value is None and agent.player.waiting
        t0 = time.monotonic()
        got = step.result()  # then the page goes
        assert got.action == A.Fail() and "the person left" in got.reasoning and got.platform == "ubuntu"
        assert 0.4 <= time.monotonic() - t0 < 3
        assert agent.player.state()["ending"] == "fail"
    finally:
        agent.close()
    for bad in ("soon", "0"):
        with pytest.raises(ConfigError, match="abandon_after"):
            HumanAgent({"abandon_after": bad})


def test_the_server_answers_its_page_only(human):
    base = human.url.split("/#token=")[0]
    token = human.url.split("#token=")[1]
    assert base.startswith("http://127.0.0.1:")
    assert human.server.server_address[0] == "127.0.0.1"
    page = httpx.get(base + "/")
    assert page.status_code == 200 and "player.js" in page.text
    assert httpx.get(base + "/api/state").status_code == 403  # no token
    assert httpx.get(base + "/api/state", headers={"X-Player-Token": "guess"}).status_code == 403
    assert httpx.get(base + "/api/state", headers={"X-Player-Token": token, "Host": "evil.example:80"}).status_code \
        == 403  # a DNS-rebinding page
    good = {"X-Player-Token": token}
    state = httpx.get(base + "/api/state", headers=good).json()
    assert state["task"]["id"] == TASK.task_id and state["step"] == -1
    assert httpx.get(base + "/api/frame/ubuntu", headers=good).status_code == 404  # no screen yet
    posted = httpx.post(base + "/api/input", headers=good, json=ev("click", seq=1, x=1, y=1, w=2, h=2))
    assert posted.status_code == 400 and "no screen" in posted.json()["error"]
    assert httpx.post(base + "/api/input", json=ev("text", seq=1, text="x")).status_code == 403
    step = Step(human)
    frame = httpx.get(base + "/api/frame/ubuntu", headers=good)
    assert frame.content == PNG and frame.headers["X-Live"] == "0"  # not briefed: the step's observation
    r = httpx.post(base + "/api/input", headers=good, json=ev("key", seq=2, key="Enter", code="Enter"))
    assert r.status_code == 200 and r.json()["action"] == {"type": "HOTKEY", "keys": ["enter"]}
    assert step.result().action == A.Hotkey(keys=["enter"])
    assert httpx.post(base + "/api/input", headers=good, content=b"[1]").status_code == 400


def test_brief_gives_the_human_agent_screens_and_nothing_else(human):
    class Device:
        def observe(self, a11y=False):
            return observation()

        def run(self, *a, **k):  # a device can run commands; the view must not hand that on
            raise AssertionError("run")

    class LookAlike(HumanAgent):
        pass

    device = Device()
    assert brief(human, [], {"ubuntu": device}) is True
    (view,) = human.player.views.values()
    assert type(view) is ScreenView and view.png() == PNG and not hasattr(view, "run") and ScreenView.__slots__
    png, live = human.player.frame("ubuntu")
    assert png == PNG and live is True
    other = LookAlike({})
    other.reset(TASK)
    try:
        assert brief(other, [], {"ubuntu": device}) is False and other.player.views == {}
    finally:
        other.close()


# -- the loop: a person's step is not a model call ---------------------------------------------------------------

class SlowDevice:
    platform = "ubuntu"

    def observe(self, a11y=False):
        return observation()

    def act(self, action):
        return ActionOutcome(ok=True)


class Slow:
    """Decides after `seconds`; `paced_by_person` as given."""

    name = "slow"

    def __init__(self, seconds: float, paced: bool):
        self.seconds, self.paced_by_person = seconds, paced

    def reset(self, task):
        pass

    def config(self):
        return {"name": self.name}

    def act(self, observations, history):
        time.sleep(self.seconds)
        return AgentStep(platform="ubuntu", action=A.Done())


def _loop(agent, tmp_path):
    result = TaskResult(task_id="probe", category="atomic", platforms=["ubuntu"], instruction="probe",
                        status="running")
    recorder = TaskRecorder(tmp_path, result)
    try:
        return run_loop(agent, {"ubuntu": SlowDevice()}, {}, recorder, LoopLimits(step_timeout=0.3, task_timeout=30))
    finally:
        recorder.finish()


def test_a_person_is_not_held_to_the_step_timeout_a_model_is(tmp_path, monkeypatch):
    monkeypatch.setattr("jarvis_pytest.harness.loop.GRACE", 0.1)  # no grace past the deadline: 0.3 s it is
    assert _loop(Slow(0.8, paced=True), tmp_path / "a").end_reason == "done"
    with pytest.raises(StepDeadline):
        _loop(Slow(0.8, paced=False), tmp_path / "b")
    with pytest.raises(InfrastructureError):  # only the literal True counts, not a truthy attribute
        _loop(Slow(0.8, paced="yes"), tmp_path / "c")


# -- replaying a person's run at their pace ------------------------------------------------------------------------

def trajectory(path: Path, player: bool, agent_ms: float = 400) -> Path:
    extra = {"player": {"think_ms": 300}} if player else {}
    lines = [{"index": 0, "platform": "ubuntu", "action": {"type": "HOTKEY", "keys": ["ctrl", "r"]},
              "agent_ms": agent_ms, "extra": extra},
             {"index": 1, "platform": "ubuntu", "action": {"type": "CLICK", "x": 5, "y": 5}, "agent_ms": agent_ms,
              "extra": extra},
             {"index": 2, "platform": "ubuntu", "action": {"type": "DONE"}, "agent_ms": 1, "extra": extra}]
    path.write_text("".join(json.dumps(line) + "\n" for line in lines))
    return path


def replay_seconds(options: dict) -> tuple[float, list]:
    agent = load_agent("replay", options)
    agent.reset(TASK)
    t0 = time.monotonic()
    steps = [agent.act({}, []) for _ in range(3)]
    return time.monotonic() - t0, steps


def test_a_person_s_run_replays_at_their_pace(tmp_path):
    human = trajectory(tmp_path / "human.jsonl", player=True)
    took, steps = replay_seconds({"file": str(human)})
    assert 0.75 <= took < 2 and [s.action.type for s in steps] == ["HOTKEY", "CLICK", "DONE"]
    assert steps[1].extra == {"replayed": 1, "waited_s": 0.4}
    assert replay_seconds({"file": str(human), "pace": "none"})[0] < 0.3
    assert replay_seconds({"file": str(human), "max_wait": "0.1"})[0] < 0.5
    model = trajectory(tmp_path / "model.jsonl", player=False)
    assert replay_seconds({"file": str(model)})[0] < 0.3  # a model's run: at once, as before
    assert replay_seconds({"file": str(model), "pace": "recorded"})[0] >= 0.75
    with pytest.raises(ConfigError, match="pace"):
        load_agent("replay", {"file": str(model), "pace": "fast"})


# -- a run saved as a GUI solution -----------------------------------------------------------------------------

VALUES = {"text_file": "/home/user/Documents/todo.txt", "old_word": "draft", "new_word": "final",
          "note": "Call Zoë"}


def test_typed_values_become_placeholders_where_they_render_back():
    assert with_placeholders("final", VALUES) == "{{new_word}}"
    assert with_placeholders("draft to final", VALUES) == "{{old_word}} to {{new_word}}"
    assert with_placeholders("todo.txt\n", VALUES) == "{{text_file.name}}\n"
    assert with_placeholders("see todo", VALUES) == "see {{text_file.stem}}"
    assert with_placeholders("nothing of it", VALUES) == "nothing of it"
    assert with_placeholders("{{raw}} final", VALUES) == "{{raw}} final"  # braces of its own: kept as typed


def record(index, action, agent_ms=100.0, error=None, observe_ms=0.0) -> StepRecord:
    return StepRecord(index=index, platform="ubuntu", action=action, agent_ms=agent_ms, error=error,
                      observe_ms=observe_ms)


def test_a_trajectory_becomes_plain_gui_steps_with_its_pace():
    steps, notes = gui_steps([
        record(0, {"type": "HOTKEY", "keys": ["ctrl", "r"]}, agent_ms=4000),
        record(1, {"type": "CLICK", "x": 1005, "y": 481, "button": "left", "clicks": 1}, agent_ms=9000),
        record(2, {"type": "TYPING", "text": "draft"}, agent_ms=100),
        record(3, {"type": "CLICK", "x": 5000, "y": 1}, error="point (5000, 1) is off the screen"),
        record(4, None, error="no input"),
        record(5, {"type": "CLICK", "x": 10, "y": 20}, agent_ms=1200, observe_ms=800),
        record(6, {"type": "DONE"}, agent_ms=3000),
    ], VALUES)
    assert steps == [{"type": "HOTKEY", "keys": ["ctrl", "r"], "note": "recorded: step 0"},  # the task starts ready
                     {"type": "WAIT", "seconds": 5.0},  # the person's 9 s, at most max_wait
                     {"type": "CLICK", "x": 1005, "y": 481, "button": "left", "clicks": 1, "note": "recorded: step 1"},
                     {"type": "WAIT", "seconds": 1.0},  # 0.1 s recorded: a second at least (SETTLE)
                     {"type": "TYPING", "text": "{{old_word}}", "note": "recorded: step 2"},
                     {"type": "WAIT", "seconds": 2.0},  # the observation's time counts: the device had it too
                     {"type": "CLICK", "x": 10, "y": 20, "note": "recorded: step 5"},
                     {"type": "WAIT", "seconds": 3.0}]  # before DONE: the person saw the click take effect
    assert any("step 3 (CLICK) left out: the device refused it" in n for n in notes)


def played_run(tmp_path: Path, actions: list[dict]) -> Path:
    task_dir = tmp_path / "run" / "tasks" / "ubuntu-mousepad-replace_text_seed0"
    task_dir.mkdir(parents=True)
    result = TaskResult(task_id="ubuntu-mousepad-replace_text[seed0]", category="atomic", platforms=["ubuntu"],
                        instruction="x", status="passed", agent={"name": "human"})
    (task_dir / "result.json").write_text(result.model_dump_json())
    (task_dir / "traj.jsonl").write_text("".join(record(i, a).model_dump_json() + "\n" for i, a in enumerate(actions)))
    return task_dir


def test_a_saved_solution_loads_as_the_template_s_and_what_the_schema_refuses_is_refused(tmp_path):
    from jarvis_pytest.tasks.instances import atomic_task
    from jarvis_pytest.tasks.library import load_library

    sub = atomic_task(load_library(REPO / "tasks").get("ubuntu-mousepad-replace_text"), 0).formatted_subtasks[0]
    new_word = sub.input["new_word"].value
    run = played_run(tmp_path, [{"type": "HOTKEY", "keys": ["ctrl", "r"]}, {"type": "TYPING", "text": new_word},
                                {"type": "DONE"}])
    out = tmp_path / "lib" / "ubuntu" / "replace.json"
    target, steps, _ = save(run, REPO / "tasks", out=out)
    assert target == out and steps[2]["text"] == "{{new_word}}"
    (tpl,) = load_library(tmp_path / "lib").templates
    seed1 = atomic_task(tpl, 1).formatted_subtasks[0]
    assert seed1.gui_solution[2].action().text == seed1.input["new_word"].value  # each instance its own word
    bad = played_run(tmp_path / "bad", [{"type": "PYAUTOGUI", "script": "import os"}])
    with pytest.raises(ConfigError, match=r"gui_solution\[0\].*cannot use PYAUTOGUI"):
        save(bad, REPO / "tasks", out=tmp_path / "never.json")
    assert not (tmp_path / "never.json").exists()
    with pytest.raises(ConfigError, match="has a gui_solution already"):
        save(run, REPO / "tasks", write=True)  # the real template keeps its own


# -- the summary's row of times ----------------------------------------------------------------------------------

def timed(task: str, loop: float, agent: float, steps: int) -> TaskResult:
    from jarvis_pytest.results.model import EvaluatorVerdict, SubtaskVerdict

    return TaskResult(task_id=task, category="atomic", platforms=["ubuntu"], instruction="x", status="passed",
                      steps=steps, durations={"loop": loop, "agent": agent},
                      subtasks=[SubtaskVerdict(index=0, template=task, platform="ubuntu", passed=True,
                                               evaluators=[EvaluatorVerdict(func="f", passed=True, reason="ok")])])


def test_the_summary_has_the_time_per_task_and_per_step():
    s = rollup([timed("a", 30, 24, 8), timed("b", 10, 8, 4), timed("c", 20, 4, 4)], agent="human")
    t = s.timing
    assert (t.tasks, t.steps, t.task_median, t.task_mean, t.decision_per_task, t.decision_per_step) == \
        (3, 16, 20, 20, 12, 36 / 16)
    md = render_markdown(s)
    assert "| human | 3 | 16 | 20.0 | 20.0 | 12.0 | 2.2 |" in md and "a person's, in the player" in md
    assert "a person's time per step 2.2 s" in render_terminal(s)
    assert "the agent's: its model calls" in render_markdown(rollup([timed("a", 1, 1, 1)], agent="holo2"))
    assert rollup([TaskResult(task_id="x", category="atomic", platforms=["ubuntu"], instruction="x",
                              status="error")]).timing is None


def test_the_dashboard_stops_the_play_runs_it_started_when_it_stops(tmp_path):
    """A play run waits for its person until the task's time limit, holding its devices: the dashboard that started
    it ends it (SIGTERM: the run removes its devices) when it stops."""
    import subprocess
    import sys

    from jarvis_pytest.dashboard.server import serving
    from jarvis_pytest.player.launch import Play

    with serving(tmp_path) as server:
        waiting = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
        server.plays.append(Play("t", waiting, tmp_path, tmp_path / "url"))
    assert waiting.poll() == -15  # terminated, not left waiting


def test_jarvis_play_runs_the_one_case_of_the_task():
    from jarvis_pytest.player.launch import node_id

    assert node_id("ubuntu-mousepad-replace_text[seed0]") == \
        ("tasks/test_atomic.py::test_atomic[ubuntu-mousepad-replace_text[seed0]]", 2)
    assert node_id("ubuntu-mousepad-replace_text[seed4]")[1] == 5  # enough instances for seed 4
    assert node_id("ubuntu-mousepad-replace_text") == \
        ("tasks/test_atomic.py::test_atomic[ubuntu-mousepad-replace_text[seed0]]", 2)  # a template: its seed 0
    assert node_id("sw-0013") == ("tasks/test_composed.py::test_composed[sw-0013]", 2)
    with pytest.raises(ConfigError, match="is not a task id"):
        node_id("x; rm -rf /")
