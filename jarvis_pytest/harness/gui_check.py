"""The quality gate's fourth check (`jarvis qc`): the task passes after its GUI solution.

After the three checks of the gate (every evaluator fails on the fresh device, the task fails on each near-miss
state, it passes after the oracle), each atomic task runs its template's `gui_solution` on fresh devices: set up
as for any agent, then the built-in GUI oracle (`agents/gui_oracle.py`) through the harness's own step loop, so
the devices see exactly what an agent's actions produce, then every evaluator. A template that says the GUI
cannot solve it on the run's backend (`gui_infeasible`) shows its reason instead, and one with neither counts
as "no GUI solution yet" (a violation on Ubuntu and Windows: `tasks/qc.GUI_REQUIRED`). Its trajectory and screenshots
are in the task's `gui/` folder.
"""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path
from typing import Any

from jarvis_pytest.agents.gui_oracle import GuiOracleAgent, backend_name
from jarvis_pytest.agents.oracle import brief
from jarvis_pytest.agents.protocol import TaskContext
from jarvis_pytest.errors import retry_device_faults
from jarvis_pytest.harness.evaluation import capture_baselines, evaluate_subtasks
from jarvis_pytest.harness.loop import LoopLimits, begin, run_loop
from jarvis_pytest.harness.setup_steps import run_setup, window_titles
from jarvis_pytest.results.model import GuiCheck, StepRecord
from jarvis_pytest.tasks.model import Task

GUI_FOLDER = "gui"


class FolderRecorder:
    """A trajectory and its screenshots in one folder (emptied first): what `run_loop` writes a task's into."""

    def __init__(self, folder: Path):
        if folder.exists():
            shutil.rmtree(folder)
        folder.mkdir(parents=True)
        self.dir = folder
        self.acted_on: set[str] = set()
        self.errors: list[str] = []
        self.last: StepRecord | None = None
        self._traj = open(folder / "traj.jsonl", "a", encoding="utf-8")

    def screenshot(self, step: int, platform: str, png: bytes) -> str:
        name = f"step_{step:04d}_{platform}.png"
        (self.dir / name).write_bytes(png)
        return name

    def step(self, record: StepRecord) -> None:
        self._traj.write(json.dumps(record.model_dump(mode="json"), ensure_ascii=True) + "\n")
        self._traj.flush()
        self.last = record
        if record.error:
            self.errors.append(record.error)
        if record.action is not None and record.platform:
            self.acted_on.add(record.platform)

    def close(self) -> None:
        self._traj.close()


def _gui_run(task: Task, platforms: tuple[str, ...], environments: Any, limits: LoopLimits,
             folder: Path) -> tuple[str, str, int, list]:
    """The GUI solution on freshly booted and set-up devices, then the evaluators: (state, reason, steps, verdicts)."""
    subtasks = task.formatted_subtasks
    env = environments.acquire(platforms)
    recorder = FolderRecorder(folder)
    try:
        opened = run_setup(subtasks, env.devices)
        baselines = capture_baselines(subtasks, env.devices)
        agent = GuiOracleAgent()
        failed_reset = begin(agent, TaskContext(task_id=task.id, instruction=task.instruction, platforms=platforms),
                             limits)
        if failed_reset is not None:  # our own agent: a bug, said as the check's failure
            return "failed", failed_reset, 0, []
        brief(agent, subtasks, env.devices, dict(getattr(env, "backends", {})), window_titles(opened, env.devices))
        planned = sum(len(s.gui_solution or []) for s in subtasks)
        outcome = run_loop(agent, env.devices, {}, recorder,
                           LoopLimits(max_steps=max(limits.max_steps, planned + 5), step_timeout=limits.step_timeout,
                                      task_timeout=limits.task_timeout))
        for platform, device in sorted(env.devices.items()):
            recorder.screenshot(outcome.steps, platform, device.observe().screenshot_png)
        verdicts = evaluate_subtasks(subtasks, env.devices, env.transfer, baselines, task.edges)
        if outcome.end_reason != "done":
            said = recorder.errors[0] if recorder.errors else (recorder.last.reasoning if recorder.last else "")
            return "failed", f"the GUI solution ended with {outcome.end_reason}: {said}"[:1000], outcome.steps, verdicts
        bad = [f"{e.func}: {e.reason}" for v in verdicts for e in v.evaluators if not e.passed]
        if bad:
            return "failed", "after the GUI solution: " + bad[0], outcome.steps, verdicts
        return "passed", "", outcome.steps, verdicts
    finally:
        recorder.close()
        env.close()


def run_gui_check(task: Task, platforms: tuple[str, ...], environments: Any, backends: dict[str, str],
                  limits: LoopLimits, folder: Path) -> list[GuiCheck]:
    """The fourth check of an atomic task (`backends`: platform → the label of the backend its run used). A device
    fault is tried again on fresh devices; the last one is raised."""
    out: list[GuiCheck] = []
    for s, sub in enumerate(task.formatted_subtasks):
        backend = backend_name(backends.get(sub.platform, ""))
        base = {"subtask": s, "template": sub.template, "app": sub.app, "backend": backend}
        reason = (sub.gui_infeasible or {}).get(backend)
        if reason:
            out.append(GuiCheck(**base, state="infeasible", reason=reason))
        elif not sub.gui_solution:
            out.append(GuiCheck(**base, state="none"))
        else:
            t0 = time.monotonic()
            (state, why, steps, verdicts), faults = retry_device_faults(
                lambda _: _gui_run(task, platforms, environments, limits, folder))
            out.append(GuiCheck(**base, state=state, reason=why, steps=steps, verdicts=verdicts,
                                device_faults=faults, seconds=round(time.monotonic() - t0, 3)))
    return out
