"""Which window the oracle's GUI steps act on (`agents/oracle.py`, `SubtaskWindows`), against a recording stand-in
for a device: on a device that names windows a subtask's window is the one its `opens` step launched (not another
window of the same title), it is checked before every GUI action and not before commands or waits, a window that
is gone fails the oracle, and the subtask's commands are told its window and process; a device that does not
name windows gets the title brought to the front once, as before. The same on real Wine windows:
`tests/test_device_windows.py::test_the_oracle_acts_on_its_subtasks_window_not_on_another_of_the_same_title`."""

from __future__ import annotations

from types import SimpleNamespace

from jarvis_pytest.agents.oracle import OracleAgent, SubtaskWindows, brief, carry_out, oracle_plan
from jarvis_pytest.agents.protocol import TaskContext
from jarvis_pytest.devices.base import ActionOutcome, CommandResult
from jarvis_pytest.devices.protocol import LaunchResponse
from jarvis_pytest.tasks.model import Launch, SolutionStep

TITLE = "notes.rtf - *wordpad"
OLD, NEW = 7, 3  # window ids: the earlier subtask's window has the higher id (ids are no age)


class Windows:
    """A device that names windows: two WordPads on one file, records every call."""

    names_windows = True
    platform = "windows"

    def __init__(self, gone: bool = False):
        self.calls: list[tuple] = []
        self.gone = gone

    def launch_window(self, app, *args, window_wait=20.0):
        self.calls.append(("launch", app, *args))
        return LaunchResponse(window=True, id=NEW)

    def focus_window(self, title=None, *, id=None, timeout=5.0):
        self.calls.append(("focus", title, id))
        if self.gone and id is not None and len([c for c in self.calls if c[0] == "focus"]) > 1:
            return None
        chosen = id if id is not None else OLD  # by title alone the device may pick the other window
        return {"ok": True, "window": True, "id": chosen, "title": "notes.rtf - Wine Wordpad", "pid": 40 + chosen,
                "changed": True, "before": {"id": 99, "title": "Untitled - Notepad", "pid": 5}}

    def run(self, command, *, timeout=60.0, user=None):
        self.calls.append(("run", command))
        return CommandResult(0, "", "")

    def act(self, action):
        self.calls.append(("act", action.type))
        return ActionOutcome(ok=True)


class Plain(Windows):
    """A device that does not name windows (Ubuntu's server)."""

    names_windows = False
    platform = "ubuntu"

    def focus(self, title, *, timeout=5.0):
        self.calls.append(("focus by title", title))
        return True

    def launch(self, app, *args, window_wait=20.0):
        self.calls.append(("launch", app, *args))
        return True


def subtasks(platform: str = "windows"):
    earlier = SimpleNamespace(platform=platform, window=TITLE, opens=None, solution=[])
    later = SimpleNamespace(
        platform=platform, window=TITLE, opens=[Launch(app="wordpad", args=["notes.rtf"])],
        solution=[SolutionStep(command="mark"), SolutionStep(action={"type": "HOTKEY", "keys": ["alt", "f"]}),
                  SolutionStep(command="wait for the menu"), SolutionStep(action={"type": "WAIT", "seconds": 0.5}),
                  SolutionStep(action={"type": "TYPING", "text": "x"})])
    return (earlier, later)


def run_agent(device) -> list:
    agent = OracleAgent()
    agent.reset(TaskContext("t", "-", (device.platform,)))
    assert brief(agent, subtasks(device.platform), {device.platform: device})
    steps = []
    while True:
        step = agent.act({}, [])
        steps.append(step)
        if step.action.type in ("DONE", "FAIL"):
            return steps
        device.act(step.action)


def test_the_window_an_opens_step_launched_is_the_subtasks_window_for_every_gui_step():
    device = Windows()
    steps = run_agent(device)
    assert steps[-1].action.type == "DONE"
    focus = [c for c in device.calls if c[0] == "focus"]
    # the plan's focus: the launched window once it shows the title; then by id before each GUI action (two),
    # never by title alone (which could name the other window)
    assert focus == [("focus", TITLE, NEW), ("focus", None, NEW), ("focus", None, NEW)]
    order = [c[0] if c[0] != "act" else c[1] for c in device.calls if c[1:] != ("WAIT",)]  # WAITs: no window
    assert order == ["launch", "run", "focus", "focus", "HOTKEY", "run", "focus", "TYPING"]
    # commands after the window is known are told it; the one before is not
    runs = [c[1] for c in device.calls if c[0] == "run"]
    assert runs == ["mark", f'set "JARVIS_WINDOW={NEW}"& set "JARVIS_WINDOW_PID={40 + NEW}"& wait for the menu']
    records = [s.extra["focus"] for s in steps if "focus" in s.extra]
    assert {r["window"] for r in records} == {NEW} and all(r["changed"] for r in records)
    waited = next(s for s in steps if s.extra.get("commands") and "menu" in s.extra["commands"][0]["command"])
    assert waited.extra["commands"][0]["command"] == "wait for the menu"  # the step's own command, and its env
    assert waited.extra["commands"][0]["env"] == {"JARVIS_WINDOW": str(NEW), "JARVIS_WINDOW_PID": str(40 + NEW)}


def test_a_window_that_is_gone_fails_the_oracle_with_the_reason():
    steps = run_agent(Windows(gone=True))
    assert steps[-1].action.type == "FAIL"
    assert f"the subtask's window {NEW}" in steps[-1].reasoning and "is gone" in steps[-1].reasoning
    assert [s.action.type for s in steps].count("HOTKEY") == 0  # no key went anywhere


def test_carry_out_keeps_the_windows_across_a_plan():
    device = Windows()
    windows = SubtaskWindows()
    for item in oracle_plan(subtasks()):
        assert carry_out(item, {"windows": device}, windows) is None
    assert [c for c in device.calls if c[0] == "focus"][0] == ("focus", TITLE, NEW)
    assert windows.ids == {1: NEW}


def test_a_device_that_does_not_name_windows_gets_the_title_brought_to_the_front_once():
    device = Plain()
    steps = run_agent(device)
    assert steps[-1].action.type == "DONE"
    assert [c for c in device.calls if c[0].startswith("focus")] == [("focus by title", TITLE)]
    assert [c[1] for c in device.calls if c[0] == "run"] == ["mark", "wait for the menu"]
