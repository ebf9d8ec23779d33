"""The agent `human`: a person playing the task in the browser player (`jarvis play <task>`).

It is an agent like any other: the runner sets up the task, the step loop observes and calls `act()`, executes
the action and records the step, and the task is evaluated as any agent's. `act()` shows the step's screens in the
page and waits for the person's next input, which `inputs.py` turns into one action of the unified action space.
So what a person did is a `traj.jsonl` of plain actions that `--agent replay` carries out again, and it can be
saved as a template's GUI solution (`solution.py`).

Time: a person is not a model call, so the loop does not hold their decisions to `--step-timeout` (which bounds
model calls): an agent with `paced_by_person` has until the task's time limit (`--task-timeout`, then status
`timeout`) for each step; the step limit (`--max-steps`) holds as for any agent. Each step records in its
`extra["player"]` the person's think time (`think_ms`: from the step's screen first shown in the page to the
input that made the action, 0 for an input made before the screen came), and the loop's `agent_ms` is the whole
wait; the result's `durations` give the task's time (`loop`: from the first screen to the last action; `agent`:
the time spent waiting for the person).

What it is handed: like any agent, the instruction, the platforms and the observations at each step; and, through
`oracle.brief` (which recognises this class object, as it does the oracles'), a view of each device's screen for
the page to show it live between steps (screenshots only: what an agent sees, as often as the person looks; no
commands, no files, no accessibility tree).
"""

from __future__ import annotations

import collections
import os
import sys
import threading
import time
from pathlib import Path
from typing import Any, Callable

from jarvis_pytest.agents.protocol import AgentStep, HistoryEntry, TaskContext
from jarvis_pytest.devices.actions import Fail
from jarvis_pytest.devices.base import Observation
from jarvis_pytest.errors import ConfigError
from jarvis_pytest.llm.deadline import remaining
from jarvis_pytest.player.inputs import Input, InputRefused, describe, is_touch, merge, translate

FRAME_CACHE = 0.15  # seconds a live frame is reused for another request of the page
# seconds without a request of the page (after its first) that end the task as the person's FAIL: the tab was
# closed, and the devices are not held until the task's time limit. A hidden tab still asks about once a minute
# (Chromium's intensive timer throttling), so it is not taken for a closed one.
ABANDON_AFTER = 180.0
QUEUE_LIMIT = 200  # inputs made ahead of the steps that carry them out
LOG_LENGTH = 8  # steps the page lists


class NotTaking(InputRefused):
    """An input at a moment the player takes none (no task yet, the task ended): answered 409."""


class ScreenView:
    """What the player is given of one device: its screen, and nothing else of it."""

    __slots__ = ("_grab",)

    def __init__(self, device: Any):
        self._grab: Callable[[], bytes] = lambda: device.observe().screenshot_png

    def png(self) -> bytes:
        return self._grab()


