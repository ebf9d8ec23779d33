"""The GUI oracle (`--agent gui-oracle`): a task's GUI solution carried out with the agent's actions alone.

Where the oracle (`agents/oracle.py`) proves that the evaluators accept a correct final state, often reached with
shell commands, the GUI oracle proves that an agent with only the action space can reach it. It carries out the
template's `gui_solution` (`tasks.model.GuiStep`): actions of the unified action space, where a pointer action may
name its target by what a person sees (a control of a window, text on screen) instead of pixels. At each step it
reads the device's accessibility tree (Ubuntu: AT-SPI; Windows: the window-handle tree), finds the target within
the step's `timeout`, and answers the plain action at the centre of the target's box: the harness's step loop then
executes it as it executes any agent's action, and the trajectory records the plain action with the target and
the node it was resolved to (`extra`). `WAIT_FOR` only observes (a WAIT(0) step records what it saw). A target
not found in time is the step's error, recorded; the next step gives up (FAIL), as does an action the device
refused.

It is told the GUI solution and given a view of the devices' accessibility trees through `oracle.brief` (the one
private path, recognising it by its class object as it does the oracle): it holds no device, so it can run no
command and write no file. A composed task's plan is its subtasks' GUI solutions in order (the built-in transfer
has its own, `tasks/transfer.py`); what an upstream made and set-up held back (`opens`) is opened first from a
command line opened through the GUI (`opening_steps`). It gives up on a subtask without a GUI solution, saying so,
and on one whose template says the GUI cannot solve it on the device's backend (`gui_infeasible`). In a composed
task, a subtask's window is brought to the front before its steps as a person does it (`front_step`): its button on
the taskbar is clicked where it is not already in front (a click on the button of the window in front would
minimise it).
"""

from __future__ import annotations

import re
import shutil
import time
from dataclasses import dataclass, replace
from typing import Any, Callable, Iterator, Sequence

from jarvis_pytest.agents.protocol import AgentStep, HistoryEntry, TaskContext
from jarvis_pytest.agents.screen_text import read_words, runs
from jarvis_pytest.devices.actions import Click, Done, Fail, Wait
from jarvis_pytest.devices.base import Observation
from jarvis_pytest.devices.control_http import title_matches
from jarvis_pytest.errors import InfrastructureError

POLL = 0.3  # seconds between two reads of the accessibility tree while a target is awaited
TREE_NODES = 5000  # the most nodes of one read (LibreOffice shows many cells)
TREE_TIMEOUT = 8.0  # seconds one read may take on the device
FRONT_SHOW = 30.0  # seconds a subtask's window gets to show before it is brought to the front
FRONT_WAIT = 5.0  # seconds a window gets to come to the front after a click on its taskbar button
FRONT_CLICKS = 2  # clicks on a window's taskbar button before giving up on bringing it to the front
# the least time between two presses of a button on one device, as a person leaves: GTK's menus take a button's
# release within half a second of the press that opened them for the end of that press, not a click (gtkmenushell.c,
# MENU_SHELL_TIMEOUT), so a click on a menu item that came that soon did nothing (Thunar's Edit > Paste, mi-0094)
CLICK_GAP = 0.6
PRESSES = frozenset({"CLICK", "RIGHT_CLICK", "DOUBLE_CLICK", "MOUSE_DOWN"})


def backend_name(label: str) -> str:
    """A backend's name from the label results record: "windows (wine)" → "wine"."""
    m = re.search(r"\(([^()]*)\)\s*$", label or "")
    return m.group(1) if m else label


def text_matches(pattern: str, value: str | None) -> bool:
    """A control's name or text against a step's pattern: case-insensitive, the whole text, or with `*` (any text)
    a pattern of the whole text; on both sides spaces at the ends are dropped and every run of white space (line
    breaks too) counts as one space."""
    if value is None:
        return False
    want = " ".join(pattern.casefold().split())
    have = " ".join(value.casefold().split())
    if "*" not in want:
        return want == have
    return re.fullmatch(".*".join(map(re.escape, want.split("*"))), have, re.S) is not None


def _top_levels(root: dict) -> Iterator[dict]:
    """The windows of the desktop: an application's children (AT-SPI), or the desktop's (the window-handle tree)."""
    for child in root.get("children", []):
        if child.get("role") == "application":
            yield from child.get("children", [])
        else:
            yield child


