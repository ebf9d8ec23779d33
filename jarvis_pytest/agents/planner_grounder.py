"""The planner–grounder agent (paper, appendix "Planner Model").

At each step the planner (a general VL model such as Qwen3-VL-Plus behind any OpenAI-compatible endpoint) sees the
screenshots of Android, Windows and Ubuntu, the instruction and the history ("Step N on <platform>: <plan>", with
the framework's errors), and answers one ``<step>{...}</step>`` JSON object: current status, platform, step plan,
element description and a tool action. Actions that need a position are grounded by the grounding model on the
chosen platform's screenshot alone; the result is one action of the unified action space.

Planner output that cannot be parsed or used comes back as an ``AgentStep`` with ``error`` set and
``action=None`` (the harness feeds the error back into the history); an unreachable endpoint raises
``InfrastructureError``.

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

import io
import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from PIL import Image

from jarvis_pytest.agents.grounding import Grounder, GroundingError
from jarvis_pytest.agents.protocol import AgentStep, HistoryEntry, TaskContext
from jarvis_pytest.devices.platforms import spec
from jarvis_pytest.devices.actions import (PLATFORMS, Action, Click, DoubleClick, Done, DragTo, Fail, Hotkey,
                                           LongPress, MoveTo, RightClick, Scroll, Swipe, SystemButton, Typing, Wait)
from jarvis_pytest.devices.base import Observation
from jarvis_pytest.errors import ConfigError
from jarvis_pytest.llm.client import ChatClient, image_part, system_message, text_part
from jarvis_pytest.llm.config import EndpointConfig, resolve_endpoint

PROMPT_FILE = Path(__file__).with_name("prompts") / "planner.txt"

DEFAULT_PLANNER_MODEL = "qwen3-vl-plus"  # the paper's planner (DashScope compatible mode)
SECRET_WORDS = ("key", "token", "secret", "password")
MAX_SCROLL = 50  # wheel notches
TERMINAL_TOOLS = frozenset({"terminate", "done", "finish", "fail"})

TRANSFER_TEXT = {
    "alist": """You have access to a alist server.
- url: {url}
- username: {user}
- password: {password}
- folder: {folder}

You can upload files to the alist server or download files from the alist server by browser on all platforms.
- first, open this url in browser: {url}
- then, login with username: {user} and password: {password}
- select the folder {folder}
- select file to download, or click bottom-right "three dot button" to find the upload file button to upload file.""",
    "copyparty": """You have access to a file server (copyparty).
- url: {url}
- username: {user}
- password: {password}
- folder: {folder}

You can upload files to the file server or download files from the file server by browser on all platforms.
- first, open this url in browser: {url}
- then, log in with password: {password} (the login box asks only for the password)
- open the folder {folder}
- click a file to download it, or use the upload panel at the top of the folder page to upload a file.""",
}


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
        return _norm(self.tool.get("action"))


def _norm(value: Any) -> str:
    return re.sub(r"[\s\-]+", "_", str(value or "").strip().lower())


def _one_line(value: Any) -> str:
    return " ".join(str(value or "").split())


# -- prompt ------------------------------------------------------------------------------------------------------
def render_history(history: list[HistoryEntry]) -> str:
    """The paper's history summary, one line per step, with the framework's error after it."""
    if not history:
        return "(none)"
    lines = []
    for n, entry in enumerate(history, 1):
        line = f"Step {n} on {entry.platform or 'no platform'}: {_one_line(entry.plan) or '(no plan)'}"
        if entry.error:
            line += f" -- ERROR: {_one_line(entry.error)}"
        lines.append(line)
    return "\n".join(lines)


def render_transfer(transfer: dict[str, str]) -> str:
    """Section 7 of the prompt: the transfer server's address and credentials (the paper's AList text unless the
    harness says ``flavour: copyparty``)."""
    if not transfer.get("url"):
        return "No file transfer server is available for this task."
    flavour = transfer.get("flavour") or transfer.get("kind") or "alist"
    template = TRANSFER_TEXT.get(str(flavour).lower(), TRANSFER_TEXT["alist"])
    return template.format(url=transfer["url"], user=transfer.get("user", "agent"),
                           password=transfer.get("password", ""), folder=transfer.get("folder", "/data"))


def render_prompt(task: TaskContext, history: list[HistoryEntry], template: str | None = None) -> str:
    """The planner prompt with {{TRANSFER}}, {{CURRENT_HISTORY}} and {{USER_QUERY}} filled in."""
    text = PROMPT_FILE.read_text(encoding="utf-8") if template is None else template
    values = {"TRANSFER": render_transfer(dict(task.transfer)), "CURRENT_HISTORY": render_history(history),
              "USER_QUERY": task.instruction}
    return re.sub(r"\{\{(TRANSFER|CURRENT_HISTORY|USER_QUERY)\}\}", lambda m: values[m.group(1)], text)


def render_step(platform: str | None, step_plan: str, tool: dict[str, Any], element_description: str = "",
                current_status: str = "") -> str:
    """A planner answer in the paper's format (for scripted planners in tests and for replaying decisions)."""
    body = {"current_status": current_status, "platform": platform, "step_plan": step_plan,
            "element_description": element_description, "tool": tool}
    return f"<step>\n{json.dumps(body, ensure_ascii=False)}\n</step>"


