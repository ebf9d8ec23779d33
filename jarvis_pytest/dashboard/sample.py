"""A small, realistic results directory written with the harness's own `TaskRecorder`: a finished run and a run in
progress, with real PNG screenshots of several devices. The dashboard's tests use it, and it lets you try the
dashboard without a benchmark run:

    python -m jarvis_pytest.dashboard.sample /tmp/demo-results && jarvis dashboard --results /tmp/demo-results
"""

from __future__ import annotations

import io
import sys
from pathlib import Path
from typing import Any

from PIL import Image, ImageDraw

from jarvis_pytest.results.model import EvaluatorVerdict, StepRecord, SubtaskVerdict, TaskResult
from jarvis_pytest.results.writer import TaskRecorder, write_json_atomic

SCREEN = {"ubuntu": (1280, 800), "windows": (1280, 800), "android": (540, 1200)}
COLORS = {"ubuntu": (48, 10, 36), "windows": (0, 84, 166), "android": (20, 90, 60)}
FINISHED_RUN = "20250101-100000-aaaaaa"
LIVE_RUN = "20250102-100000-bbbbbb"


def screenshot_png(platform: str, step: int, target: tuple[int, int] | None = None) -> bytes:
    """A PNG of the device's screen size: a coloured desktop naming the step, with a button at `target`."""
    w, h = SCREEN.get(platform, (1024, 768))
    img = Image.new("RGB", (w, h), COLORS.get(platform, (60, 60, 60)))
    draw = ImageDraw.Draw(img)
    draw.rectangle((0, 0, w, 28), fill=(30, 30, 30))
    draw.text((8, 8), f"{platform} - step {step}", fill=(255, 255, 255))
    if target is not None:
        x, y = target
        draw.rectangle((x - 40, y - 14, x + 40, y + 14), fill=(230, 230, 230), outline=(0, 0, 0))
        draw.text((x - 30, y - 6), "OK", fill=(0, 0, 0))
    buf = io.BytesIO()
    img.save(buf, "PNG")
    return buf.getvalue()


def record_step(recorder: TaskRecorder, index: int, platforms: list[str], platform: str | None,
                action: dict[str, Any] | None, reasoning: str = "", error: str | None = None) -> StepRecord:
    """Take a screenshot of every device (the click target drawn on the acting one), then append the step."""
    target = (action["x"], action["y"]) if action and "x" in action and "y" in action else None
    shots = {p: recorder.screenshot(index, p, screenshot_png(p, index, target if p == platform else None))
             for p in platforms}
    record = StepRecord(index=index, platform=platform, action=action, reasoning=reasoning, raw_output=reasoning,
                        error=error, screenshots=shots, observe_ms=35.0, agent_ms=900.0, exec_ms=12.0,
                        usage={"prompt_tokens": 1200, "completion_tokens": 80})
    recorder.step(record)
    return record


def _verdict(index: int, template: str, platform: str, checks: list[tuple[str, bool, str]]) -> SubtaskVerdict:
    evaluators = [EvaluatorVerdict(func=f, args={"path": "/home/user/report.xlsx"}, passed=ok, reason=why)
                  for f, ok, why in checks]
    return SubtaskVerdict(index=index, template=template, platform=platform, passed=all(ok for _, ok, _ in checks),
                          evaluators=evaluators)


AGENT = {"name": "oracle", "version": 1}


def start_task(run_dir: Path, task_id: str, category: str, platforms: list[str], instruction: str) -> TaskRecorder:
    """A recorder for a task that has just started (status "running", like the harness writes it)."""
    result = TaskResult(task_id=task_id, category=category, platforms=platforms, instruction=instruction,
                        status="running", agent=AGENT, agent_key="sample")
    return TaskRecorder(run_dir, result)


def finish_task(recorder: TaskRecorder, subtasks: list[SubtaskVerdict], end_reason: str, steps: int,
                error: str | None = None) -> None:
    """Screenshots of the final state (unless the devices never came up), the verdicts, and the final result.json."""
    r = recorder.result
    for p in r.platforms if error is None else []:
        recorder.screenshot(steps, p, screenshot_png(p, steps))
    r.subtasks, r.end_reason, r.steps, r.error = subtasks, end_reason, steps, error
    r.status = "error" if error else ("passed" if subtasks and all(s.passed for s in subtasks) else "failed")
    r.durations = {"boot": 1.2, "setup": 0.8, "agent": 2.5 * steps, "evaluate": 0.4, "total": 3 + 2.5 * steps}
    recorder.finish()


def _calc_task(run_dir: Path, passed: bool) -> None:
    rec = start_task(run_dir, "ubuntu-calc-sum[seed0]", "atomic", ["ubuntu"],
                     "Open report.xlsx and put the sum of column A into B1.")
    record_step(rec, 0, ["ubuntu"], "ubuntu", {"type": "CLICK", "x": 812, "y": 433, "button": "left", "clicks": 1},
                "The spreadsheet is open. I click cell B1 first.\nThen I will type the formula.")
    record_step(rec, 1, ["ubuntu"], "ubuntu", {"type": "TYPING", "text": "=SUM(A1:A9)\n"}, "Type the formula.")
    record_step(rec, 2, ["ubuntu"], "ubuntu", {"type": "HOTKEY", "keys": ["ctrl", "s"]}, "Save the file.")
    record_step(rec, 3, ["ubuntu"], "ubuntu", {"type": "DONE"}, "The sum is in B1 and the file is saved.")
    check = ("compare_cell", True, "B1 = 45 as expected") if passed else ("compare_cell", False, "expected B1 = 45, found 44")
    finish_task(rec, [_verdict(0, "calc-sum", "ubuntu", [("file_exists", True, "report.xlsx exists"), check])], "done", 4)