def visible_box(box: Sequence[int] | None, screen: tuple[int, int] | None = None) -> list[int] | None:
    """The part of `box` [x, y, w, h] on the screen (`screen`: width, height; None: unbounded right and below),
    None where no pixel of it is."""
    if not box or box[2] <= 0 or box[3] <= 0:
        return None
    right, bottom = box[0] + box[2], box[1] + box[3]
    if screen is not None:
        right, bottom = min(right, screen[0]), min(bottom, screen[1])
    left, top = max(box[0], 0), max(box[1], 0)
    return [left, top, right - left, bottom - top] if right > left and bottom > top else None


def _on_screen(node: dict, screen: tuple[int, int] | None = None) -> bool:
    return visible_box(node.get("box"), screen) is not None


def _walk(node: dict, path: tuple[int, ...] = ()) -> Iterator[tuple[tuple[int, ...], dict]]:
    yield path, node
    for i, child in enumerate(node.get("children", [])):
        yield from _walk(child, path + (i,))


def _control_matches(node: dict, control: Any) -> bool:
    if control.role is not None and node.get("role", "").casefold() != control.role.casefold():
        return False
    if control.class_ is not None and node.get("class", "").casefold() != control.class_.casefold():
        return False
    if control.name is not None and not text_matches(control.name, node.get("name")):
        return False
    if control.text is not None and not text_matches(control.text, node.get("text")):
        return False
    return True


def find_target(tree: dict, target: Any, screen: tuple[int, int] | None = None) -> tuple[dict | None, str | None]:
    """The node `target` (`tasks.model.GuiTarget`) names in an accessibility tree (the `tree` of `a11y_tree()`),
    with the title of the window it was found in: a `control` (the first match in the tree's order), a node
    showing `text` (the innermost one: a label, not the panel around it) or the `window` itself; the `index`-th
    match. Only nodes with a box on the screen count (`screen`: its width and height, where known).
    (None, None) when nothing matches."""
    windows = [w for w in _top_levels(tree) if target.window is None or title_matches(target.window, w.get("name", ""))]
    if target.control is None and target.text is None:
        shown = [w for w in windows if _on_screen(w, screen)]
        node = shown[target.index] if len(shown) > target.index else None
        return node, (node or {}).get("name")
    found: list[tuple[tuple[int, ...], dict, str]] = []
    for w_index, window in enumerate(windows):
        for path, node in _walk(window, (w_index,)):
            if not _on_screen(node, screen):
                continue
            if target.control is not None:
                hit = _control_matches(node, target.control)
            else:
                hit = text_matches(target.text, node.get("name")) or text_matches(target.text, node.get("text"))
            if hit:
                found.append((path, node, window.get("name", "")))
    if target.text is not None:  # the innermost: drop a match that holds another match
        paths = [p for p, _, _ in found]
        found = [f for f in found if not any(len(q) > len(f[0]) and q[:len(f[0])] == f[0] for q in paths)]
    if len(found) <= target.index:
        return None, None
    _, node, title = found[target.index]
    return node, title


def describe_target(target: Any) -> str:
    """A target in words, for errors and the trajectory."""
    parts = []
    if target.control is not None:
        c = target.control
        what = " ".join(f"{k}={v!r}" for k, v in (("role", c.role), ("class", c.class_), ("name", c.name),
                                                   ("text", c.text)) if v is not None)
        parts.append(f"a control ({what})")
    if target.text is not None:
        parts.append(f"the text {target.text!r}")
    if target.screen_text is not None:
        parts.append(f"the text {target.screen_text!r} on the screen image")
    if target.window is not None:
        parts.append(("in " if parts else "") + f"the window {target.window!r}")
    if target.index:
        parts.append(f"(match {target.index})")
    return " ".join(parts)


class A11yView:
    """What the GUI oracle is given of one device: its accessibility tree and its screen image, nothing else."""

    __slots__ = ("_read", "_shot")

    def __init__(self, device: Any):
        self._read: Callable[[], dict] = lambda: device.a11y_tree(max_nodes=TREE_NODES, timeout=TREE_TIMEOUT)
        self._shot: Callable[[], bytes] = lambda: device.observe().screenshot_png

    def tree(self) -> dict:
        """`{"tree": {...}, "truncated": bool, ...}` as the device's `/a11y` answers."""
        return self._read()

    def screenshot(self) -> bytes:
        """The screen now (PNG), as an agent's observation has it."""
        return self._shot()