# -- parsing -----------------------------------------------------------------------------------------------------
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
    platform = _norm(data.get("platform")) or None
    return PlannerStep(current_status=_one_line(data.get("current_status")), platform=platform,
                       step_plan=_one_line(data.get("step_plan")),
                       element_description=_one_line(data.get("element_description")), tool=tool)


# -- mapping to the action space ---------------------------------------------------------------------------------
Locate = Callable[[str], tuple[int, int]]


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
    direction = _norm(tool.get("direction"))
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
        target = _one_line(tool.get("target") or tool.get("to") or tool.get("target_description"))
        if not target:
            raise PlannerOutputError('drag needs "target": a description of the element to drop on')
        start = point()
        end = locate(target)
        return DragTo(x=end[0], y=end[1], start_x=start[0], start_y=start[1]), extra
    if name == "swipe":
        direction = _norm(tool.get("direction"))
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
        horizontal = name == "hscroll" or _norm(tool.get("direction")) in ("left", "right")
        amount = _scroll_amount(tool)
        x = y = None
        if step.element_description:
            x, y = locate(step.element_description)
        if horizontal:
            return Scroll(dx=amount, x=x, y=y), extra
        return Scroll(dy=-amount, x=x, y=y), extra
    if name == "system_button":
        button = _norm(tool.get("button"))
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
        status = _norm(tool.get("status", "failure" if name == "fail" else "success"))
        return (Done() if status in ("success", "succeeded", "successful", "done", "complete") else Fail()), extra
    raise PlannerOutputError(f"unknown tool action {name!r}")


# -- the agent ---------------------------------------------------------------------------------------------------
def redact(options: dict[str, Any]) -> dict[str, Any]:
    """`options` with every secret-looking value replaced by "***" (nested dicts included)."""
    out: dict[str, Any] = {}
    for key, value in options.items():
        if isinstance(value, dict):
            out[key] = redact(value)
        elif any(word in str(key).lower() for word in SECRET_WORDS):
            out[key] = "***" if value else value
        else:
            out[key] = value
    return out


def _screen_of(obs: Observation) -> tuple[int, int]:
    if obs.width and obs.height:
        return obs.width, obs.height
    with Image.open(io.BytesIO(obs.screenshot_png)) as img:
        return img.size


def _add_usage(total: dict[str, int], usage: dict[str, int], role: str) -> None:
    for key in ("prompt_tokens", "completion_tokens"):
        value = int(usage.get(key, 0) or 0)
        total[key] = total.get(key, 0) + value
        total[f"{role}_{key}"] = total.get(f"{role}_{key}", 0) + value


