"""The dashboard in a real headless Chromium (Debian's `chromium`, driven by Playwright): the pages render, the
live view follows a run as it writes steps, click markers sit where the action clicked, and damaged result files
are shown as problems while the page keeps working.

The finished run is a real benchmark run made here on real devices (`pytest tasks` with the `replay` agent clicking,
typing and waiting on two atomic and one composed Ubuntu task), or the run directory named by `JARVIS_DASHBOARD_RUN`
(e.g. `reports/<run id>`; copied, never modified). The live view is checked twice: against a real run in progress
(steps arrive from the devices) and step by step against a run written with `jarvis_pytest.dashboard.sample`.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import time
import uuid
from pathlib import Path

import httpx
import pytest
from playwright.sync_api import Page, expect

from jarvis_pytest.dashboard import sample
from jarvis_pytest.dashboard.server import serving
from jarvis_pytest.results.model import SubtaskVerdict

POINT_ACTIONS = ("CLICK", "RIGHT_CLICK", "DOUBLE_CLICK", "MOVE_TO", "LONG_PRESS")
REPO = Path(__file__).resolve().parents[1]
REAL_TASKS = ["-k", "(mousepad-write_note or mousepad-replace_text) and seed0 or sw-0013", "--instances", "1"]
CLICKS = [{"type": "CLICK", "x": 960, "y": 540}, {"type": "TYPING", "text": "dashboard check"},
          {"type": "RIGHT_CLICK", "x": 300, "y": 200}, {"type": "HOTKEY", "keys": ["escape"]}]

pytestmark = pytest.mark.containers  # the default finished run and the real live run boot devices


def replay_file(path: Path, actions: list[dict]) -> Path:
    """A trajectory for the `replay` agent: these actions on the Ubuntu device, in order."""
    path.write_text("".join(json.dumps({"index": i, "platform": "ubuntu", "action": a,
                                        "reasoning": f"dashboard test step {i}"}) + "\n"
                            for i, a in enumerate(actions)))
    return path


def bench(run_dir: Path, trajectory: Path, *args: str) -> subprocess.Popen:
    """A real benchmark run with the replay agent, writing into `run_dir`."""
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-q", str(REPO / "tasks"), "--results-dir",
           str(run_dir), "--agent", "replay", "--agent-option", f"file={trajectory}", *args]
    return subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


@pytest.fixture(scope="module")
def results_root(tmp_path_factory, request) -> Path:
    root = tmp_path_factory.mktemp("results")
    real = os.environ.get("JARVIS_DASHBOARD_RUN")
    if real:
        shutil.copytree(real, root / Path(real).name, ignore_dangling_symlinks=True)
        return root
    request.getfixturevalue("device_images")
    trajectory = replay_file(tmp_path_factory.mktemp("replay") / "traj.jsonl", CLICKS)
    proc = bench(root / f"real-{uuid.uuid4().hex[:6]}", trajectory, *REAL_TASKS)
    out, _ = proc.communicate(timeout=600)
    assert proc.returncode in (0, 1), f"the benchmark run did not finish (exit {proc.returncode}):\n{out[-3000:]}"
    return root


@pytest.fixture(scope="module")
def finished_run(results_root) -> str:
    (run,) = [p.name for p in results_root.iterdir()]
    return run


@pytest.fixture(scope="module")
def damaged(results_root, finished_run) -> dict[str, str]:
    """A copy of the finished run with one result.json corrupted and one trajectory ending in half a line."""
    run = f"{finished_run}-damaged"
    shutil.copytree(results_root / finished_run, results_root / run, ignore_dangling_symlinks=True)
    tasks = sorted(p for p in (results_root / run / "tasks").iterdir() if p.is_dir())
    with_steps = [p for p in tasks if (p / "traj.jsonl").is_file() and (p / "traj.jsonl").stat().st_size > 0]
    traj_task = with_steps[0]
    result_task = next(p for p in tasks if p != traj_task)
    (result_task / "result.json").write_text('{"task_id": "trunc')
    with open(traj_task / "traj.jsonl", "a") as f:
        f.write('{"index": 99, "platform": "ubuntu", "action": {"type": "CLI')
    return {"run": run, "traj_task": traj_task.name, "result_task": result_task.name}


@pytest.fixture(scope="module")
def base_url(results_root):
    with serving(results_root) as server:
        host, port = server.server_address[:2]
        yield f"http://{host}:{port}"


@pytest.fixture
def page(browser, base_url):
    context = browser.new_context(viewport={"width": 1400, "height": 1000})
    pg = context.new_page()
    pg.set_default_timeout(10_000)
    errors: list[str] = []
    pg.on("pageerror", lambda exc: errors.append(str(exc)))
    pg.on("console", lambda msg: errors.append(msg.text)
          if msg.type == "error" and not msg.text.startswith("Failed to load resource") else None)
    yield pg
    context.close()
    assert not errors, f"errors in the page: {errors}"


def view(page: Page, base_url: str, route: str) -> None:
    page.goto(f"{base_url}/viewer.html#{route}")


def test_pages_render(page, base_url, finished_run, damaged):
    run = httpx.get(f"{base_url}/api/runs/{finished_run}").json()

    view(page, base_url, "/")
    row = page.locator(f'tr[data-run="{finished_run}"]')
    expect(row).to_contain_text("finished")
    expect(row).to_contain_text(f"{run['counts']['done']}/{run['counts']['total']} done")

    view(page, base_url, f"/run/{finished_run}")
    expect(page.locator("h1")).to_contain_text(finished_run)
    expect(page.locator("[data-testid=tasks] tbody tr")).to_have_count(len(run["tasks"]))
    if run["summary"]["available"]:
        expect(page.locator("[data-testid=summary-table]").first).to_be_visible()
        if run["summary"]["curve"]:
            expect(page.locator("[data-testid=curve] circle")).to_have_count(len(run["summary"]["curve"]))

    task = next(t for t in run["tasks"] if t["steps"] > 0)
    page.locator(f'tr[data-task="{task["name"]}"] a').click()
    expect(page.locator("h1")).to_contain_text(task["task_id"])
    expect(page.locator("[data-testid=step-position]")).to_contain_text(" / ")
    first = page.locator("[data-testid=shot]").first
    expect(first).to_be_visible()
    page.wait_for_function("() => [...document.querySelectorAll('[data-testid=shot]')].every(i => i.complete && i.naturalWidth > 0)")
    page.locator("[data-testid=next]").click()
    expect(page.locator("[data-testid=step-position]")).to_contain_text("2 / ")
    if task["subtasks_total"]:
        expect(page.locator("[data-testid=subtask]")).to_have_count(task["subtasks_total"])

    view(page, base_url, f"/compare/{finished_run}/{damaged['run']}")
    expect(page.locator("[data-testid=compare] tbody tr")).to_have_count(len(run["tasks"]))
    expect(page.locator(f'[data-testid=compare] tr[data-change="same"]').first).to_be_visible()


def test_summary_tables_and_subtask_plot(page, base_url, finished_run, monkeypatch):
    """The viewer draws whatever the rollup adapter returns (the adapter itself: test_dashboard_stats.py)."""
    from jarvis_pytest.dashboard import stats

    curve = [{"subtasks": 1, "rate": 0.5, "tasks": 4, "passed": 2}, {"subtasks": 2, "rate": 0.25, "tasks": 4, "passed": 1},
             {"subtasks": 4, "rate": 0.0, "tasks": 2, "passed": 0}]
    table = {"title": "atomic", "columns": ["platform", "TSR"], "rows": [["ubuntu", "50.0%"]]}
    monkeypatch.setattr(stats, "summary", lambda results: {"available": True, "message": "", "tables": [table],
                                                           "curve": curve, "headline": {"tsr": 0.375, "ssr": 0.5}})
    view(page, base_url, f"/run/{finished_run}")
    expect(page.locator("[data-testid=summary-table]")).to_contain_text("ubuntu")
    expect(page.get_by_text("TSR 37.5%")).to_be_visible()
    circles = page.locator("[data-testid=curve] circle")
    expect(circles).to_have_count(3)
    ys = [float(c.get_attribute("cy")) for c in circles.all()]
    xs = [float(c.get_attribute("cx")) for c in circles.all()]
    assert ys[0] < ys[1] < ys[2] and abs((ys[2] - ys[0]) - 2 * (ys[2] - ys[1])) < 0.01  # rates 0.5, 0.25, 0
    assert abs((xs[1] - xs[0]) * 2 - (xs[2] - xs[1])) < 0.01  # subtask counts 1, 2, 4 on a linear axis


def test_live_view_follows_a_real_run(page, base_url, results_root, tmp_path):
    """A benchmark run on a real device, watched while it runs: its steps appear without a reload."""
    run = f"live-real-{uuid.uuid4().hex[:6]}"
    waits = [{"type": "WAIT", "seconds": 1.0}] * 6
    proc = bench(results_root / run, replay_file(tmp_path / "traj.jsonl", [CLICKS[0], *waits]),
                 "-k", "mousepad-write_note and seed0", "--instances", "1")
    try:
        deadline = time.monotonic() + 120
        while not list((results_root / run).glob("tasks/*/traj.jsonl")):
            assert proc.poll() is None and time.monotonic() < deadline, "the run wrote no step"
            time.sleep(0.2)
        view(page, base_url, f"/run/{run}")
        page.evaluate("window.__sameDocument = 7")
        card = page.locator("[data-testid=live-task]")
        expect(card.locator("[data-testid=live-action]")).to_contain_text("WAIT", timeout=30_000)
        shown = [int(card.locator("[data-testid=live-steps]").inner_text().split()[0])]
        expect(card.locator("[data-testid=live-steps]")).not_to_have_text(f"{shown[0]} steps", timeout=30_000)
        expect(card.locator("[data-testid=live-shot]")).to_have_attribute("src", re.compile(r"step_\d+_ubuntu\.png$"))
        out, _ = proc.communicate(timeout=180)
        assert proc.returncode == 0, out[-3000:]  # the replayed clicks do not write the note: the task fails (a result)
        expect(page.locator("[data-testid=count-failed]")).to_contain_text("1", timeout=30_000)
        expect(page.locator("[data-testid=count-running]")).to_contain_text("0")
        expect(page.locator("[data-testid=live-task]")).to_have_count(0)
        assert page.evaluate("window.__sameDocument") == 7  # updated in place, never reloaded
    finally:
        if proc.poll() is None:
            proc.kill()


def test_live_view_follows_a_running_task(page, base_url, results_root):
    run = f"live-{uuid.uuid4().hex[:6]}"
    run_dir = results_root / run
    run_dir.mkdir()
    (run_dir / "plan.json").write_text(json.dumps({"tasks": ["live-task[0]", "later-task[1]"]}))
    rec = sample.start_task(run_dir, "live-task[0]", "atomic", ["ubuntu"], "Type the greeting into the field.")
    sample.record_step(rec, 0, ["ubuntu"], "ubuntu", {"type": "CLICK", "x": 100, "y": 120}, "Click the field.")

    view(page, base_url, f"/run/{run}")
    card = page.locator("[data-testid=live-task]")
    expect(card.locator("[data-testid=live-action]")).to_contain_text("CLICK(x=100, y=120)")
    expect(page.locator("[data-testid=pending]")).to_contain_text("later-task[1]")
    expect(page.locator("[data-testid=count-running]")).to_contain_text("1")
    page.evaluate("window.__sameDocument = 42")

    sample.record_step(rec, 1, ["ubuntu"], "ubuntu", {"type": "TYPING", "text": "hello-live-42"}, "Type it.")
    expect(card.locator("[data-testid=live-action]")).to_contain_text("hello-live-42")
    expect(card.locator("[data-testid=live-steps]")).to_have_text("2 steps")
    expect(card.locator("[data-testid=live-shot]")).to_have_attribute("src", f"/files/{run}/tasks/live-task_0/step_0001_ubuntu.png")

    card.locator("a").first.click()  # the task view follows the newest step while the task runs
    expect(page.locator("[data-testid=step-position]")).to_have_text("2 / 2")
    sample.record_step(rec, 2, ["ubuntu"], "ubuntu", {"type": "DONE"}, "The greeting is typed.")
    expect(page.locator("[data-testid=step-position]")).to_have_text("3 / 3")
    expect(page.locator("[data-testid=action]")).to_have_text("DONE()")
    sample.finish_task(rec, [SubtaskVerdict(index=0, template="type-greeting", platform="ubuntu", passed=True)], "done", 3)
    expect(page.locator("h1 .badge")).to_have_text("passed")
    expect(page.locator("[data-testid=step-position]")).to_have_text("4 / 4")  # + the final state
    expect(page.locator("[data-testid=subtask]")).to_have_count(1)

    page.go_back()
    expect(page.locator("[data-testid=live]")).to_contain_text("No task is running.")
    expect(page.locator("[data-testid=count-passed]")).to_contain_text("1")
    assert page.evaluate("window.__sameDocument") == 42  # updated in place, never reloaded


def _point_step(base_url: str, run: str) -> tuple[dict, dict]:
    """A task and one of its steps whose action has a point on a device with a screenshot."""
    for t in httpx.get(f"{base_url}/api/runs/{run}").json()["tasks"]:
        if not t["steps"]:
            continue
        task = httpx.get(f"{base_url}/api/runs/{run}/tasks/{t['name']}").json()
        for s in task["steps_detail"]:
            a = s["action"] or {}
            if a.get("type") in POINT_ACTIONS and isinstance(a.get("x"), int) and s["platform"] in s["screenshots"]:
                return task, s
    if os.environ.get("JARVIS_DASHBOARD_RUN"):
        pytest.skip(f"JARVIS_DASHBOARD_RUN {run} has no step with a click point")
    pytest.fail(f"the benchmark run {run} recorded no step with a click point")


def test_click_marker_sits_on_the_clicked_point(page, base_url, finished_run):
    task, step = _point_step(base_url, finished_run)
    x, y = step["action"]["x"], step["action"]["y"]
    view(page, base_url, f"/run/{finished_run}/task/{task['name']}/{step['index']}")
    expect(page.locator("[data-testid=action]")).to_contain_text(step["action"]["type"])
    img = page.locator(f'img[data-platform="{step["platform"]}"]')
    marker = page.locator(f'figure:has(img[data-platform="{step["platform"]}"]) [data-testid=marker]')
    expect(marker).to_have_count(1)
    natural_w, natural_h = img.evaluate("i => [i.naturalWidth, i.naturalHeight]")

    def offsets() -> tuple[float, float, float]:
        ib, mb = img.bounding_box(), marker.bounding_box()
        expected = (ib["x"] + x * ib["width"] / natural_w, ib["y"] + y * ib["height"] / natural_h)
        centre = (mb["x"] + mb["width"] / 2, mb["y"] + mb["height"] / 2)
        return abs(centre[0] - expected[0]), abs(centre[1] - expected[1]), ib["width"]

    shown_widths = []
    for size in ({"width": 1400, "height": 1000}, {"width": 760, "height": 600}):  # the marker follows a resize
        page.set_viewport_size(size)
        page.evaluate("() => new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")  # layout, ResizeObserver
        dx, dy, shown = offsets()
        shown_widths.append(shown)
        assert dx <= 2 and dy <= 2, f"marker off by ({dx:.1f}, {dy:.1f}) px in a {size} viewport"
    assert shown_widths[1] < shown_widths[0] < natural_w, f"the screenshot should be scaled: {shown_widths}"
    expect(page.locator(f'img[data-platform]:not([data-platform="{step["platform"]}"]) ~ [data-testid=marker]')).to_have_count(0)


def test_damaged_files_are_shown_and_the_page_keeps_working(page, base_url, damaged):
    run = damaged["run"]
    view(page, base_url, f"/run/{run}")
    problems = page.locator("[data-testid=problems]").first
    expect(problems).to_contain_text(f"{damaged['result_task']}/result.json")
    expect(problems).to_contain_text(f"{damaged['traj_task']}/traj.jsonl")
    expect(problems).to_contain_text("half-written")
    expect(page.locator(f'tr[data-task="{damaged["result_task"]}"]')).to_have_attribute("data-status", "unknown")
    expect(page.locator("[data-testid=tasks] tbody tr")).to_have_count(
        len(httpx.get(f"{base_url}/api/runs/{run}").json()["tasks"]))

    view(page, base_url, f"/run/{run}/task/{damaged['traj_task']}")
    expect(page.locator("[data-testid=problems]")).to_contain_text("incomplete")
    expect(page.locator("[data-testid=step-position]")).to_contain_text(" / ")
    expect(page.locator("[data-testid=shot]").first).to_be_visible()

    view(page, base_url, f"/run/{run}/task/{damaged['result_task']}")
    expect(page.locator("[data-testid=problems]")).to_contain_text("not valid JSON")
    expect(page.locator("h1 .badge")).to_have_text("unknown")

    view(page, base_url, "/run/no-such-run")
    expect(page.locator("[data-testid=page-error]")).to_contain_text("no run")