class ScreenWords:
    """A view whose "tree" is the words of the screen image (`screen_text.read_words`), for `poll_tree`."""

    __slots__ = ("view",)

    def __init__(self, view: A11yView):
        self.view = view

    def tree(self) -> dict:
        return {"tree": {"words": read_words(self.view.screenshot())}}


def find_screen_text(words: Sequence[Any], target: Any,
                     screen: tuple[int, int] | None = None) -> tuple[dict | None, str | None]:
    """The `index`-th run of words on one line (`screen_text.runs`) that shows `target.screen_text`, as a node
    (`role` "screen text", its `name` what was read, its `box`); (None, None) when none does."""
    found = [(text, box) for text, box in runs(words) if text_matches(target.screen_text, text)
             and visible_box(box, screen) is not None]
    if len(found) <= target.index:
        return None, None
    text, box = found[target.index]
    return {"role": "screen text", "name": text, "box": box}, None


@dataclass(frozen=True)
class Found:
    """What an awaited target came to: its node (None when it did not show, or for `gone` when it went), the
    window it was found in, the seconds waited and the reads taken, and whether a read was cut short."""

    node: dict | None
    window: str | None
    seconds: float
    reads: int
    truncated: bool


def poll_tree(view: A11yView, judge: Callable[[dict], tuple[bool, Any]], timeout: float, *,
              clock: Callable[[], float] = time.monotonic,
              sleep: Callable[[float], None] = time.sleep) -> tuple[bool, Any, int, bool, float]:
    """Read `view`'s tree until `judge(tree)` answers (True, value), at most `timeout` seconds (one read at least):
    (done, the last value judged, reads, whether a read was cut short, seconds). A read the device fails (AT-SPI
    "did not receive a reply" while a program starts, on a loaded machine) is read again within the timeout, twice
    at least; the device's error is raised only when no read at all succeeded."""
    start = clock()
    reads, truncated, failed, value = 0, False, 0, None
    while True:
        try:
            answer = view.tree()
        except InfrastructureError:
            failed += 1
            if clock() - start >= timeout and (reads or failed >= 2):
                if not reads:
                    raise
                return False, value, reads, truncated, round(clock() - start, 3)
            sleep(POLL)
            continue
        reads += 1
        truncated = truncated or bool(answer.get("truncated"))
        done, value = judge(answer.get("tree") or {})
        if done or clock() - start >= timeout:
            return done, value, reads, truncated, round(clock() - start, 3)
        sleep(POLL)


def await_target(view: A11yView, target: Any, timeout: float, *, gone: bool = False, settled: bool = False,
                 screen: tuple[int, int] | None = None, clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[[float], None] = time.sleep) -> Found:
    """Read `view`'s tree until `target` shows on `screen` (with `gone`: until it no longer shows), at most
    `timeout` seconds (`poll_tree`). `Found.node` is the node found; with `gone` it is None once the target went.
    With `settled` (a target about to be clicked) it shows once two reads in a row give it the same box, as a
    person waits for a dialog or bubble to stop moving before clicking into it; when the timeout passes while it
    still moves, the last box is taken."""
    last: list[Any] = [None]
    on_image = target.screen_text is not None

    def judge(tree: dict) -> tuple[bool, tuple[dict | None, str | None]]:
        node, title = (find_screen_text(tree.get("words", []), target, screen) if on_image
                       else find_target(tree, target, screen))
        moving = settled and node is not None and node.get("box") != last[0]
        last[0] = None if node is None else node.get("box")
        return (node is None) == gone and not moving, (node, title)

    source = ScreenWords(view) if on_image else view
    done, value, reads, truncated, seconds = poll_tree(source, judge, timeout, clock=clock, sleep=sleep)
    node, title = value or (None, None)
    if not done and not (gone or (settled and node is not None)):  # it did not show
        node, title = None, None
    return Found(node, title, seconds, reads, truncated)