class PlannerGrounderAgent:
    """A planner model that decides the step and a grounding model that finds the element (see module doc)."""

    def __init__(self, name: str, planner: ChatClient, grounder: Grounder, *, planner_params: dict | None = None,
                 swipe_fraction: float = 0.3, public_config: dict[str, Any] | None = None):
        self.name = name
        self.planner = planner
        self.grounder = grounder
        self.planner_params = dict(planner_params or {})
        self.swipe_fraction = swipe_fraction
        self._config = public_config or {"name": name, "planner": planner.config(),
                                         "grounder": grounder.client.config()}
        self.task: TaskContext | None = None
        self.template = PROMPT_FILE.read_text(encoding="utf-8")

    def preflight(self) -> None:
        """Called once at start-up, before any device boots: one minimal real request per model proves its
        endpoint, model name and key, or the run stops with one clear error saying which is wrong."""
        from jarvis_pytest.errors import ConfigError

        for role, client in (("planner", self.planner), ("grounder", self.grounder.client)):
            try:
                client.probe()
            except ConfigError as exc:
                raise ConfigError(f"{role}: {exc.detail}", field=f"--{role}-{(exc.field or 'base_url').replace('_', '-')}",
                                  fix=exc.fix) from None

    def reset(self, task: TaskContext) -> None:
        self.task = task

    def config(self) -> dict[str, Any]:
        return redact(self._config)

    def planner_messages(self, observations: dict[str, Observation], history: list[HistoryEntry]
                         ) -> list[dict[str, Any]]:
        """System prompt (with history and query) and one user message with the three screenshots."""
        if self.task is None:
            raise RuntimeError("reset(task) must be called before act()")
        parts: list[dict[str, Any]] = []
        for platform in PLATFORMS:
            obs = observations.get(platform)
            label = spec(platform).label
            if obs is None:
                parts.append(text_part(f"{label} screenshot: (none)"))
                continue
            note = "" if obs.available else " (not used by this task; initial screenshot only)"
            parts += [text_part(f"{label} screenshot{note}:"), image_part(obs.screenshot_png)]
        parts.append(text_part("Output the next step as one <step>...</step> JSON object."))
        return [system_message(render_prompt(self.task, history, self.template)),
                {"role": "user", "content": parts}]

    def act(self, observations: dict[str, Observation], history: list[HistoryEntry]) -> AgentStep:
        result = self.planner.chat(self.planner_messages(observations, history), **self.planner_params)
        trace = _Trace(raw=result.text)
        _add_usage(trace.usage, result.usage, "planner")
        try:
            step = parse_planner_output(result.text)
        except PlannerOutputError as exc:
            return trace.step(None, None, f"action not found: {exc}")
        trace.reasoning = "\n".join(line for line in (
            step.step_plan or "(no plan)",
            f"status: {step.current_status}" if step.current_status else "",
            f"element: {step.element_description}" if step.element_description else "") if line)
        trace.extra["planner"] = {"platform": step.platform, "step_plan": step.step_plan,
                                  "element_description": step.element_description, "tool": step.tool}
        platform = step.platform
        if step.action in TERMINAL_TOOLS:
            return trace.step(None, map_action(step, _no_locate, (0, 0))[0])
        if platform not in PLATFORMS:
            return trace.step(None, None, f"action not found: unknown platform {platform!r}; "
                                          f"use android, windows or ubuntu")
        obs = observations.get(platform)
        if obs is None or not obs.available:
            used = ", ".join(self.task.platforms) if self.task else "?"
            return trace.step(platform, None, f"device unavailable: {platform} is not used by this task "
                                              f"(use one of {used})")
        try:
            action, more = map_action(step, lambda text: self._locate(obs, text, trace), _screen_of(obs),
                                      self.swipe_fraction)
        except PlannerOutputError as exc:
            return trace.step(platform, None, f"action not found: {exc}")
        except GroundingError as exc:
            return trace.step(platform, None, f"action not found: the grounding model's answer has no usable "
                                              f"point ({exc})")
        trace.extra.update(more)
        return trace.step(platform, action)

    def _locate(self, obs: Observation, description: str, trace: _Trace) -> tuple[int, int]:
        """Ground `description` on `obs`'s screenshot; the point in device pixels."""
        try:
            g = self.grounder.ground(obs.screenshot_png, description, obs.platform)
        except GroundingError as exc:
            _add_usage(trace.usage, exc.usage, "grounder")
            trace.groundings.append({"instruction": description, "answer": exc.answer or ""})
            raise
        _add_usage(trace.usage, g.usage, "grounder")
        trace.groundings.append({"instruction": description, **g.record()})
        (w, h), (sx, sy) = _screen_of(obs), g.screen_size
        if (sx, sy) == (w, h):
            return g.x, g.y
        return min(int(round(g.x * w / sx)), w - 1), min(int(round(g.y * h / sy)), h - 1)  # shot → device