class Player:
    """The state the page and the agent share: the task, the step waiting for input, the screens, the inputs made
    and not yet carried out. Every method is thread-safe (the page's requests come from the server's threads,
    `decide` from the loop's)."""

    def __init__(self) -> None:
        self.cond = threading.Condition()
        self.task: TaskContext | None = None
        self.tasks = 0  # tasks begun
        self.step = -1  # the index of the step the loop asked for last
        self.waiting = False  # the loop waits for the person's input
        self.step_started = 0.0
        self.shown_at: float | None = None  # when the page first showed a screen of the current step
        self.sizes: dict[str, tuple[int, int]] = {}  # platform → the screen size of its latest observation
        self.shots: dict[str, bytes] = {}  # platform → its latest observation's screenshot
        self.views: dict[str, ScreenView] = {}
        self.ready: collections.deque[Input] = collections.deque()
        self.pending: Input | None = None  # text, wheel turns or a click that later events may still extend
        self.last_seq = 0
        self.ending: str | None = None  # "done" / "fail": the person ended the task (no more inputs)
        self.log: collections.deque[dict[str, Any]] = collections.deque(maxlen=LOG_LENGTH)
        self.last_error: str | None = None
        self._frames: dict[str, tuple[float, bytes]] = {}
        self._grab_locks: dict[str, threading.Lock] = collections.defaultdict(threading.Lock)
        self.seen: float | None = None  # when the page last asked anything (None: it has not yet)
        self.abandon_after = ABANDON_AFTER

    # -- the loop's side ------------------------------------------------------------------------------------
    def begin(self, task: TaskContext) -> None:
        with self.cond:
            self.task, self.tasks = task, self.tasks + 1
            self.step, self.waiting, self.shown_at = -1, False, None
            self.sizes, self.shots, self.views, self._frames = {}, {}, {}, {}
            self.ready.clear()
            self.pending, self.ending, self.last_error = None, None, None
            self.log.clear()
            self.cond.notify_all()

    def decide(self, observations: dict[str, Observation], history: list[HistoryEntry]) -> AgentStep:
        """Show the step's screens and wait for the person's next input (until the step's deadline, which for a
        person is the task's)."""
        with self.cond:
            self.step = len(history)
            self.last_error = history[-1].error if history else None
            if history and history[-1].error and self.log:
                self.log[-1]["error"] = history[-1].error
            for platform, obs in observations.items():
                if obs.available:
                    self.sizes[platform] = (obs.width, obs.height)
                    self.shots[platform] = obs.screenshot_png
            self._frames = {}  # the next frame is taken after the last action
            self.step_started, self.shown_at, self.waiting = time.monotonic(), None, True
            self.cond.notify_all()
            try:
                item = self._next()
            finally:
                self.waiting = False
            if item is None:
                return AgentStep(platform=None, action=None,
                                 error="the person made no input before the step's deadline")
            if item == "left":
                self.ending = "fail"
                return AgentStep(platform=self.task.platforms[0] if self.task and self.task.platforms else None,
                                 action=Fail(), reasoning=f"the person left: the player's page asked nothing for "
                                                          f"{self.abandon_after:g} s (its tab was closed)")
            shown = self.shown_at if self.shown_at is not None else self.step_started
            queued = item.at < self.step_started
            think = 0.0 if queued else max(0.0, item.at - shown)
            self.log.append({"index": self.step, "platform": item.platform, "action": describe(item.action),
                             "think_s": round(think, 1), "error": None})
            self.cond.notify_all()
        said = {"think_ms": round(think * 1000), "queued": queued, "events": item.events, "input": item.raw}
        return AgentStep(platform=item.platform, action=item.action, reasoning=f"a person in the player: "
                         f"{describe(item.action)}", extra={"player": said})

    def _next(self) -> Input | str | None:
        """The next input (the oldest made), waiting for one; None once the step's deadline passed; "left" once
        the page, having asked before, asked nothing for `abandon_after` seconds."""
        while True:
            now = time.monotonic()
            if self.ready:
                return self.ready.popleft()
            if self.pending is not None and now >= self.pending.open_until():
                self.ready.append(self.pending)
                self.pending = None
                continue
            left = remaining()
            if left is not None and left <= 0:
                return None
            if self.seen is not None and now - self.seen > self.abandon_after:
                return "left"
            waits = [1.0] + ([left] if left is not None else [])
            if self.pending is not None:
                waits.append(self.pending.open_until() - now)
            self.cond.wait(max(0.01, min(waits)))

    # -- the page's side ------------------------------------------------------------------------------------
    def receive(self, event: dict[str, Any]) -> dict[str, Any]:
        """Take one event of the page (see `inputs.translate`); raises InputRefused (or NotTaking) with why not."""
        seq = event.get("seq")
        with self.cond:
            self.seen = time.monotonic()
            if isinstance(seq, bool) or not isinstance(seq, int):
                raise InputRefused("an event needs its sequence number `seq` (an integer)")
            if self.task is None:
                raise NotTaking("no task has started yet")
            if self.ending is not None:
                raise NotTaking(f"the task has ended ({self.ending.upper()})")
            if seq <= self.last_seq:  # sent twice: taken once
                return {"accepted": False, "duplicate": True}
            platform = event.get("platform")
            if platform not in self.task.platforms:
                raise InputRefused(f"the task does not use {platform!r} (it uses {', '.join(self.task.platforms)})")
            if len(self.ready) >= QUEUE_LIMIT:
                raise NotTaking(f"{QUEUE_LIMIT} inputs wait to be carried out: wait for the device")
            now = time.monotonic()
            item = translate(event, self.sizes.get(platform), now)
            self.last_seq = seq
            if item is None:
                return {"accepted": True, "action": None}
            merged = merge(self.pending, item) if self.pending is not None else None
            if merged is not None:
                self.pending = merged
            else:
                if self.pending is not None:
                    self.ready.append(self.pending)
                    self.pending = None
                if item.merges:
                    self.pending = item
                else:
                    self.ready.append(item)
                if item.action.type in ("DONE", "FAIL"):
                    self.ending = item.action.type.lower()
            self.cond.notify_all()
            current = merged or item
            return {"accepted": True, "action": current.action.model_dump(mode="json", exclude_none=True)}

    def state(self) -> dict[str, Any]:
        """What the page shows besides the screens."""
        with self.cond:
            self.seen = time.monotonic()
            task = self.task
            return {
                "task": None if task is None else {"id": task.task_id, "instruction": task.instruction,
                                                   "platforms": list(task.platforms)},
                "touch": [] if task is None else [p for p in task.platforms if is_touch(p)],
                "tasks": self.tasks,
                "step": self.step,
                "waiting": self.waiting,
                "ending": self.ending,
                "sizes": {p: list(s) for p, s in self.sizes.items()},
                "queued": len(self.ready),
                "typing": self.pending.action.model_dump(mode="json", exclude_none=True) if self.pending else None,
                "last_error": self.last_error,
                "log": list(self.log),
                "last_seq": self.last_seq,
            }

    def frame(self, platform: str) -> tuple[bytes, bool]:
        """The screen of `platform` now (live through its view; else its latest observation) and whether it is
        live. Raises LookupError when there is none to show."""
        asked = time.monotonic()
        with self.cond:
            self.seen = asked
            view = self.views.get(platform)
            shot = self.shots.get(platform)
        png, live = None, False
        if view is not None:
            with self._grab_locks[platform]:
                cached = self._frames.get(platform)
                if cached is not None and asked - cached[0] < FRAME_CACHE:
                    png, live = cached[1], True
                else:
                    try:
                        png, live = view.png(), True
                        self._frames[platform] = (time.monotonic(), png)
                    except Exception:  # a device busy or gone: its latest observation instead
                        png = None
        png = png or shot
        if png is None:
            raise LookupError(f"no screen of {platform} yet")
        with self.cond:
            if self.waiting and self.shown_at is None and asked >= self.step_started:
                self.shown_at = time.monotonic()
        return png, live


