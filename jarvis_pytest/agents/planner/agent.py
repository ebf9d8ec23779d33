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
    """`options` with every secret-looking value replaced by "***" (nested dicts included); a count of tokens
    (`max_tokens`) is no secret."""
    out: dict[str, Any] = {}
    for key, value in options.items():
        if isinstance(value, dict):
            out[key] = redact(value)
        elif any(word in str(key).lower() for word in SECRET_WORDS) and not str(key).lower().endswith("_tokens"):
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
                 swipe_fraction: float = 0.3, public_config: dict[str, Any] | None = None, seed: str = "derived"):
        self.name = name
        self.seed_mode = seed
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

        seed = {} if self.seed_mode == "none" else {"seed": 0}  # a server that refuses seeds says so now

        def probe(client: Any) -> ConfigError | None:
            try:
                client.probe(extra=seed)
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
        self.grounder.call_params = self._seed()

    def _seed(self) -> dict[str, Any]:
        """`{"seed": N}` for every request of this task and trial (`TaskContext.seed`), unless seeds are off."""
        if self.seed_mode == "none" or self.task is None or self.task.seed is None:
            return {}
        return {"seed": self.task.seed}

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
        result = self.planner.chat(self.planner_messages(observations, history), **self.planner_params,
                                   **self._seed())
        trace = _Trace(raw=result.text, model_seconds=result.seconds)
        if result.raw.get("system_fingerprint"):  # the server's build behind the answer (OpenAI, vLLM)
            trace.extra["system_fingerprint"] = str(result.raw["system_fingerprint"])
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


SAMPLING = {"temperature": (float, 0.0), "top_p": (float, 1.0)}  # name → (type, default): sent on every call
PLANNER_MAX_TOKENS = 2048
SEED_MODES = ("derived", "none")


def _sampling(options: dict[str, Any], role: str, defaults: dict[str, Any]) -> dict[str, Any]:
    """The sampling parameters of `role`'s requests: `defaults`, each overridable by `--agent-option
    <role>_<name>=VALUE`; every one of them is sent on every call (a server's own default never decides)."""
    params = dict(defaults)
    for name, value in defaults.items():
        given = options.get(f"{role}_{name}")
        if given not in (None, ""):
            params[name] = _option(options, f"{role}_{name}", type(value) if value is not None else float, value)
    for name in ("temperature", "top_p"):
        if name in params and not 0 <= params[name] <= (2 if name == "temperature" else 1):
            raise ConfigError(f"{role}_{name} {params[name]} is out of range", field=f"--agent-option {role}_{name}",
                              fix=f"pass e.g. --agent-option {role}_{name}={SAMPLING[name][1]}")
    if params.get("max_tokens") is not None and params["max_tokens"] < 1:
        raise ConfigError(f"{role}_max_tokens must be 1 or more", field=f"--agent-option {role}_max_tokens",
                          fix=f"pass e.g. --agent-option {role}_max_tokens={PLANNER_MAX_TOKENS}")
    return params


def _full_screens() -> dict[str, Any]:
    """The planner's screenshots, for the run card: PNG at each platform's full screen size."""
    from jarvis_pytest.devices.platforms import PLATFORMS

    screens = {p: list(f.screen) for p, f in PLATFORMS.items()}
    return {"encoding": "PNG", "screen": screens, "sent": screens}


def source_digest(*objects: Any) -> str:
    """A short SHA-256 of the source files of `objects` (modules, classes, paths): what a prompt or a parser was
    when a run was made, comparable across runs (`jarvis diff`)."""
    import hashlib
    import inspect
    from pathlib import Path

    h = hashlib.sha256()
    for obj in objects:
        path = obj if isinstance(obj, Path) else Path(inspect.getsourcefile(obj) or "")
        h.update(path.name.encode() + b"\0" + (path.read_bytes() if path.is_file() else b"?") + b"\0")
    return h.hexdigest()[:16]


def build_planner_grounder(name: str, grounder_cls: type[Grounder], options: dict[str, Any] | None = None
                           ) -> PlannerGrounderAgent:
    """The planner–grounder agent `name` with `grounder_cls` as grounding model, configured from `options`
    (see :mod:`jarvis_pytest.llm.config` for the keys and the other sources). Extra options: the sampling
    parameters ``planner_temperature`` (default 0: greedy), ``planner_top_p`` (1), ``planner_max_tokens`` (2048),
    ``grounder_temperature``, ``grounder_top_p``, ``grounder_max_tokens`` (the adapter's own, else 0, 1 and 256),
    all sent on every call; ``seed`` (``derived``, the default: each call carries a seed from the task id and the
    trial; ``none``: no seed, for a server that refuses the field); ``swipe_fraction`` (default 0.3)."""
    options = dict(options or {})
    planner_cfg: EndpointConfig = resolve_endpoint("planner", options, defaults={"model": DEFAULT_PLANNER_MODEL})
    grounder_cfg: EndpointConfig = resolve_endpoint("grounder", options,
                                                    defaults={"model": grounder_cls.default_model or None})
    params = _sampling(options, "planner", {**{k: d for k, (_, d) in SAMPLING.items()},
                                            "max_tokens": PLANNER_MAX_TOKENS})
    adapter = grounder_cls.params
    grounder_params = _sampling(options, "grounder", {"temperature": adapter.get("temperature", 0.0),
                                                      "top_p": adapter.get("top_p", 1.0),
                                                      "max_tokens": adapter.get("max_tokens", 256)})
    seed = str(options.get("seed") or "derived")
    if seed not in SEED_MODES:
        raise ConfigError(f"seed {seed!r} is not one of {', '.join(SEED_MODES)}", field="--agent-option seed",
                          fix="pass --agent-option seed=derived (a seed per task and trial) or seed=none")
    swipe = _option(options, "swipe_fraction", float, 0.3)
    if not 0 < swipe <= 1:
        raise ConfigError(f"swipe_fraction must be in (0, 1], got {swipe}", field="--agent-option swipe_fraction",
                          fix="pass e.g. --agent-option swipe_fraction=0.3")
    from jarvis_pytest.agents import grounding
    from jarvis_pytest.agents.planner import prompt as prompt_module, tools as tools_module

    public = {"name": name, "kind": "planner-grounder", "grounder_adapter": grounder_cls.__name__,
              "planner": planner_cfg.public(), "grounder": grounder_cfg.public(), "planner_params": params,
              "grounder_params": {**grounder_cls.params, **grounder_params}, "seed": seed,
              "swipe_fraction": swipe,
              "prompts": {"planner": source_digest(PROMPT_FILE, prompt_module),
                          "grounder": source_digest(grounder_cls)},
              "parsers": {"planner": source_digest(tools_module), "grounder": source_digest(grounding, grounder_cls)},
              "model_input": {"planner": _full_screens(), "grounder": grounder_cls.model_input()}}
    grounder = grounder_cls(grounder_cfg.client())
    grounder.overrides = grounder_params
    return PlannerGrounderAgent(name, planner_cfg.client(), grounder, planner_params=params, swipe_fraction=swipe,
                                public_config=public, seed=seed)
