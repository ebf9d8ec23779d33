"""The oracle: the tasks' reference solutions, as a plan of steps, and the agent that carries the plan out.

The plan of a task (`oracle_plan`) is every subtask's solution in order, each step tagged with its subtask: before a
subtask's first GUI step in a composed task its window (the template's `window`) is brought to the front, and a
file an upstream subtask made is opened first (`opens`: set-up held those steps back, the instruction asks for
them). Every GUI step knows the window it acts on (`SubtaskWindows`): on a device that names windows (Windows) a
subtask's window is one window, not a title, and it is checked to hold the foreground before each of its GUI
actions. The quality gate changes plans to make near-miss wrong chains (`harness/chain_negatives.py`) and carries
them out directly (`carry_out`); the agent carries the plan out through the harness's step loop.

The oracle is the one agent that sees the solution and holds the devices, and it gets them through `brief`, not
through the agent protocol: `brief` hands them to an instance of exactly `OracleAgent` (the class object, not its
name, a subclass or a look-alike) and to nothing else. `OracleAgent` has slots, so an instance's methods cannot
be swapped for others that read what it was handed.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Literal, Sequence

from jarvis_pytest.agents.protocol import AgentStep, HistoryEntry, TaskContext
from jarvis_pytest.devices.actions import Done, Fail, Wait, parse_action
from jarvis_pytest.devices.base import Device, Observation
from jarvis_pytest.errors import DeviceFault


INPUT_FREE = frozenset({"WAIT", "DONE", "FAIL"})  # action types that send nothing to a window
OPENED_TITLE_WAIT = 20.0  # seconds a window an `opens` step launched gets to show its subtask's title (its file)


@dataclass(frozen=True)
class PlanItem:
    """One step of an oracle plan: open a held-back file (`open`, `what` a Launch or Open step), bring a window to
    the front (`focus`, `what` its title), or a solution step (`step`, `what` a SolutionStep; `index` its place in
    its subtask's solution). `window`: the title of the subtask's window (the template's `window`), if it has one."""

    subtask: int
    platform: str
    kind: Literal["open", "focus", "step"]
    what: Any
    index: int = -1
    window: str | None = None


class SubtaskWindows:
    """Which window each subtask's GUI steps act on, and keeping it in front of them.

    A title does not name a window: after a Save As, or when a later subtask opens the same file again, two windows
    show one title (two WordPads on one file, one of them still holding what an earlier subtask did to it), and a
    key meant for one of them goes to whichever holds the foreground; a window that a program started a moment ago
    may also take the foreground after another was brought to the front, and closes a menu opened there. So on a
    device that names windows (`names_windows`: Windows) a subtask's window is one window id: the window its
    `opens` step launched (once it shows the subtask's title, i.e. its file is loaded), else the newest window
    showing that title when the subtask's first GUI step comes. Before every GUI action of the subtask the device
    checks that the foreground is that window's own (it, a menu it opened, a dialog it shows) and brings it back
    when it is not (`changed` in the record says so). A window that is gone, or that cannot be brought to the
    front, fails the oracle with the reason. On other devices the window is brought to the front by title before
    the subtask's first GUI step, as before.
    """

    def __init__(self) -> None:
        self.ids: dict[int, int] = {}  # subtask → its window
        self.pids: dict[int, int] = {}  # subtask → the process of its window
        self.opened: dict[int, int] = {}  # subtask → the window its `opens` step launched (title not seen yet)

    def launched(self, subtask: int, window: int | None) -> None:
        """The window that subtask `subtask`'s `opens` step made show (None: the device did not say)."""
        if window:
            self.opened[subtask] = window

    def bring(self, device: Device, subtask: int, title: str) -> dict[str, Any]:
        """Bring subtask `subtask`'s window (its title pattern `title`) to the front (on devices that name windows:
        unless the foreground is already its own). A record for the trajectory: `title`, `shown`, and on devices
        that name windows `window` (its id), `changed` (whether the foreground had to move), `before` (the
        foreground it replaced), or `error`."""
        if not getattr(device, "names_windows", False):
            return {"title": title, "shown": bool(getattr(device, "focus", lambda t: False)(title))}
        record: dict[str, Any] = {"title": title}
        if subtask in self.ids:
            answer = device.focus_window(id=self.ids[subtask])
            if answer is None:
                return {**record, "shown": False, "window": self.ids[subtask],
                        "error": f"the subtask's window {self.ids[subtask]} ({title!r}) is gone"}
        else:
            answer = None
            if subtask in self.opened:  # the window the subtask's `opens` launched, once it shows the file
                answer = device.focus_window(title, id=self.opened[subtask], timeout=OPENED_TITLE_WAIT)
                if answer is None:
                    record["opened_window_not_shown"] = self.opened[subtask]
            if answer is None:
                answer = device.focus_window(title)
            if answer is None:
                return {**record, "shown": False, "error": f"no window shows {title!r}"}
        if "error" in answer:
            return {**record, "shown": False, "window": self.ids.get(subtask), "error": answer["error"]}
        self.ids[subtask] = answer["id"]
        if answer.get("pid"):
            self.pids[subtask] = answer["pid"]
        before = answer.get("before") or {}
        record.update(shown=True, window=answer["id"], changed=bool(answer.get("changed")))
        if record["changed"]:
            record["before"] = {k: before.get(k) for k in ("id", "title", "pid")}
        return record

    def environment(self, device: Device, item: "PlanItem") -> dict[str, str]:
        """What a command of a plan step is told of its subtask's window, as environment variables: `JARVIS_WINDOW`
        (its id) and `JARVIS_WINDOW_PID` (its process), once known, so that a solution's wait for a menu or a
        dialog looks for one of that window's own (a Save As of another program, or of the other window on the
        same file, does not count). Empty where the device does not name windows."""
        if item.kind != "step" or not item.window or not getattr(device, "names_windows", False) \
                or item.subtask not in self.ids:
            return {}
        env = {"JARVIS_WINDOW": str(self.ids[item.subtask])}
        if item.subtask in self.pids:
            env["JARVIS_WINDOW_PID"] = str(self.pids[item.subtask])
        return env

    def before_action(self, device: Device, item: "PlanItem") -> dict[str, Any] | None:
        """The check before a GUI action of a plan step (`bring`: the foreground is left alone when it is already the
        window's own); None when the step sends nothing to a window, its subtask names no window, or the device does
        not name windows."""
        step = item.what
        if item.kind != "step" or step.action is None or not item.window \
                or not getattr(device, "names_windows", False) or step.action.get("type") in INPUT_FREE:
            return None
        return self.bring(device, item.subtask, item.window)


def oracle_plan(subtasks: Sequence[Any]) -> list[PlanItem]:
    """The plan of a task whose subtasks (`tasks.model.Subtask`, in execution order) are `subtasks`."""
    composed = len(subtasks) > 1
    plan: list[PlanItem] = []
    for s, sub in enumerate(subtasks):
        for opener in sub.opens or []:
            plan.append(PlanItem(s, opener.platform or sub.platform, "open", opener))
        focus = composed and bool(sub.window)
        for i, step in enumerate(sub.solution):
            platform = step.platform or sub.platform
            if focus and step.action is not None:
                plan.append(PlanItem(s, platform, "focus", sub.window))
                focus = False
            window = sub.window if sub.window and platform == sub.platform else None
            plan.append(PlanItem(s, platform, "step", step, i, window=window))
    return plan


def run_command(device: Device, item: PlanItem, env: dict[str, str] | None = None) -> tuple[Any, dict[str, Any]]:
    """Run a plan item's command on `device`: its result and a record for the trajectory. `env`: environment
    variables for it (`SubtaskWindows.environment`; set by `cmd`'s `set` before the command, on Windows). A device
    fault (the device's, not the solution's) raises DeviceFault."""
    step = item.what
    command = "".join(f'set "{k}={v}"& ' for k, v in (env or {}).items()) + step.command
    t0 = time.monotonic()
    result = device.run(command, user=step.user, timeout=float(step.timeout or 120))
    if result.fault:
        raise DeviceFault(f"an oracle command hit a device fault: {result.fault}: {step.command[:300]}")
    record = {"platform": item.platform, "command": step.command, "user": step.user,
              "returncode": result.returncode, "seconds": round(time.monotonic() - t0, 3),
              "output": (result.stdout[-500:] + result.stderr[-500:]).strip()}
    if env:
        record["env"] = dict(env)
    return result, record


def open_held(device: Device, opener: Any) -> tuple[str, bool, int | None]:
    """Carry out a held-back set-up step that opens a file: (what was opened, whether its window shows, that
    window's id where the device names windows)."""
    what = f"{opener.app} {' '.join(opener.args)}" if opener.type == "launch" else opener.path
    if getattr(device, "names_windows", False):
        answer = device.launch_window(opener.app, *opener.args) if opener.type == "launch" \
            else device.open_window(opener.path)
        return what, bool(answer.window), answer.id
    shown = device.launch(opener.app, *opener.args) if opener.type == "launch" else device.open(opener.path)
    return what, bool(shown), None


def carry_out(item: PlanItem, devices: dict[str, Device], windows: SubtaskWindows | None = None) -> str | None:
    """Carry out one plan item directly on the devices (no agent loop); what went wrong, or None. `windows`: the
    subtasks' windows so far (one object for the whole plan; without it each GUI step finds its window anew)."""
    windows = windows if windows is not None else SubtaskWindows()
    device = devices[item.platform]
    if item.kind == "open":
        windows.launched(item.subtask, open_held(device, item.what)[2])
        return None
    if item.kind == "focus":
        record = windows.bring(device, item.subtask, item.what)
        return f"focus: {record['error']}" if "error" in record else None
    step = item.what
    if step.command is not None:
        result, _ = run_command(device, item, windows.environment(device, item))
        if result.returncode != 0:
            return f"command failed ({result.returncode}): {step.command[:200]}"
        return None
    record = windows.before_action(device, item)
    if record and "error" in record:
        return f"action {step.action}: {record['error']}"
    outcome = device.act(parse_action(step.action))
    return None if outcome.ok else f"action {step.action} failed: {outcome.error}"


class OracleAgent:
    """Carries out the task's oracle plan (`oracle_plan`), handed to it by `brief` after `reset`.

    A solution step is either `{"action": {...}}` (an action of the unified action space, sent through the
    harness like any agent's action) or `{"command": "...", "user": ..., "platform": ...}` (run on the device
    directly, on the devices `brief` handed it). A step's platform defaults to its subtask's platform. Each
    command is one step of the trajectory, on its device, with the command, its return code, its time and the end
    of its output (as a WAIT(0) action, so replays skip it). A failing command ends the task with FAIL and the
    command's output as reasoning; so does a task it was not briefed on.
    """

    __slots__ = ("options", "devices", "queue", "last_platform", "failed", "windows", "briefed")
    name = "oracle"

    def __init__(self, options: dict[str, Any] | None = None):
        self.options = dict(options or {})
        self.reset(TaskContext(task_id="", instruction="", platforms=()))

    def reset(self, task: TaskContext) -> None:
        """Forget the previous task; the plan and the devices of this one come with `brief`."""
        self.devices: dict[str, Device] = {}
        self.queue: list[PlanItem] = []
        self.last_platform: str | None = task.platforms[0] if task.platforms else None
        self.failed: AgentStep | None = None
        self.windows = SubtaskWindows()
        self.briefed = False

    def act(self, observations: dict[str, Observation], history: list[HistoryEntry]) -> AgentStep:
        if not self.briefed:
            return AgentStep(platform=self.last_platform, action=Fail(),
                             reasoning="oracle: the harness handed it no solution for this task (`brief`)")
        if self.failed is not None:
            return self.failed
        if not self.queue:
            return AgentStep(platform=self.last_platform, action=Done(), reasoning="oracle solution complete")
        item = self.queue.pop(0)
        platform = self.last_platform = item.platform
        if item.kind == "open":  # a held-back set-up step: open the upstream's file
            what, shown, window = open_held(self.devices[platform], item.what)
            self.windows.launched(item.subtask, window)
            opened = {"what": what, "window": shown} | ({"id": window} if window else {})
            return AgentStep(platform=platform, action=Wait(seconds=0), reasoning=f"oracle: open {what} "
                             f"({'its window shows' if shown else 'no window yet'})", extra={"opened": opened})
        if item.kind == "focus":  # bring the subtask's window to the front
            record = self.windows.bring(self.devices[platform], item.subtask, item.what)
            if "error" in record:
                return self._fail(platform, f"oracle: cannot bring the window {item.what!r} to the front: "
                                            f"{record['error']}", {"focus": record})
            return AgentStep(platform=platform, action=Wait(seconds=0), reasoning=f"oracle: bring the window "
                             f"{item.what!r} to the front ({'done' if record['shown'] else 'no such window'})",
                             extra={"focus": record})
        step = item.what
        if step.action is not None:
            record = self.windows.before_action(self.devices[platform], item)
            if record and "error" in record:
                return self._fail(platform, f"oracle: the window of {step.action} is not in front: "
                                            f"{record['error']}", {"focus": record})
            return AgentStep(platform=platform, action=parse_action(step.action),
                             reasoning=step.note or "oracle solution step",
                             extra={"focus": record} if record else {})
        result, record = run_command(self.devices[platform], item,
                                     self.windows.environment(self.devices[platform], item))
        if result.returncode != 0:
            self.failed = AgentStep(platform=platform, action=Fail(), extra={"commands": [record]},
                                    reasoning=f"oracle command failed ({result.returncode}): {step.command}\n"
                                              f"{result.stdout[-1000:]}{result.stderr[-1000:]}")
            return self.failed
        return AgentStep(platform=platform, action=Wait(seconds=0),
                         reasoning=f"{step.note or 'oracle command'}: $ {step.command[:300]}",
                         extra={"commands": [record]})

    def _fail(self, platform: str, reasoning: str, extra: dict[str, Any]) -> AgentStep:
        self.failed = AgentStep(platform=platform, action=Fail(), reasoning=reasoning, extra=extra)
        return self.failed

    def config(self) -> dict[str, Any]:
        return {"name": self.name}


def brief(agent: Any, subtasks: Sequence[Any], devices: dict[str, Device],
          backends: dict[str, str] | None = None, windows: dict[int, str] | None = None) -> bool:
    """Hand the task's solution (its formatted subtasks, in execution order) and its devices to `agent` if it is
    the built-in oracle: an instance of exactly `OracleAgent`, this module's class object (no name, attribute,
    subclass or copy of it qualifies). The built-in GUI oracle (exactly `gui_oracle.GuiOracleAgent`) is handed the
    subtasks' GUI solutions and a view of the devices' accessibility trees instead, never the devices (`backends`:
    platform → the label of the backend that runs it, for its `gui_infeasible`; `windows`: subtask → the title of
    the window its set-up opened, for subtasks whose template names none, to bring it to the front). The browser player's agent
    (exactly `player.agent.HumanAgent`) is handed a view of each device's screen, for its page to show it live:
    screenshots only, nothing of the solution. Call it after `agent.reset`. Whether `agent` was briefed; any other
    agent is handed nothing."""
    from jarvis_pytest.agents.gui_oracle import GuiOracleAgent, brief_gui
    from jarvis_pytest.player.agent import HumanAgent, brief_human

    if type(agent) is GuiOracleAgent:
        brief_gui(agent, subtasks, devices, backends, windows)
        return True
    if type(agent) is HumanAgent:
        brief_human(agent, devices)
        return True
    if type(agent) is not OracleAgent:
        return False
    agent.queue = oracle_plan(subtasks)
    agent.devices = dict(devices)
    agent.briefed = True
    return True
