"""The GUI oracle on a real Ubuntu device, through the harness's step loop: a control found by its role and name
in the AT-SPI tree is clicked at the centre of its box (the trajectory records the plain CLICK), and a target that
never shows is the step's error, recorded within its timeout, after which the oracle gives up."""

from __future__ import annotations

import json
import time

import pytest

from jarvis_pytest.agents.gui_oracle import GuiOracleAgent, find_target
from jarvis_pytest.agents.oracle import brief
from jarvis_pytest.agents.protocol import TaskContext
from jarvis_pytest.devices.actions import Hotkey
from jarvis_pytest.harness.gui_check import FolderRecorder
from jarvis_pytest.harness.loop import LoopLimits, run_loop
from jarvis_pytest.tasks.instances import materialise
from jarvis_pytest.tasks.model import GuiTarget, TaskTemplate

pytestmark = pytest.mark.containers

NOTE = "/home/user/Documents/gui_probe.txt"


def subtasks(steps: list[dict]) -> list:
    template = TaskTemplate.model_validate({
        "id": "ubuntu-test-gui_probe", "platform": "ubuntu", "app": "Text Editor", "instruction": "Probe.",
        "evaluate": [{"func": "file_text_equals", "args": {"path": NOTE, "expected": "x"}}],
        "gui_solution": steps})
    return [materialise(template, {}, gui=True)]


def run(env, steps: list[dict], folder) -> tuple[list[dict], str, float]:
    """The GUI oracle on `steps` through `run_loop`: the trajectory's records, the end reason, the seconds."""
    agent = GuiOracleAgent()
    agent.reset(TaskContext(task_id="probe", instruction="Probe.", platforms=("ubuntu",)))
    assert brief(agent, subtasks(steps), env.devices, {"ubuntu": "ubuntu (docker)"})
    recorder = FolderRecorder(folder)
    t0 = time.monotonic()
    try:
        outcome = run_loop(agent, env.devices, {}, recorder, LoopLimits(max_steps=20, step_timeout=60))
    finally:
        recorder.close()
    records = [json.loads(line) for line in (folder / "traj.jsonl").read_text().splitlines()]
    return records, outcome.end_reason, time.monotonic() - t0


def test_a_control_found_by_role_and_name_is_clicked_at_its_centre(ubuntu_env, tmp_path):
    device = ubuntu_env.devices["ubuntu"]
    device.upload(NOTE, b"one\ntwo\n")
    assert device.launch("mousepad", NOTE)
    box = GuiTarget.model_validate({"window": "Find and Replace",
                                    "control": {"role": "check box", "name": "Match case"}})
    records, end, _ = run(ubuntu_env, [
        {"type": "CLICK", "target": {"window": "gui_probe.txt - Mousepad", "control": {"role": "text"}}},
        {"type": "HOTKEY", "keys": ["ctrl", "r"]},
        {"type": "WAIT_FOR", "target": {"window": "Find and Replace"}, "timeout": 20},
        {"type": "CLICK", "target": box.model_dump(by_alias=True, exclude_none=True)}], tmp_path / "found")
    assert end == "done", records
    click = records[3]
    assert click["action"]["type"] == "CLICK" and not click["error"], click
    x, y, w, h = click["extra"]["resolved"]["box"]
    assert (click["action"]["x"], click["action"]["y"]) == (x + w // 2, y + h // 2), click
    assert records[2]["action"] == {"type": "WAIT", "seconds": 0.0} and "shows after" in records[2]["reasoning"]
    node, _ = find_target(device.a11y_tree()["tree"], box)  # the click landed on the control: it is checked now
    assert node is not None and "checked" in node["states"], node
    device.act(Hotkey(keys=["Escape"]))


def test_a_target_that_does_not_show_is_a_step_error_within_its_timeout(ubuntu_env, tmp_path):
    records, end, seconds = run(ubuntu_env, [
        {"type": "CLICK", "target": {"control": {"role": "push button", "name": "No Such Button"}}, "timeout": 1.5},
        {"type": "HOTKEY", "keys": ["ctrl", "q"]}], tmp_path / "missing")
    assert end == "fail", records
    first, last = records[0], records[-1]
    assert first["action"] is None and "did not show within 1.5 s" in first["error"], first
    assert "No Such Button" in first["error"]
    assert 1.5 <= first["agent_ms"] / 1000 < 3.2, first["agent_ms"]  # the timeout, a poll and a read more at most
    assert last["action"] == {"type": "FAIL"} and "did not show" in last["reasoning"]
    assert len(records) == 2 and seconds < 15  # the next step was never taken


def test_a_calc_sheet_is_read_in_time_without_its_cells(ubuntu_env):
    """A LibreOffice Calc sheet has 2^31 - 1 cells on the accessibility bus, made on demand: the walk keeps the
    sheet without its children (`children_skipped`) and ends in time, so targets in Calc can be found. (Before,
    the walk asked for every cell and never ended: the request timed out.)"""
    device = ubuntu_env.devices["ubuntu"]
    assert device.launch("libreoffice", "--calc", "--norestore", window_wait=90)
    sheet = GuiTarget.model_validate({"window": "LibreOffice Calc", "control": {"role": "table"}})
    deadline = time.monotonic() + 90
    node = None
    while node is None and time.monotonic() < deadline:
        t0 = time.monotonic()
        answer = device.a11y_tree(max_nodes=5000, timeout=8)
        assert time.monotonic() - t0 < 15, "one read of the tree took longer than its time limit"
        node, _ = find_target(answer["tree"], sheet)
    assert node is not None and node["children_skipped"] >= 2 ** 20 and "children" not in node, node
    device.run("pkill -x soffice.bin")
