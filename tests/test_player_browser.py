"""The browser player in a real headless Chromium (Debian's `chromium`, driven by Playwright, as the dashboard's
tests). Without devices, the page sends what a person does (clicks, a double click, a right click, a drag, the
wheel, key combinations, non-ASCII text, a second device's tab, the keys box, DONE) and the agent `human` makes
each the action it should be. With devices, `jarvis play` boots a real Ubuntu task and a scripted person plays it through the page — clicking on the
displayed screen where the controls are, typing, pressing keys, then DONE — and the task passes; `--agent replay`
of the recording passes too; the recording saved as the template's GUI solution passes `jarvis qc`'s GUI check (on
both instances: the typed words became placeholders); the summary, the dashboard and the comparison view show
the agent `human` with its times; the dashboard's Play button opens the player on a task.

The person's eyes are the device's accessibility tree, read from outside the run (the device's port on
127.0.0.1, as a person would look at the screen): it says where a control is in device pixels, and the person
clicks the displayed screen there. So the trajectory's clicks must be exactly those pixels, and a wrong mapping
of the page's points misses the small controls of Mousepad's Find and Replace dialog and fails the task.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import docker
import pytest
from playwright.sync_api import Page, expect

from jarvis_pytest.agents.gui_oracle import A11yView, await_target, centre
from jarvis_pytest.agents.protocol import HistoryEntry, TaskContext
from jarvis_pytest.dashboard.server import serving
from jarvis_pytest.devices.base import Observation
from jarvis_pytest.devices.desktop import DesktopDevice
from jarvis_pytest.infra.containers import LABEL_PLATFORM, LABEL_RUN
from jarvis_pytest.llm.deadline import deadline_at
from jarvis_pytest.player.agent import HumanAgent
from jarvis_pytest.results.run_state import resource_id
from jarvis_pytest.tasks.instances import atomic_task
from jarvis_pytest.tasks.library import load_library

REPO = Path(__file__).resolve().parents[1]
TEMPLATE = "ubuntu-mousepad-replace_text"  # Ctrl+R, two boxes to click and fill, two check boxes, two buttons, save
TASK = f"{TEMPLATE}[seed0]"
NODE = f"tasks/test_atomic.py::test_atomic[{TASK}]"
VIEWPORT = {"width": 1280, "height": 900}  # the 1920x1080 screen is shown smaller: the mapping scales
KEYS = {"ctrl": "Control", "alt": "Alt", "shift": "Shift", "super": "Meta", "enter": "Enter", "esc": "Escape",
        "tab": "Tab", "end": "End", "home": "Home"}


def cli(*args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", *args], cwd=REPO, capture_output=True,
                          text=True, timeout=timeout)


def bench(*args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-q", *args], cwd=REPO,
                          capture_output=True, text=True, timeout=timeout)


def wait_for_line(log: Path, pattern: str, proc: subprocess.Popen, timeout: float) -> re.Match:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        m = re.search(pattern, log.read_text(errors="replace"))
        if m:
            return m
        assert proc.poll() is None, f"jarvis play ended (exit {proc.returncode}):\n{log.read_text()[-3000:]}"
        time.sleep(0.2)
    raise AssertionError(f"no {pattern!r} in {timeout} s:\n{log.read_text()[-3000:]}")


def run_device(run_dir: Path, timeout: float = 30) -> DesktopDevice:
    """The Ubuntu device of the run in `run_dir`, reached as the harness reaches it: its port on 127.0.0.1."""
    client = docker.from_env()
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        found = client.containers.list(filters={"label": [f"{LABEL_RUN}={resource_id(run_dir)}",
                                                          f"{LABEL_PLATFORM}=ubuntu"]})
        for c in found:
            for bindings in (c.attrs["NetworkSettings"]["Ports"] or {}).values():
                for b in bindings or []:
                    if b.get("HostIp") == "127.0.0.1":
                        device = DesktopDevice(f"http://127.0.0.1:{b['HostPort']}")
                        try:
                            device.health()
                            return device
                        except Exception:
                            pass
        time.sleep(0.3)
    raise AssertionError(f"no Ubuntu device of {run_dir}")


def page_errors(page: Page) -> list[str]:
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.on("console", lambda msg: errors.append(msg.text)
            if msg.type == "error" and not msg.text.startswith("Failed to load resource") else None)
    return errors


def click_device(page: Page, x: int, y: int) -> float:
    """Click the displayed screen over device pixel (x, y): the middle of the area that pixel is displayed in. The
    device pixels one displayed pixel covers (the browser's mouse events come in whole displayed pixels)."""
    screen = page.get_by_test_id("screen")
    box = screen.bounding_box()
    width, height = page.evaluate("() => [document.getElementById('shot').naturalWidth, "
                                  "document.getElementById('shot').naturalHeight]")
    assert box["width"] < width, "the screen should be shown smaller than it is"
    page.mouse.click(box["x"] + (x + 0.5) * box["width"] / width, box["y"] + (y + 0.5) * box["height"] / height)
    return width / box["width"]


def play_step(page: Page, eyes: A11yView, step) -> tuple[int, int, float] | None:
    """One step of the template's GUI solution, done the way a person would in the page; the device pixel clicked
    and the device pixels a displayed pixel covers."""
    if step.type == "WAIT":
        time.sleep(step.action().seconds)
    elif step.type == "WAIT_FOR":
        found = await_target(eyes, step.target, step.timeout, gone=step.gone)
        assert (found.node is None) == step.gone, f"the screen never showed {step.target}"
    elif step.type == "HOTKEY":
        page.get_by_test_id("keyboard").focus()
        page.keyboard.press("+".join(KEYS.get(k, k) for k in step.action().keys))
    elif step.type == "TYPING":
        page.get_by_test_id("keyboard").focus()
        page.keyboard.type(step.action().text)
    elif step.type == "CLICK":
        # as a person does, click once the control has settled where it shows (in one make test under load the click
        # on Mousepad's "Replace all in" box did not take, likely sent while the dialog was still being laid out)
        found = await_target(eyes, step.target, step.timeout, settled=True)
        assert found.node is not None, f"the person does not see {step.target}"
        point = centre(found.node["box"])
        return (*point, click_device(page, *point))
    else:
        raise AssertionError(f"the scripted person has no move for {step.type}")
    return None


@dataclass
class Played:
    run_dir: Path
    task_dir: Path
    clicked: list[tuple[int, int, float]]  # device pixel, and the device pixels one displayed pixel covers
    seconds: float
    output: str
    values: dict


@pytest.fixture(scope="module")
def played(device_images, browser, tmp_path_factory) -> Played:
    root = tmp_path_factory.mktemp("player")
    run_dir = root / "reports" / "played"
    log = root / "play.log"
    with open(log, "w") as out:
        proc = subprocess.Popen([sys.executable, "-m", "jarvis_pytest.cli", "play", TASK, "--no-open",
                                 "--results-dir", str(run_dir)], cwd=REPO, stdout=out, stderr=subprocess.STDOUT,
                                start_new_session=True)  # its run with it: stopped together below
    try:
        url = wait_for_line(log, r"is ready in the player: (\S+)", proc, 240).group(1)
        eyes = A11yView(run_device(run_dir))
        sub = atomic_task(load_library(REPO / "tasks").get(TEMPLATE), 0).formatted_subtasks[0]
        context = browser.new_context(viewport=VIEWPORT)
        page = context.new_page()
        page.set_default_timeout(30_000)
        errors = page_errors(page)
        page.goto(url)
        expect(page.get_by_test_id("instruction")).to_have_text(sub.instruction)
        expect(page.get_by_test_id("status")).to_have_attribute("data-state", "turn")
        expect(page.get_by_test_id("screen")).to_have_attribute("data-platform", "ubuntu")
        t0 = time.monotonic()
        clicked = [p for p in (play_step(page, eyes, step) for step in sub.gui_solution) if p is not None]
        page.get_by_test_id("done").click()
        seconds = time.monotonic() - t0
        expect(page.get_by_test_id("status")).to_have_attribute("data-state", "ended")
        assert proc.wait(timeout=240) == 0, log.read_text()[-3000:]
        expect(page.get_by_test_id("status")).to_have_attribute("data-state", "stopped")  # the run is over
        context.close()
        assert not errors, f"errors in the page: {errors}"
    finally:
        if proc.poll() is None:  # a failed play: the run would wait for the person until its time limit
            os.killpg(proc.pid, signal.SIGTERM)  # the harness removes its devices on SIGTERM
            proc.wait(timeout=60)
    (task_dir,) = (run_dir / "tasks").iterdir()
    values = {k: v.value for k, v in sub.input.items()}
    print(f"\nplayed {TASK} through the page in {seconds:.1f} s")
    return Played(run_dir, task_dir, clicked, seconds, log.read_text(), values)


def trajectory(task_dir: Path) -> list[dict]:
    return [json.loads(line) for line in (task_dir / "traj.jsonl").read_text().splitlines()]


@pytest.mark.containers
def test_a_task_played_through_the_page_passes(played):
    result = json.loads((played.task_dir / "result.json").read_text())
    assert (result["status"], result["end_reason"], result["agent"]) == ("passed", "done", {"name": "human"}), \
        played.output[-3000:]
    steps = trajectory(played.task_dir)
    actions = [s["action"] for s in steps]
    clicks = [(a["x"], a["y"]) for a in actions if a["type"] == "CLICK"]
    assert len(clicks) == len(played.clicked)
    for (x, y), (aim_x, aim_y, scale) in zip(clicks, played.clicked):  # the pixel aimed at, to a displayed pixel
        assert 1 < scale < 2 and abs(x - aim_x) <= scale and abs(y - aim_y) <= scale, (clicks, played.clicked)
    assert [a["text"] for a in actions if a["type"] == "TYPING"] == [played.values["old_word"], played.values["new_word"]]
    assert [a["keys"] for a in actions if a["type"] == "HOTKEY"] == [["ctrl", "r"], ["ctrl", "s"]]
    assert actions[-1] == {"type": "DONE"} and len(actions) == len(played.clicked) + 5
    thinks = [s["extra"]["player"]["think_ms"] for s in steps]
    assert all(isinstance(t, int) and t >= 0 for t in thinks) and max(thinks) > 100, thinks
    assert f"{TASK}: passed (done) in {len(steps)} steps" in played.output
    print(f"result: passed in {len(steps)} steps; {result['durations']['loop']:.1f} s in the loop; "
          f"think times {thinks} ms")


@pytest.mark.containers
def test_the_recording_replays_to_the_same_verdict(played, tmp_path):
    t0 = time.monotonic()
    proc = bench(NODE, "--agent", "replay", "--agent-option", f"file={played.task_dir / 'traj.jsonl'}",
                 "--results-dir", str(tmp_path / "replay"))
    (task_dir,) = (tmp_path / "replay" / "tasks").iterdir()
    result = json.loads((task_dir / "result.json").read_text())
    assert proc.returncode == 0 and result["status"] == "passed", proc.stdout[-3000:]
    replayed = [s["action"] for s in trajectory(task_dir)]
    assert replayed == [s["action"] for s in trajectory(played.task_dir)]  # the same actions, DONE last
    waits = [s["extra"]["waited_s"] for s in trajectory(task_dir)[:-1]]
    assert any(w > 0 for w in waits), waits  # at the person's pace
    print(f"replay: passed in {time.monotonic() - t0:.1f} s")


@pytest.mark.containers
def test_the_recording_saved_as_the_gui_solution_passes_the_quality_gate(played, tmp_path):
    out = tmp_path / "library" / "ubuntu" / "mousepad_replace_text.json"
    saved = cli("gui-solution", str(played.task_dir), "--out", str(out))
    assert saved.returncode == 0, saved.stderr
    steps = json.loads(out.read_text())["gui_solution"]
    typed = [s["text"] for s in steps if s["type"] == "TYPING"]
    assert typed == ["{{old_word}}", "{{new_word}}"], typed
    assert all("target" not in s for s in steps) and any(s["type"] == "WAIT" for s in steps)
    gate = cli("qc", "--library", str(tmp_path / "library"), "--results-dir", str(tmp_path / "qc"),
               "--instances", "2", "-n", "2", "--platform", "ubuntu")
    rows = [line for line in gate.stdout.splitlines() if line.startswith(f"| {TEMPLATE}[")]
    assert gate.returncode == 0 and len(rows) == 2, gate.stdout[-3000:] + gate.stderr[-2000:]
    assert all("| pass | pass | ok |" in row for row in rows), rows  # the oracle, the GUI solution, the verdict
    print("qc: " + " / ".join(rows))


@pytest.mark.containers
def test_the_summary_and_the_dashboard_show_the_human_row_with_its_times(played, browser, tmp_path):
    summary = (played.run_dir / "summary.md").read_text()
    assert "| human | – | – | 100.0 (1/1) | 100.0 (1/1) |" in summary
    row = next(line for line in summary.splitlines() if line.startswith("| human | 1 | "))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert float(cells[3]) > 0 and float(cells[6]) > 0, row  # a task's time, a step's
    assert "a person's, in the player" in summary
    other = tmp_path / "gui-run"
    assert bench(NODE, "--agent", "gui-oracle", "--results-dir", str(other)).returncode == 0
    root = tmp_path / "root"
    root.mkdir()
    shutil.copytree(played.run_dir, root / "human")  # the dashboard follows no link out of its folder
    shutil.copytree(other, root / "gui")
    with serving(root) as server:
        base = f"http://127.0.0.1:{server.server_address[1]}"
        page = browser.new_page(viewport={"width": 1400, "height": 1000})
        errors = page_errors(page)
        page.goto(f"{base}/viewer.html#/")
        human = page.locator("tr[data-run=human]")
        expect(human).to_contain_text("human")
        expect(human.get_by_test_id("run-time")).to_have_text(re.compile(r"\d+\.\d s a task · \d+\.\d s a step"))
        expect(human.get_by_test_id("run-time")).to_have_attribute("title", "a person's time")
        page.goto(f"{base}/viewer.html#/run/human")
        expect(page.get_by_test_id("task-time").first).to_have_text(re.compile(r"\d+\.\d s \(\d+\.\d s\)"))
        page.goto(f"{base}/viewer.html#/compare/human/gui")
        expect(page.get_by_test_id("compare-time-A")).to_have_text(re.compile(r"\d+\.\d s a task"))
        expect(page.get_by_test_id("compare").locator("tbody tr")).to_have_count(1)
        expect(page.locator(".card", has_text="A: human")).to_contain_text("agent human")
        expect(page.locator(".card", has_text="B: gui")).to_contain_text("agent gui-oracle")
        page.goto(f"{base}/viewer.html#/run/human/task/{played.task_dir.name}/1")
        expect(page.get_by_test_id("step")).to_contain_text("waited for the person")
        expect(page.get_by_test_id("step")).to_contain_text("think")
        page.close()
        assert not errors, errors


@pytest.mark.containers
def test_the_dashboard_plays_a_task_in_the_player(played, browser, tmp_path):
    """The Play button on a task starts `jarvis play` into a new run of the results directory and opens the player
    in a new tab; the person gives up (FAIL) and the dashboard lists the run as the agent human's, failed."""
    root = tmp_path / "root"
    root.mkdir()
    shutil.copytree(played.run_dir, root / "human")
    with serving(root) as server:
        base = f"http://127.0.0.1:{server.server_address[1]}"
        context = browser.new_context(viewport=VIEWPORT)
        page = context.new_page()
        page.set_default_timeout(240_000)
        errors = page_errors(page)
        page.goto(f"{base}/viewer.html#/run/human/task/{played.task_dir.name}")
        with context.expect_page(timeout=240_000) as opened:
            page.get_by_test_id("play").click()
        player = opened.value
        expect(player.get_by_test_id("status")).to_have_attribute("data-state", "turn", timeout=240_000)
        expect(player.get_by_test_id("task")).to_have_text(TASK)
        expect(player.get_by_test_id("screen")).to_have_attribute("data-platform", "ubuntu")
        expect(page.get_by_test_id("play-link")).to_have_attribute("href", re.compile(r"^http://127\.0\.0\.1:\d+/#token="))
        player.get_by_test_id("fail").click()
        expect(player.get_by_test_id("status")).to_have_attribute("data-state", "stopped", timeout=240_000)
        (play,) = server.plays
        assert play.proc.wait(timeout=60) in (0, 1)
        result = json.loads(next((play.results_dir / "tasks").glob("*/result.json")).read_text())
        assert (result["status"], result["end_reason"], result["agent"]["name"]) == ("failed", "fail", "human")
        page.goto(f"{base}/viewer.html#/")
        expect(page.locator(f"tr[data-run='{play.results_dir.name}']")).to_contain_text("human")
        context.close()
        assert not errors, errors


def test_the_dashboard_refuses_play_from_elsewhere(tmp_path):
    import httpx

    with serving(tmp_path) as server:
        base = f"http://127.0.0.1:{server.server_address[1]}"
        body = {"task": TASK}
        assert httpx.post(f"{base}/api/play", json=body).status_code == 403  # no header: another site's form
        assert httpx.post(f"{base}/api/play", json=body, headers={"X-Jarvis-Play": "1", "Host": "evil.example"}) \
            .status_code == 403  # a DNS-rebinding page
        bad = httpx.post(f"{base}/api/play", json={"task": "no such task!"}, headers={"X-Jarvis-Play": "1"})
        assert bad.status_code == 400 and "is not a task id" in bad.json()["error"]
        assert server.plays == []


# -- the page, without devices --------------------------------------------------------------------------------------

def png(width: int, height: int) -> bytes:
    import io

    from PIL import Image

    out = io.BytesIO()
    Image.new("RGB", (width, height), (40, 90, 160)).save(out, "PNG")
    return out.getvalue()


class Loop:
    """The step loop's side: the agent asked for step after step (as `run_loop` does) until DONE."""

    def __init__(self, agent, observations):
        self.steps: list = []
        self.thread = threading.Thread(target=self._run, args=(agent, observations), daemon=True)
        self.thread.start()

    def _run(self, agent, observations):
        history = []
        while True:
            with deadline_at(time.monotonic() + 60):
                step = agent.act(observations, list(history))
            self.steps.append(step)
            history.append(HistoryEntry(len(history), step.platform, "", None))
            if step.action is None or step.action.type in ("DONE", "FAIL"):
                return


@contextmanager
def playing(browser, sizes: dict[str, tuple[int, int]]):
    """The player's page on a task of `sizes`' devices (platform → screen size, the first shown first), each
    showing a plain screen, with the step loop asking the agent `human` for steps: (the loop, the page, the
    page's errors), once the page shows the first device's screen and says it is the person's turn."""
    agent = HumanAgent({})
    agent.reset(TaskContext(task_id="on-the-page", instruction="do both", platforms=tuple(sizes)))
    loop = Loop(agent, {p: Observation(p, png(*size), *size) for p, size in sizes.items()})
    page = browser.new_page(viewport=VIEWPORT)
    errors = page_errors(page)
    try:
        page.goto(agent.url)
        expect(page.get_by_test_id("status")).to_have_attribute("data-state", "turn")
        expect(page.get_by_test_id("screen")).to_have_attribute("data-platform", next(iter(sizes)))
        yield loop, page, errors
    finally:
        page.close()
        agent.close()


def test_the_page_sends_what_a_person_does(browser):
    from jarvis_pytest.devices import actions as A
    from jarvis_pytest.player.inputs import to_device

    with playing(browser, {"ubuntu": (1920, 1080), "windows": (1280, 800)}) as (loop, page, errors):
        box = page.get_by_test_id("screen").bounding_box()

        def at(x: int, y: int, screen=(1920, 1080), box=box):  # a page point → the device pixel it must make
            return to_device(x - box["x"], y - box["y"], box["width"], box["height"], *screen)

        page.mouse.click(300, 200)
        page.mouse.dblclick(500, 300)
        page.mouse.click(600, 350, button="right")
        page.mouse.move(200, 400)
        page.mouse.down()
        page.mouse.move(420, 460, steps=5)
        page.mouse.up()
        page.mouse.move(700, 380)
        page.mouse.wheel(0, 300)
        page.keyboard.press("Control+Shift+KeyS")
        page.keyboard.press("Shift+Tab")
        page.keyboard.type("Grüße, 東京")
        page.keyboard.press("Enter")
        page.get_by_test_id("tab-windows").click()
        expect(page.get_by_test_id("screen")).to_have_attribute("data-platform", "windows")
        windows = page.get_by_test_id("screen").bounding_box()
        page.mouse.click(500, 300)
        page.get_by_test_id("combo").fill("ctrl+w")
        page.get_by_test_id("combo").press("Enter")
        page.get_by_test_id("done").click()
        loop.thread.join(20)
        got = [(s.platform, s.action) for s in loop.steps]
        ux, uy = at(300, 200)
        assert got[:9] == [
            ("ubuntu", A.Click(x=ux, y=uy)),
            ("ubuntu", A.Click(**dict(zip("xy", at(500, 300))), clicks=2)),
            ("ubuntu", A.RightClick(**dict(zip("xy", at(600, 350))))),
            ("ubuntu", A.DragTo(**dict(zip(("start_x", "start_y"), at(200, 400))), **dict(zip("xy", at(420, 460))))),
            ("ubuntu", A.Scroll(dy=3, **dict(zip("xy", at(700, 380))))),
            ("ubuntu", A.Hotkey(keys=["ctrl", "shift", "s"])),
            ("ubuntu", A.Hotkey(keys=["shift", "tab"])),
            ("ubuntu", A.Typing(text="Grüße, 東京")),
            ("ubuntu", A.Hotkey(keys=["enter"])),
        ], got
        wx, wy = at(500, 300, (1280, 800), windows)
        assert got[9:] == [("windows", A.Click(x=wx, y=wy)), ("windows", A.Hotkey(keys=["ctrl", "w"])),
                           ("windows", A.Done())], got
        assert 1 < 1920 / box["width"] and (ux, uy) != (300, 200)  # shown smaller: the points were scaled
        expect(page.get_by_test_id("status")).to_have_attribute("data-state", "ended")
        expect(page.get_by_test_id("log")).to_contain_text("#9 windows: CLICK")
        assert not errors, errors


def test_the_page_sends_a_resting_pointer_and_a_phones_gestures_and_buttons(browser):
    """The mouse at rest a second on a desktop's screen is a MOVE_TO (a menu that opens under the pointer); on a
    phone's screen a drag is a SWIPE at its speed, and its system buttons, shown under its screen only, are
    SYSTEM_BUTTONs."""
    from jarvis_pytest.devices import actions as A
    from jarvis_pytest.player.inputs import to_device

    with playing(browser, {"ubuntu": (1920, 1080), "android": (1080, 2400)}) as (loop, page, errors):
        expect(page.get_by_test_id("system-buttons")).to_be_hidden()
        box = page.get_by_test_id("screen").bounding_box()
        page.mouse.move(box["x"] + 300, box["y"] + 200, steps=3)
        page.wait_for_timeout(1500)  # at rest: a hover
        page.mouse.move(box["x"] + 305, box["y"] + 202)
        page.wait_for_timeout(1300)  # at rest again, but where it was: nothing
        page.get_by_test_id("tab-android").click()
        expect(page.get_by_test_id("screen")).to_have_attribute("data-platform", "android")
        expect(page.get_by_test_id("system-buttons")).to_be_visible()
        phone = page.get_by_test_id("screen").bounding_box()
        px, py = phone["x"] + phone["width"] / 2, phone["y"] + phone["height"] * 0.8
        page.mouse.move(px, py)
        page.mouse.down()
        page.mouse.move(px, py - phone["height"] * 0.5, steps=4)
        page.mouse.up()
        page.get_by_test_id("button-back").click()
        page.get_by_test_id("done").click()
        loop.thread.join(20)
        got = [(s.platform, s.action) for s in loop.steps]
        # (a held press, a LONG_PRESS, is checked in test_player.py only: through the page under make test's load
        # it once did not arrive, cause not found)
        assert [a.type for _, a in got] == ["MOVE_TO", "SWIPE", "SYSTEM_BUTTON", "DONE"], got
        hover, (hx, hy) = got[0][1], to_device(300, 200, box["width"], box["height"], 1920, 1080)
        assert got[0][0] == "ubuntu" and abs(hover.x - hx) <= 1 and abs(hover.y - hy) <= 1  # the box's fractions
        swipe = got[1][1]
        sx, sy = to_device(px - phone["x"], py - phone["y"], phone["width"], phone["height"], 1080, 2400)
        tol = 2400 / phone["height"] + 1  # device pixels per displayed pixel: the box's fractions
        assert got[1][0] == "android" and abs(swipe.x - sx) <= tol and abs(swipe.y - sy) <= tol and abs(swipe.dx) <= tol
        assert -1250 < swipe.dy < -1150 and 50 <= swipe.duration < 900  # half the phone's height, upwards
        assert got[2] == ("android", A.SystemButton(button="back"))
        assert not errors, errors
