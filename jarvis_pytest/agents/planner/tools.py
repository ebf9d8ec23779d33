"""The planner's answer: one ``<step>{...}</step>`` JSON object, written by :func:`render_step` and read by
:func:`parse_planner_output`, and its tool call mapped to one action of the unified action space by
:func:`map_action`. An answer that cannot be read or used raises :class:`PlannerOutputError`, whose message is what
the planner reads in its history.

Tool actions and what they become (the paper's tool list, plus the desktop mouse actions it leaves implicit):

=========================================  ==========================================================
click, left_click, tap                     CLICK at the grounded point
right_click / double_click / triple_click  RIGHT_CLICK / DOUBLE_CLICK / CLICK(clicks=3) at the point
long_press                                 LONG_PRESS at the point
mouse_move, hover                          MOVE_TO the point
drag (``target``: where to drop)           DRAG_TO, both ends grounded
swipe (``direction``)                      SWIPE from the point (the screen centre without element)
                                           by ``swipe_fraction`` of the screen in that direction
type (``text``)                            TYPING
key, hotkey (``keys``: list or "ctrl+s")   HOTKEY
scroll / hscroll (``pixels``)              SCROLL, -pixels / +pixels wheel notches (positive pixels
                                           scroll up / right), at the point when an element is given
system_button (``button``)                 SYSTEM_BUTTON
wait (``time``)                            WAIT
answer (``text``)                          WAIT(0); the answer is kept in the step's extra
terminate (``status``)                     DONE for success, FAIL otherwise
=========================================  ==========================================================
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from typing import Any, Callable

from jarvis_pytest.devices.actions import (Action, Click, DoubleClick, Done, DragTo, Fail, Hotkey, LongPress, MoveTo,
                                           RightClick, Scroll, Swipe, SystemButton, Typing, Wait)

MAX_SCROLL = 50  # wheel notches
TERMINAL_TOOLS = frozenset({"terminate", "done", "finish", "fail"})

Locate = Callable[[str], tuple[int, int]]


class PlannerOutputError(Exception):
    """The planner's answer cannot be used; the message is what the planner reads in its history."""


@dataclass
class PlannerStep:
    """The planner's ``<step>`` object."""

    current_status: str
    platform: str | None
    step_plan: str
    element_description: str
    tool: dict[str, Any]

    @property
    def action(self) -> str:
        return norm(self.tool.get("action"))


def norm(value: Any) -> str:
    """`value` as a lower-case name with ``_`` for spaces and dashes ("Left-Click" → "left_click")."""
    return re.sub(r"[\s\-]+", "_", str(value or "").strip().lower())


def one_line(value: Any) -> str:
    """`value` as text on one line, runs of white space folded to one space."""
    return " ".join(str(value or "").split())


# -- the answer's format -----------------------------------------------------------------------------------------
def render_step(platform: str | None, step_plan: str, tool: dict[str, Any], element_description: str = "",
                current_status: str = "") -> str:
    """A planner answer in the paper's format (for scripted planners in tests and for replaying decisions)."""
    body = {"current_status": current_status, "platform": platform, "step_plan": step_plan,
            "element_description": element_description, "tool": tool}
    return f"<step>\n{json.dumps(body, ensure_ascii=False)}\n</step>"


def parse_planner_output(text: str) -> PlannerStep:
    """The planner's step; tolerant of a missing ``</step>``, code fences and text around the JSON."""
    blocks = re.findall(r"<step>(.*?)(?:</step>|$)", text, flags=re.S)
    candidate = blocks[-1] if blocks else text
    candidate = re.sub(r"```(?:json)?", "", candidate)
    data = None
    decoder = json.JSONDecoder()
    for i in [m.start() for m in re.finditer(r"\{", candidate)]:
        try:
            obj, _ = decoder.raw_decode(candidate, i)
        except json.JSONDecodeError:
            continue
        if isinstance(obj, dict) and ("tool" in obj or "platform" in obj or "step_plan" in obj):
            data = obj
            break
    if data is None:
        where = "inside <step>...</step>" if blocks else "(no <step> tag found)"
        raise PlannerOutputError(f"the planner's answer has no JSON step object {where}; answer exactly one "
                                 f"<step>{{...}}</step> with current_status, platform, step_plan, "
                                 f"element_description and tool")
    tool = data.get("tool")
    if isinstance(tool, str):
        tool = {"action": tool}
    if not isinstance(tool, dict) or not tool.get("action"):
        raise PlannerOutputError('the step has no tool action; give "tool": {"action": "..."}')
    platform = norm(data.get("platform")) or None
    return PlannerStep(current_status=one_line(data.get("current_status")), platform=platform,
                       step_plan=one_line(data.get("step_plan")),
                       element_description=one_line(data.get("element_description")), tool=tool)


# -- mapping to the action space ---------------------------------------------------------------------------------
def _keys(tool: dict[str, Any]) -> list[str]:
    raw = tool.get("keys", tool.get("key", tool.get("text")))
    if isinstance(raw, (list, tuple)):
        keys = [str(k).strip().lower() for k in raw if str(k).strip()]
    else:
        keys = [k.lower() for k in re.split(r"\s*\+\s*|\s+", str(raw or "").strip()) if k]
    if not keys:
        raise PlannerOutputError('key needs "keys", e.g. {"action": "key", "keys": ["ctrl", "s"]}')
    return keys


