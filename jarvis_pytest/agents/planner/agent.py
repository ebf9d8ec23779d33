"""The planner–grounder agent and its construction from options.

At each step the planner (a general VL model such as Qwen3-VL-Plus behind any OpenAI-compatible endpoint) sees the
screenshots of Android, Windows and Ubuntu, the instruction and the history ("Step N on <platform>: <plan>", with
the framework's errors), and answers one ``<step>{...}</step>`` JSON object: current status, platform, step plan,
element description and a tool action. Actions that need a position are grounded by the grounding model on the
chosen platform's screenshot alone; the result is one action of the unified action space.

Planner output that cannot be parsed or used comes back as an ``AgentStep`` with ``error`` set and
``action=None`` (the harness feeds the error back into the history); an unreachable endpoint raises
``InfrastructureError``.
"""

from __future__ import annotations

import io
from dataclasses import dataclass, field
from typing import Any

from PIL import Image

from jarvis_pytest.agents.grounding import Grounder, GroundingError
from jarvis_pytest.agents.planner.prompt import PROMPT_FILE, render_prompt
from jarvis_pytest.agents.planner.tools import TERMINAL_TOOLS, PlannerOutputError, map_action, parse_planner_output
from jarvis_pytest.agents.protocol import AgentStep, HistoryEntry, TaskContext
from jarvis_pytest.devices.actions import PLATFORMS, Action
from jarvis_pytest.devices.base import Observation
from jarvis_pytest.devices.platforms import spec
from jarvis_pytest.errors import ConfigError
from jarvis_pytest.llm.client import ChatClient, image_part, system_message, text_part
from jarvis_pytest.llm.config import EndpointConfig, resolve_endpoint

DEFAULT_PLANNER_MODEL = "qwen3-vl-plus"  # the paper's planner (DashScope compatible mode)
SECRET_WORDS = ("key", "token", "secret", "password")


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


# -- one step's usage and trace ----------------------------------------------------------------------------------
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
    model_seconds: float = 0.0  # time spent waiting for the models' answers

    def step(self, platform: str | None, action: Action | None, error: str | None = None) -> AgentStep:
        extra = dict(self.extra)
        extra["model_ms"] = round(self.model_seconds * 1000, 1)
        if self.groundings:
            extra["grounding"] = self.groundings
        raw = "\n".join([self.raw] + [f"--- grounder ({g['instruction']}) ---\n{g['answer']}"
                                      for g in self.groundings])
        return AgentStep(platform=platform, action=action, reasoning=self.reasoning, raw_output=raw, error=error,
                         usage=self.usage, extra=extra)


# -- the agent ---------------------------------------------------------------------------------------------------
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
        endpoint, model name and key, or the run stops with one clear error saying which is wrong (the planner's
        first). Both requests are in flight together: start-up waits for the slower model, not for the sum."""
        from concurrent.futures import ThreadPoolExecutor

        def probe(client: Any) -> ConfigError | None:
            try:
                client.probe()
            except ConfigError as exc:
                return exc
            return None

        roles = (("planner", self.planner), ("grounder", self.grounder.client))
        with ThreadPoolExecutor(len(roles)) as pool:
            problems = list(pool.map(probe, [client for _, client in roles]))
        for (role, _), exc in zip(roles, problems):
            if exc is not None:
                raise ConfigError(f"{role}: {exc.detail}", field=f"--{role}-{(exc.field or 'base_url').replace('_', '-')}",
                                  fix=exc.fix)

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
        trace = _Trace(raw=result.text, model_seconds=result.seconds)
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
        trace.model_seconds += g.model_seconds
        trace.groundings.append({"instruction": description, **g.record()})
        (w, h), (sx, sy) = _screen_of(obs), g.screen_size
        if (sx, sy) == (w, h):
            return g.x, g.y
        return min(int(round(g.x * w / sx)), w - 1), min(int(round(g.y * h / sy)), h - 1)  # shot → device


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