def _no_locate(description: str) -> tuple[int, int]:
    raise PlannerOutputError("terminate needs no element")


@dataclass
class _Trace:
    """What one step gathers on its way to an AgentStep: texts, token usage, groundings, extra facts."""

    raw: str
    reasoning: str = ""
    usage: dict[str, int] = field(default_factory=dict)
    groundings: list[dict[str, Any]] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict)

    def step(self, platform: str | None, action: Action | None, error: str | None = None) -> AgentStep:
        extra = dict(self.extra)
        if self.groundings:
            extra["grounding"] = self.groundings
        raw = "\n".join([self.raw] + [f"--- grounder ({g['instruction']}) ---\n{g['answer']}"
                                      for g in self.groundings])
        return AgentStep(platform=platform, action=action, reasoning=self.reasoning, raw_output=raw, error=error,
                         usage=self.usage, extra=extra)


# -- construction from options -----------------------------------------------------------------------------------
def _option(options: dict[str, Any], name: str, kind: type, default: Any) -> Any:
    value = options.get(name, default)
    try:
        return kind(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be a {kind.__name__}, got {value!r}", field=f"--agent-option {name}",
                          fix=f"pass e.g. --agent-option {name}={default}") from None


def build_planner_grounder(name: str, grounder_cls: type[Grounder], options: dict[str, Any] | None = None
                           ) -> PlannerGrounderAgent:
    """The planner–grounder agent `name` with `grounder_cls` as grounding model, configured from `options`
    (see :mod:`jarvis_pytest.llm.config` for the keys and the other sources). Extra options:
    ``planner_temperature``, ``planner_max_tokens``, ``swipe_fraction`` (default 0.3)."""
    options = dict(options or {})
    planner_cfg: EndpointConfig = resolve_endpoint("planner", options, defaults={"model": DEFAULT_PLANNER_MODEL})
    grounder_cfg: EndpointConfig = resolve_endpoint("grounder", options,
                                                    defaults={"model": grounder_cls.default_model or None})
    params: dict[str, Any] = {}
    if options.get("planner_temperature") not in (None, ""):
        params["temperature"] = _option(options, "planner_temperature", float, 0.0)
    if options.get("planner_max_tokens") not in (None, ""):
        params["max_tokens"] = _option(options, "planner_max_tokens", int, 2048)
    swipe = _option(options, "swipe_fraction", float, 0.3)
    if not 0 < swipe <= 1:
        raise ConfigError(f"swipe_fraction must be in (0, 1], got {swipe}", field="--agent-option swipe_fraction",
                          fix="pass e.g. --agent-option swipe_fraction=0.3")
    public = {"name": name, "kind": "planner-grounder", "grounder_adapter": grounder_cls.__name__,
              "planner": planner_cfg.public(), "grounder": grounder_cfg.public(), "planner_params": params,
              "swipe_fraction": swipe}
    return PlannerGrounderAgent(name, planner_cfg.client(), grounder_cls(grounder_cfg.client()),
                                planner_params=params, swipe_fraction=swipe, public_config=public)