def _number(tool: dict[str, Any], name: str, default: float | None = None) -> float:
    value = tool.get(name, default)
    try:
        return float(value)
    except (TypeError, ValueError):
        raise PlannerOutputError(f'{tool.get("action")} needs a number in "{name}", got {value!r}') from None


def _scroll_amount(tool: dict[str, Any]) -> int:
    direction = norm(tool.get("direction"))
    if "pixels" not in tool and direction:
        signs = {"up": 1, "down": -1, "right": 1, "left": -1}
        if direction not in signs:
            raise PlannerOutputError(f"unknown scroll direction {direction!r}; use pixels")
        return 5 * signs[direction]
    pixels = _number(tool, "pixels")
    return int(max(-MAX_SCROLL, min(MAX_SCROLL, round(pixels))))


def map_action(step: PlannerStep, locate: Locate, screen: tuple[int, int], swipe_fraction: float = 0.3
               ) -> tuple[Action, dict[str, Any]]:
    """The unified action for `step` and extra facts for the trajectory. `locate(description)` grounds a
    description on the step's platform; `screen` is that platform's (width, height)."""
    tool, name = step.tool, step.action
    extra: dict[str, Any] = {}

    def point() -> tuple[int, int]:
        if not step.element_description:
            raise PlannerOutputError(f'{name} needs an element_description for the grounding model')
        return locate(step.element_description)

    if name in ("click", "left_click", "tap"):
        return Click(x=(p := point())[0], y=p[1]), extra
    if name == "right_click":
        return RightClick(x=(p := point())[0], y=p[1]), extra
    if name == "double_click":
        return DoubleClick(x=(p := point())[0], y=p[1]), extra
    if name == "triple_click":
        return Click(x=(p := point())[0], y=p[1], clicks=3), extra
    if name == "middle_click":
        return Click(x=(p := point())[0], y=p[1], button="middle"), extra
    if name in ("long_press", "long_click"):
        return LongPress(x=(p := point())[0], y=p[1]), extra
    if name in ("mouse_move", "move", "hover"):
        return MoveTo(x=(p := point())[0], y=p[1]), extra
    if name in ("drag", "left_click_drag"):
        target = one_line(tool.get("target") or tool.get("to") or tool.get("target_description"))
        if not target:
            raise PlannerOutputError('drag needs "target": a description of the element to drop on')
        start = point()
        end = locate(target)
        return DragTo(x=end[0], y=end[1], start_x=start[0], start_y=start[1]), extra
    if name == "swipe":
        direction = norm(tool.get("direction"))
        vectors = {"up": (0, -1), "down": (0, 1), "left": (-1, 0), "right": (1, 0)}
        if direction not in vectors:
            raise PlannerOutputError(f'swipe needs "direction": up, down, left or right (got {direction!r})')
        w, h = screen
        x, y = point() if step.element_description else (w // 2, h // 2)
        vx, vy = vectors[direction]
        dx = int(round(vx * swipe_fraction * w))
        dy = int(round(vy * swipe_fraction * h))
        dx = min(max(dx, -x), w - 1 - x)  # keep the end on the screen
        dy = min(max(dy, -y), h - 1 - y)
        return Swipe(x=x, y=y, dx=dx, dy=dy), extra
    if name in ("type", "input", "input_text", "typing"):
        text = tool.get("text", tool.get("content"))
        if not isinstance(text, str) or text == "":
            raise PlannerOutputError('type needs "text": the text to type')
        return Typing(text=text), extra
    if name in ("key", "hotkey", "key_press", "press"):
        return Hotkey(keys=_keys(tool)), extra
    if name in ("scroll", "hscroll"):
        horizontal = name == "hscroll" or norm(tool.get("direction")) in ("left", "right")
        amount = _scroll_amount(tool)
        x = y = None
        if step.element_description:
            x, y = locate(step.element_description)
        if horizontal:
            return Scroll(dx=amount, x=x, y=y), extra
        return Scroll(dy=-amount, x=x, y=y), extra
    if name == "system_button":
        button = norm(tool.get("button"))
        button = {"return": "enter", "volumeup": "volume_up", "volumedown": "volume_down"}.get(button, button)
        allowed = ("home", "back", "menu", "enter", "volume_up", "volume_down", "power")
        if button not in allowed:
            raise PlannerOutputError(f'unknown system button {button!r}; use one of {", ".join(allowed)}')
        return SystemButton(button=button), extra
    if name == "wait":
        seconds = _number(tool, "time", tool.get("seconds", 1.0))
        return Wait(seconds=max(0.0, min(60.0, seconds))), extra
    if name == "answer":
        extra["answer"] = str(tool.get("text", ""))
        return Wait(seconds=0), extra
    if name in TERMINAL_TOOLS:
        status = norm(tool.get("status", "failure" if name == "fail" else "success"))
        return (Done() if status in ("success", "succeeded", "successful", "done", "complete") else Fail()), extra
    raise PlannerOutputError(f"unknown tool action {name!r}")