def _transfer_task(run_dir: Path) -> None:
    platforms = ["android", "ubuntu"]
    rec = start_task(run_dir, "md-photo-to-doc[seed1]", "md", platforms,
                     "On the phone, take the latest photo, send it to the transfer server, then insert it into "
                     "notes.odt on the Ubuntu desktop.")
    record_step(rec, 0, platforms, "android", {"type": "LONG_PRESS", "x": 270, "y": 640, "duration": 800},
                "Long-press the latest photo in the gallery.")
    record_step(rec, 1, platforms, "windows", {"type": "CLICK", "x": 10, "y": 10}, "Try the Windows PC.",
                error="device unavailable: windows is not used by this task (use one of ['android', 'ubuntu'])")
    record_step(rec, 2, platforms, "android", {"type": "SWIPE", "x": 270, "y": 900, "dx": 0, "dy": -500, "duration": 300},
                "Swipe up to the share sheet.")
    record_step(rec, 3, platforms, "ubuntu", {"type": "DRAG_TO", "x": 900, "y": 300, "start_x": 200, "start_y": 600},
                "Drag the downloaded photo into the document.")
    record_step(rec, 4, platforms, "ubuntu", {"type": "DONE"}, "Done.")
    finish_task(rec, [
        _verdict(0, "android-share-photo", "android", [("transfer_has_file", True, "photo.jpg is on the server")]),
        _verdict(1, "ubuntu-insert-image", "ubuntu",
                 [("odt_has_image", False, "notes.odt has no image (0 images, expected 1)")]),
    ], "done", 5)


def _boot_error_task(run_dir: Path) -> None:
    rec = start_task(run_dir, "windows-notepad-save[seed0]", "atomic", ["windows"], "Save a note in Notepad.")
    finish_task(rec, [], "error", 0, error="device failed to boot: windows image not available (needs KVM)")


def _sw_task(run_dir: Path, passed: int) -> None:
    rec = start_task(run_dir, "sw-rename-and-zip[seed2]", "sw", ["ubuntu"],
                     "Rename data.csv to sales.csv, then compress it into sales.zip.")
    for i in range(3):
        record_step(rec, i, ["ubuntu"], "ubuntu", {"type": "CLICK", "x": 300 + 100 * i, "y": 200 + 50 * i}, f"Step {i}.")
    record_step(rec, 3, ["ubuntu"], "ubuntu", {"type": "DONE"}, "Done.")
    names = ["ubuntu-rename", "ubuntu-zip", "ubuntu-check-size"]
    finish_task(rec, [_verdict(i, n, "ubuntu", [("check", i < passed, "ok" if i < passed else "sales.zip is missing")])
                      for i, n in enumerate(names)], "done", 4)


def write_finished_run(root: Path, run_id: str = FINISHED_RUN) -> Path:
    """A run that ended: four tasks (passed, failed, infrastructure error, composed) and run.json."""
    run_dir = root / run_id
    run_dir.mkdir(parents=True, exist_ok=True)
    write_json_atomic(run_dir / "plan.json", {"tasks": ["md-photo-to-doc[seed1]", "sw-rename-and-zip[seed2]",
                                                        "ubuntu-calc-sum[seed0]", "windows-notepad-save[seed0]"]})
    _calc_task(run_dir, passed=True)
    _transfer_task(run_dir)
    _boot_error_task(run_dir)
    _sw_task(run_dir, passed=2)
    write_json_atomic(run_dir / "run.json", {"run_id": run_id, "agent": AGENT, "started": "2025-01-01T10:00:00+00:00",
                                             "finished": "2025-01-01T10:20:00+00:00", "tasks": 4})
    return run_dir


def write_live_run(root: Path, run_id: str = LIVE_RUN) -> tuple[Path, TaskRecorder]:
    """A run in progress (no run.json): one task done, one running (its recorder is returned, open), two pending."""
    run_dir = root / run_id
    run_dir.mkdir(parents=True, exist_ok=True)
    write_json_atomic(run_dir / "plan.json", {"tasks": ["md-photo-to-doc[seed1]", "sw-rename-and-zip[seed2]",
                                                        "ubuntu-calc-sum[seed0]", "windows-notepad-save[seed0]"]})
    _calc_task(run_dir, passed=False)
    rec = start_task(run_dir, "sw-rename-and-zip[seed2]", "sw", ["ubuntu"],
                     "Rename data.csv to sales.csv, then compress it into sales.zip.")
    record_step(rec, 0, ["ubuntu"], "ubuntu", {"type": "CLICK", "x": 640, "y": 400}, "Open the file manager.")
    record_step(rec, 1, ["ubuntu"], "ubuntu", {"type": "RIGHT_CLICK", "x": 500, "y": 300}, "Open the context menu.")
    return run_dir, rec


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1:
        print("usage: python -m jarvis_pytest.dashboard.sample RESULTS_DIR", file=sys.stderr)
        return 2
    root = Path(args[0])
    write_finished_run(root)
    write_live_run(root)
    print(f"sample results in {root.resolve()}: jarvis dashboard --results {root}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