class HumanAgent:
    """A person in the browser player (see the module's docstring). Options: `port` (default 0: a free port),
    `url_file` (where the player's address is written once it listens, for `jarvis play`), `abandon_after`
    (seconds without a request of the page that end the task as a FAIL; default ABANDON_AFTER)."""

    name = "human"
    paced_by_person = True  # the loop bounds its decisions by the task's time limit, not --step-timeout

    def __init__(self, options: dict[str, Any] | None = None):
        self.options = dict(options or {})
        raw = str(self.options.get("port", "0"))
        if not raw.isdigit() or int(raw) > 65535:
            raise ConfigError(f"port {raw!r} is not a port number", field="--agent-option port",
                              fix="give 0 (a free port) or a port from 1 to 65535")
        self.port = int(raw)
        abandon = str(self.options.get("abandon_after", ABANDON_AFTER))
        try:
            after = float(abandon)
        except ValueError:
            after = -1.0
        if not after > 0:
            raise ConfigError(f"abandon_after {abandon!r} is not a number of seconds", field="--agent-option "
                              "abandon_after", fix=f"give the seconds without a request of the page that end the task "
                              f"(default {ABANDON_AFTER:g})")
        self.url_file = Path(self.options["url_file"]) if self.options.get("url_file") else None
        self.player = Player()
        self.player.abandon_after = after
        self.server: Any = None

    @property
    def url(self) -> str | None:
        return None if self.server is None else self.server.url

    def reset(self, task: TaskContext) -> None:
        if self.server is None:
            from jarvis_pytest.player.server import start_player_server

            self.server = start_player_server(self.player, self.port)
            self._announce(self.server.url)
        self.player.begin(task)

    def act(self, observations: dict[str, Observation], history: list[HistoryEntry]) -> AgentStep:
        return self.player.decide(observations, history)

    def config(self) -> dict[str, Any]:
        return {"name": self.name}

    def close(self) -> None:
        if self.server is not None:
            self.server.stop()
            self.server = None

    def _announce(self, url: str) -> None:
        """Write the address where `jarvis play` (or a person) finds it: `url_file` (atomically), and the terminal."""
        if self.url_file is not None:
            worker = os.environ.get("PYTEST_XDIST_WORKER")  # one player per xdist worker
            path = self.url_file.with_name(f"{self.url_file.name}.{worker}") if worker else self.url_file
            tmp = path.with_name(f".{path.name}.tmp")
            tmp.write_text(url + "\n", encoding="utf-8")
            os.replace(tmp, path)
        line = f"\n[jarvis] the player: {url}\n"
        try:  # pytest captures the test's output; the person reads the terminal
            with open("/dev/tty", "w", encoding="utf-8") as tty:
                tty.write(line)
        except OSError:
            print(line, file=sys.__stderr__, flush=True)


def brief_human(agent: HumanAgent, devices: dict[str, Any]) -> None:
    """Hand `agent` (exactly a HumanAgent: `oracle.brief` checked) a view of each device's screen."""
    with agent.player.cond:
        agent.player.views = {platform: ScreenView(device) for platform, device in devices.items()}