def front_state(tree: dict, window: str, button_role: str | None, marks_front: bool = False,
                screen: tuple[int, int] | None = None) -> tuple[str, dict | None]:
    """Where the window whose title shows `window` stands, and its taskbar button (a `button_role` control named by
    its title; None where there is none): "front", "behind", or "absent" (neither the window nor its button shows).
    A dialog, which has no button of its own, goes by its application's window's. Where the taskbar marks the
    window in front (`marks_front`: XFCE checks its button) that mark decides, as a person reads it: it holds for a
    window whose modal dialog has the keyboard (Ristretto's warning), for one the tree does not show (GIMP shows
    nothing to AT-SPI) and among windows of one title (Settings' "Desktop" and the desktop itself); elsewhere the
    window must be the active one."""
    from jarvis_pytest.tasks.model import GuiTarget

    def button_of(title: str) -> dict | None:
        name = title if "*" in title else f"*{title}*"
        return find_target(tree, GuiTarget.model_validate({"control": {"role": button_role, "name": name}}),
                           screen)[0]

    node, _ = find_target(tree, GuiTarget(window=window), screen)
    button = button_of(window) if button_role is not None else None
    if button is None and node is not None and button_role is not None:
        for sibling in _siblings(tree, node):  # a dialog has no button: its application's window has
            button = button_of(sibling["name"]) if sibling.get("name") else None
            if button is not None:
                break
    if button is not None and (marks_front or node is None):
        return ("front" if "checked" in button.get("states", ()) else "behind"), button
    if node is not None:
        return ("front" if "active" in node.get("states", ()) else "behind"), button
    return "absent", None


def _siblings(tree: dict, node: dict) -> list[dict]:
    """The other windows of the application that shows `node` (AT-SPI groups them; the window-handle tree does not:
    none there)."""
    for app in tree.get("children", []):
        kids = app.get("children", []) if app.get("role") == "application" else []
        if any(k is node for k in kids):
            return [k for k in kids if k is not node and _on_screen(k)]
    return []


def front_among(tree: dict, windows: Sequence[str], button_role: str | None, marks_front: bool = False,
                screen: tuple[int, int] | None = None) -> tuple[str, dict | None, str]:
    """`front_state` of the window that shows one of `windows`: "front" where one is in front; else "behind", with
    the taskbar button of the first one that has a button; else "absent". The title it concerns comes last."""
    found = [(w, *front_state(tree, w, button_role, marks_front, screen)) for w in windows]
    for w, state, button in found:
        if state == "front":
            return state, button, w
    behind = [f for f in found if f[1] == "behind"]
    if behind:
        w, state, button = min(behind, key=lambda f: f[2] is None)  # one with a button to click first
        return state, button, w
    return "absent", None, windows[0]


def centre(box: Sequence[int], screen: tuple[int, int] | None = None) -> tuple[int, int]:
    """The centre of a box [x, y, w, h]; with `screen`, of its part on the screen."""
    box = visible_box(box, screen) or box
    return int(box[0] + box[2] // 2), int(box[1] + box[3] // 2)


@dataclass(frozen=True)
class GuiItem:
    """One step of a GUI plan: subtask `subtask`'s GUI step `index` (`step`, a GuiStep) on `platform`; `origin`
    says where the step comes from: the subtask's `gui_solution`, `opens` (opening what an upstream made) or
    `front` (bringing the subtask's window to the front: `front_step`)."""

    subtask: int
    platform: str
    index: int
    step: Any
    origin: str = "gui_solution"
    tries: int = 0  # `front`: taskbar clicks made so far
    windows: tuple[str, ...] = ()  # `front`: the titles the subtask's window may show (`front_step`)


OPENED_SHOW = 60.0  # seconds a program opened through the GUI gets to show its window (GIMP under load)
OPENED_SETTLE = 2.0  # seconds it then gets before the subtask's first step (a window shows before it takes keys)


def opening_steps(s: int, sub: Any) -> tuple[list[GuiItem], str | None]:
    """The GUI steps that open what subtask `s` works on where set-up held it back (`sub.opens`): the same
    program started from a command line opened through the GUI, then its window awaited as a person waits for
    it — the subtask's `window`, or else the taskbar button that shows the opened file's name (GIMP shows nothing
    of itself to AT-SPI but its title) — and a moment to settle; and why there are none."""
    from jarvis_pytest.devices.platforms import spec
    from jarvis_pytest.tasks.model import GuiStep

    steps: list[dict] = []
    for opener in sub.opens or []:
        facts = spec(opener.platform or sub.platform)
        app, args = (opener.app, opener.args) if opener.type == "launch" else (None, [opener.path])
        shell = facts.gui_shell_steps(facts.start_command(app, args), "open what this subtask works on")
        if not shell:
            return [], f"subtask {s} ({sub.template}) opens a file an upstream subtask made, and the {facts.label} " \
                       "device has no way known to do that through the GUI"
        steps += shell
        shows = opened_window_target(sub, facts, args)
        if shows is not None:
            steps.append({"type": "WAIT_FOR", "target": shows, "timeout": OPENED_SHOW, "platform": facts.name,
                          "note": "the window of what was opened shows"})
        steps.append({"type": "WAIT", "seconds": OPENED_SETTLE, "platform": facts.name})
    return [GuiItem(s, step.get("platform") or sub.platform, i, GuiStep.model_validate(step), "opens")
            for i, step in enumerate(steps)], None


def opened_window_target(sub: Any, facts: Any, args: Sequence[str]) -> dict | None:
    """What shows once a program opened `args` (a GuiTarget's fields): the subtask's `window`, else a taskbar
    button whose title shows the name of the file opened (without its extension: GIMP shows "[name]"); None where
    neither is known."""
    if sub.window:
        return {"window": sub.window}
    import ntpath
    import posixpath

    files = [a for a in args if a and not a.startswith("-")]
    if not files or facts.taskbar_button_role is None:
        return None
    base = (ntpath if facts.path_style == "windows" else posixpath).basename(files[-1])
    stem = base.rsplit(".", 1)[0] if "." in base.lstrip(".") else base
    return {"control": {"role": facts.taskbar_button_role, "name": f"*{stem}*"}} if stem else None


def front_step(s: int, sub: Any, windows: Sequence[str]) -> GuiItem:
    """The step that brings subtask `s`'s window to the front before its GUI solution, where other subtasks'
    programs are open on the same desktop: its title shows one of `windows` (a title set-up saw may have changed
    since — LibreOffice names its window only once the file is loaded — and the window a GUI solution starts in may
    be a dialog in front of it, Ristretto's warning). Carried out by `GuiOracleAgent` as a person does it (the
    window's button on the taskbar, clicked only when the window is not already in front)."""
    from jarvis_pytest.tasks.model import GuiStep

    step = GuiStep.model_validate({"type": "WAIT_FOR", "target": {"window": windows[0]}, "timeout": FRONT_SHOW,
                                   "note": "the subtask's window, brought to the front"})
    return GuiItem(s, sub.platform, 0, step, "front", windows=tuple(windows))


def first_window(steps: Sequence[Any]) -> str | None:
    """The window a GUI solution starts in: the `window` its first step names, waits aside (None where that step
    names none: it presses keys, or clicks a control of the desktop such as the Start button, and the windows it
    works in are ones it opens itself)."""
    first = next((step for step in steps if step.type != "WAIT"), None)
    return first.target.window if first is not None and first.target is not None else None


def gui_plan(subtasks: Sequence[Any], backends: dict[str, str] | None = None,
             windows: dict[int, str] | None = None) -> tuple[list[GuiItem], str | None]:
    """The GUI plan of a task (its subtasks in execution order): every subtask's GUI steps in order, in a composed
    task after bringing the subtask's window to the front (`front_step`: the template's `window`, else the title of
    the window its set-up opened, from `windows`: subtask → title, or the window its GUI solution starts in), and
    why there is none (a subtask without a GUI solution, one whose file set-up held back for the solver to open, or
    one the template says the GUI cannot solve on the device's backend, from `backends`: platform → label)."""
    plan: list[GuiItem] = []
    for s, sub in enumerate(subtasks):
        backend = backend_name((backends or {}).get(sub.platform, ""))
        reason = (sub.gui_infeasible or {}).get(backend)
        if reason:
            return [], f"subtask {s} ({sub.template}) cannot be solved through the GUI on {backend}: {reason}"
        if not sub.gui_solution:
            return [], f"subtask {s} ({sub.template}) has no GUI solution yet"
        opening, why = opening_steps(s, sub)
        if why is not None:
            return [], why
        plan += opening
        candidates = [sub.window] if sub.window else \
            list(dict.fromkeys(w for w in ((windows or {}).get(s), first_window(sub.gui_solution)) if w))
        if len(subtasks) > 1 and candidates:
            plan.append(front_step(s, sub, candidates))
        plan += [GuiItem(s, step.platform or sub.platform, i, step) for i, step in enumerate(sub.gui_solution)]
    return plan, None


class GuiOracleAgent:
    """Carries out the task's GUI plan (`gui_plan`), handed to it with the devices' accessibility views by
    `oracle.brief` after `reset`; see the module's docstring."""

    __slots__ = ("options", "views", "queue", "last_platform", "failed", "briefed", "pending", "pressed")
    name = "gui-oracle"

    def __init__(self, options: dict[str, Any] | None = None):
        self.options = dict(options or {})
        self.reset(TaskContext(task_id="", instruction="", platforms=()))

    def reset(self, task: TaskContext) -> None:
        self.views: dict[str, A11yView] = {}
        self.queue: list[GuiItem] = []
        self.last_platform: str | None = task.platforms[0] if task.platforms else None
        self.failed: AgentStep | None = None
        self.briefed: bool | str = False  # True, or why there is no plan
        self.pending: GuiItem | None = None  # the step whose action the harness is carrying out
        self.pressed: dict[str, float] = {}  # platform → when its last button press was handed out (monotonic)

    def act(self, observations: dict[str, Observation], history: list[HistoryEntry]) -> AgentStep:
        """The next step; a press of a button comes at least CLICK_GAP seconds after the last one on its device."""
        step = self._next(observations, history)
        if step.action is not None and step.action.type in PRESSES and step.platform is not None:
            since = time.monotonic() - self.pressed.get(step.platform, float("-inf"))
            if since < CLICK_GAP:
                time.sleep(CLICK_GAP - since)
            self.pressed[step.platform] = time.monotonic()
        return step

    def _next(self, observations: dict[str, Observation], history: list[HistoryEntry]) -> AgentStep:
        if self.briefed is not True:
            why = self.briefed or "the harness handed it no GUI solution for this task (`brief`)"
            return AgentStep(platform=self.last_platform, action=Fail(), reasoning=f"gui-oracle: {why}")
        if self.failed is not None:
            return self.failed
        if self.pending is not None and history and history[-1].error:  # the device refused our last action
            item = self.pending
            return self._fail(item.platform, f"gui-oracle: {item.origin}[{item.index}] of subtask {item.subtask} "
                                             f"failed: {history[-1].error}")
        self.pending = None
        if not self.queue:
            return AgentStep(platform=self.last_platform, action=Done(), reasoning="GUI solution complete")
        item = self.queue.pop(0)
        step = item.step
        platform = self.last_platform = item.platform
        where = f"{item.origin}[{item.index}]" + (f" of subtask {item.subtask}" if item.subtask else "")
        note = f" ({step.note})" if step.note else ""
        if step.target is None:
            self.pending = item
            return AgentStep(platform=platform, action=step.action(), reasoning=f"{where}{note}",
                             extra={"gui_step": item.index, "origin": item.origin})
        what = describe_target(step.target)
        shown = observations.get(platform)
        screen = (shown.width, shown.height) if shown is not None and shown.width and shown.height else None
        if item.origin == "front":
            return self._front(item, where, screen)
        found = await_target(self.views[platform], step.target, step.timeout, gone=step.gone, screen=screen,
                             settled=step.type != "WAIT_FOR")
        seen = {"gui_step": item.index, "origin": item.origin,
                "target": step.target.model_dump(mode="json", by_alias=True, exclude_none=True),
                "waited": found.seconds, "reads": found.reads}
        if found.node is not None:
            seen["resolved"] = {k: found.node[k] for k in ("role", "name", "class", "box") if k in found.node}
            seen["resolved"]["window"] = found.window
        if step.type == "WAIT_FOR":
            if (found.node is None) != step.gone:
                return self._missing(platform, where, what, step, found, seen)
            return AgentStep(platform=platform, action=Wait(seconds=0), extra=seen,
                             reasoning=f"{where}: {what} {'went' if step.gone else 'shows'} after "
                                       f"{found.seconds:g} s{note}")
        if found.node is None:
            return self._missing(platform, where, what, step, found, seen)
        x, y = centre(found.node["box"], screen)
        self.pending = item
        return AgentStep(platform=platform, action=step.action(x, y), extra=seen,
                         reasoning=f"{where}: {step.type} at the centre of {what} ({x}, {y}){note}")

    def _front(self, item: GuiItem, where: str, screen: tuple[int, int] | None) -> AgentStep:
        """Bring the subtask's window to the front as a person does (`front_state`): nothing to do where it is
        already in front, else a click on its taskbar button, then a look whether it came (at most FRONT_CLICKS
        clicks: a click on the button of a window the taskbar thinks in front minimises it, the next one restores
        it)."""
        from jarvis_pytest.devices.platforms import spec

        platform, step, view = item.platform, item.step, self.views[item.platform]
        facts = spec(platform)
        windows, role = item.windows or (step.target.window,), facts.taskbar_button_role
        seen: dict[str, Any] = {"origin": "front", "windows": list(windows), "clicks": item.tries}
        wanted = ("front",) if item.tries else ("front", "behind")  # after a click: it comes; first: it shows

        def judge(tree: dict) -> tuple[bool, tuple[str, dict | None, str]]:
            where_now = front_among(tree, windows, role, facts.taskbar_marks_front, screen)
            return where_now[0] in wanted, where_now

        _, value, reads, _, seconds = poll_tree(view, judge, FRONT_WAIT if item.tries else step.timeout)
        state, button, window = value or ("absent", None, windows[0])
        seen.update(state=state, window=window, waited=seconds, reads=reads)
        if state == "front":
            return AgentStep(platform=platform, action=Wait(seconds=0), extra=seen,
                             reasoning=f"{where}: the window {window!r} is {'in' if item.tries else 'already in'} "
                                       "front")
        if state == "absent" and not item.tries:
            error = (f"{where}: no window showing {' or '.join(map(repr, windows))} showed within "
                     f"{step.timeout:g} s ({reads} reads)")
        elif role is None:
            return AgentStep(platform=platform, action=Wait(seconds=0), extra=seen,
                             reasoning=f"{where}: the {platform} device has no taskbar known: the window {window!r} "
                                       "is left where it is")
        elif item.tries >= FRONT_CLICKS:
            error = (f"{where}: the window {window!r} did not come to the front after {item.tries} clicks on its "
                     "taskbar button")
        elif button is None:
            error = f"{where}: the window {window!r} is not in front and has no taskbar button ({role}) on screen"
        else:
            x, y = centre(button["box"], screen)
            self.queue.insert(0, replace(item, tries=item.tries + 1))
            self.pending = item
            seen["resolved"] = {k: button[k] for k in ("role", "name", "box") if k in button}
            return AgentStep(platform=platform, action=Click(x=x, y=y), extra=seen,
                             reasoning=f"{where}: CLICK the taskbar button of the window {window!r} ({x}, {y}) to "
                                       "bring it to the front")
        self._fail(platform, f"gui-oracle: {error}")
        return AgentStep(platform=platform, action=None, error=error, reasoning=error, extra=seen)

    def _missing(self, platform: str, where: str, what: str, step: Any, found: Found,
                 seen: dict[str, Any]) -> AgentStep:
        """The step's error (recorded by the harness), and a FAIL for the next step."""
        state = "still shows" if step.gone else "did not show"
        cut = (" (the accessibility tree was cut short: it has more nodes than one read takes)"
               if found.truncated else "")
        error = f"{where}: {what} {state} within {step.timeout:g} s ({found.reads} reads){cut}"
        self._fail(platform, f"gui-oracle: {error}")
        return AgentStep(platform=platform, action=None, error=error, reasoning=error, extra=seen)

    def _fail(self, platform: str, reasoning: str) -> AgentStep:
        self.failed = AgentStep(platform=platform, action=Fail(), reasoning=reasoning)
        return self.failed

    def config(self) -> dict[str, Any]:
        return {"name": self.name}


def brief_gui(agent: GuiOracleAgent, subtasks: Sequence[Any], devices: dict[str, Any],
              backends: dict[str, str] | None, windows: dict[int, str] | None = None) -> None:
    """Hand `agent` (exactly a GuiOracleAgent: `oracle.brief` checked) the task's GUI plan and the devices'
    accessibility views."""
    plan, why = gui_plan(subtasks, backends, windows)
    if why is None and shutil.which("tesseract") is None and any(
            item.step.target is not None and item.step.target.screen_text is not None for item in plan):
        why = ("the GUI solution reads text off the screen (`screen_text`) with Tesseract, which is not installed "
               "on this host: apt-get install tesseract-ocr (or make host-packages)")
    agent.queue = plan
    agent.views = {platform: A11yView(device) for platform, device in devices.items()}
    agent.briefed = True if why is None else why
