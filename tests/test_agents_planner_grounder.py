"""The planner–grounder agent driven by a scripted fake planner and a fake grounding model on the loopback server,
over real Pillow screenshots: prompt and history as in the paper, actions mapped to the unified action space,
grounding on the chosen platform's screenshot only, malformed answers as AgentStep errors, keys kept secret."""

from __future__ import annotations

import json

import pytest

from jarvis_pytest.agents.grounding import smart_resize
from jarvis_pytest.agents.planner import (PlannerOutputError, PlannerStep, map_action, parse_planner_output,
                                          render_history, render_step, render_transfer)
from jarvis_pytest.agents.protocol import AgentStep, HistoryEntry, TaskContext
from jarvis_pytest.agents.registry import load_agent
from jarvis_pytest.devices.base import Observation
from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.llm.fake_server import FakeChatServer, fail
from screens import red_box, screenshot

KEY = "sk-planner-and-grounder-secret"
UBUNTU_BOX = (900, 500, 980, 540)      # centre (940, 520) on 1280x720
ANDROID_BOX = (100, 1800, 500, 1900)   # centre (300, 1850) on 1080x2400
TRANSFER = {"url": "http://transfer:5244", "user": "agent", "password": "agentPassword"}


def step(platform, plan, tool, element="") -> str:
    return render_step(platform, plan, tool, element, current_status="screens shown")


def ui_tars_grounder(req) -> str:
    """A fake UI-TARS: finds the red element in the image it received and clicks its centre."""
    x1, y1, x2, y2 = red_box(req.images()[0])
    return f"Thought: the red element.\nAction: click(point='<point>{(x1 + x2 - 1) / 2:.0f} {(y1 + y2 - 1) / 2:.0f}</point>')"


@pytest.fixture(scope="module")
def observations() -> dict[str, Observation]:
    return {
        "android": Observation("android", screenshot(1080, 2400, [ANDROID_BOX]), 1080, 2400),
        "windows": Observation("windows", screenshot(1920, 1080), 1920, 1080, available=False),
        "ubuntu": Observation("ubuntu", screenshot(1280, 720, [UBUNTU_BOX]), 1280, 720),
    }


def options(server) -> dict:
    return {"planner": {"base_url": server.url, "model": "planner", "api_key": KEY},
            "grounder": {"base_url": server.url, "model": "grounder", "api_key": KEY},
            "planner_max_retries": "0", "grounder_max_retries": "0"}


def run(agent, observations, answers: int) -> list[AgentStep]:
    """Drive the agent like the harness's loop does: history with each step's first reasoning line and error."""
    history: list[HistoryEntry] = []
    steps = []
    for index in range(answers):
        s = agent.act(observations, list(history))
        steps.append(s)
        history.append(HistoryEntry(index=index, platform=s.platform,
                                    plan=s.reasoning.splitlines()[0] if s.reasoning else "",
                                    action=None if s.action is None else s.action.model_dump(mode="json"),
                                    error=s.error))
    return steps


def test_scripted_episode(observations):
    with FakeChatServer(api_key=KEY) as server:
        server.respond_with(ui_tars_grounder, model="grounder")
        server.script(
            "I think the red app should be opened first.",  # no <step>: must come back as an error
            step("ubuntu", "Open the red app", {"action": "left_click"}, "the red app icon"),
            step("ubuntu", "Type the greeting", {"action": "type", "text": "hello <world> {ok}"}),
            step("android", "Scroll the list", {"action": "swipe", "direction": "up"}, "the red list"),
            step("windows", "Open the browser", {"action": "left_click"}, "the browser icon"),
            step("Ubuntu", "Save", {"action": "key", "keys": "ctrl+s"}),
            step(None, "All done", {"action": "terminate", "status": "success"}),
            model="planner")
        agent = load_agent("ui-tars-1.5", options(server))
        agent.reset(TaskContext("t1", "Open the red app on Ubuntu, greet, scroll the phone's list, save.",
                                ("android", "ubuntu"), transfer=TRANSFER))
        steps = run(agent, observations, 7)

        bad, click, typing, swipe, unavailable, key, done = steps
        assert bad.action is None and bad.platform is None and bad.error.startswith("action not found")
        assert "I think the red app" in bad.raw_output
        assert click.platform == "ubuntu" and click.action.type == "CLICK" and click.error is None
        assert abs(click.action.x - 940) <= 2 and abs(click.action.y - 520) <= 2
        assert click.reasoning.splitlines()[0] == "Open the red app"
        assert typing.action.type == "TYPING" and typing.action.text == "hello <world> {ok}"
        assert swipe.platform == "android" and swipe.action.type == "SWIPE"
        assert abs(swipe.action.x - 300) <= 2 and abs(swipe.action.y - 1850) <= 2
        assert (swipe.action.dx, swipe.action.dy) == (0, -720)
        assert unavailable.action is None and unavailable.error.startswith("device unavailable: windows")
        assert key.platform == "ubuntu" and key.action.keys == ["ctrl", "s"]
        assert done.action.type == "DONE" and done.platform is None

        grounder_requests = server.requests_for("grounder")
        assert len(grounder_requests) == 2  # only the click and the swipe needed a position
        h, w = smart_resize(720, 1280, 28, 100 * 784, 16384 * 784)
        assert grounder_requests[0].image_sizes() == [(w, h)]
        assert "the red app icon" in grounder_requests[0].text()
        h, w = smart_resize(2400, 1080, 28, 100 * 784, 16384 * 784)
        assert grounder_requests[1].image_sizes() == [(w, h)]  # the Android screenshot, and only it
        assert click.extra["grounding"][0]["sent_size"] == [1288, 728]

        planner_requests = server.requests_for("planner")
        assert len(planner_requests) == 7
        assert all(r.image_sizes() == [(1080, 2400), (1920, 1080), (1280, 720)] for r in planner_requests)
        user_text = planner_requests[0].text("user")
        assert "Windows screenshot (not used by this task" in user_text and "Android screenshot:" in user_text
        prompt = planner_requests[-1].text("system")
        assert "User Query: Open the red app on Ubuntu" in prompt
        assert "http://transfer:5244" in prompt and "agentPassword" in prompt and "username: agent" in prompt
        assert "Step 1 on no platform: (no plan) -- ERROR: action not found" in prompt
        assert "Step 2 on ubuntu: Open the red app\n" in prompt
        assert "Step 5 on windows: Open the browser -- ERROR: device unavailable" in prompt
        assert planner_requests[0].text("system").count("Current history:\n(none)") == 1
        assert all(r.headers["Authorization"] == f"Bearer {KEY}" for r in server.requests)

        assert click.usage["planner_prompt_tokens"] > 0 and click.usage["grounder_prompt_tokens"] > 0
        assert click.usage["prompt_tokens"] == click.usage["planner_prompt_tokens"] + click.usage["grounder_prompt_tokens"]
        assert "grounder_prompt_tokens" not in typing.usage

        config = json.dumps(agent.config())
        assert KEY not in config and "api_key" not in config
        assert agent.config()["grounder"] == {"base_url": server.url, "model": "grounder"}


def test_unusable_grounding_answer_is_a_step_error(observations):
    with FakeChatServer() as server:
        server.script(step("ubuntu", "Click it", {"action": "click"}, "the red app icon"), model="planner")
        server.script("I am not sure where that is.", model="grounder")
        agent = load_agent("holo2", {k: {**v, "api_key": None} if isinstance(v, dict) else v
                                     for k, v in options(server).items()})
        agent.reset(TaskContext("t", "click", ("ubuntu",)))
        s = agent.act(observations, [])
        assert s.action is None and s.platform == "ubuntu"
        assert s.error.startswith("action not found: the grounding model's answer has no usable point")
        assert "I am not sure" in s.raw_output


def test_endpoint_down_raises_infrastructure_error(observations):
    with FakeChatServer() as server:
        server.script(fail(503), model="planner")
        agent = load_agent("qwen3-vl", options(server))
        agent.reset(TaskContext("t", "x", ("ubuntu",)))
        with pytest.raises(InfrastructureError, match="503"):
            agent.act(observations, [])


@pytest.mark.parametrize("text,platform,action", [
    ('<step>{"platform": "ubuntu", "step_plan": "p", "tool": {"action": "wait", "time": 2}}</step>', "ubuntu", "wait"),
    ('```json\n{"platform": "Android", "tool": {"action": "Long Press"}}\n```', "android", "long_press"),
    ('Thinking...\n<step>\n{"platform": "windows", "tool": "double_click"}', "windows", "double_click"),
    ('<step>{"step_plan": "old"}</step> ... <step>{"platform": "ubuntu", "tool": {"action": "scroll"}}</step>',
     "ubuntu", "scroll"),
])
def test_parse_planner_output_tolerates(text, platform, action):
    parsed = parse_planner_output(text)
    assert parsed.platform == platform and parsed.action == action


@pytest.mark.parametrize("text,match", [
    ("no json at all", "no <step> tag"),
    ("<step>{not json}</step>", "inside <step>"),
    ('<step>{"platform": "ubuntu", "step_plan": "p"}</step>', "no tool action"),
])
def test_parse_planner_output_errors(text, match):
    with pytest.raises(PlannerOutputError, match=match):
        parse_planner_output(text)


def _map(tool: dict, element: str = "the thing", screen=(1000, 800)):
    located: list[str] = []

    def locate(description):
        located.append(description)
        return (100, 700) if description == "the drop zone" else (100, 200)

    action, extra = map_action(PlannerStep("", "ubuntu", "p", element, tool), locate, screen)
    return action.model_dump(exclude_defaults=False), located, extra


@pytest.mark.parametrize("tool,element,expected", [
    ({"action": "click"}, "x", {"type": "CLICK", "x": 100, "y": 200, "button": "left", "clicks": 1}),
    ({"action": "left_click"}, "x", {"type": "CLICK", "x": 100, "y": 200}),
    ({"action": "right_click"}, "x", {"type": "RIGHT_CLICK", "x": 100, "y": 200}),
    ({"action": "double_click"}, "x", {"type": "DOUBLE_CLICK", "x": 100, "y": 200}),
    ({"action": "triple_click"}, "x", {"type": "CLICK", "clicks": 3}),
    ({"action": "long_press"}, "x", {"type": "LONG_PRESS", "x": 100, "y": 200}),
    ({"action": "drag", "target": "the drop zone"}, "x", {"type": "DRAG_TO", "x": 100, "y": 700, "start_x": 100,
                                                          "start_y": 200}),
    ({"action": "swipe", "direction": "down"}, "x", {"type": "SWIPE", "x": 100, "y": 200, "dx": 0, "dy": 240}),
    ({"action": "swipe", "direction": "left"}, "x", {"type": "SWIPE", "dx": -100}),  # clamped at the edge
    ({"action": "swipe", "direction": "up"}, "", {"type": "SWIPE", "x": 500, "y": 400, "dy": -240}),
    ({"action": "type", "text": "a\nb"}, "", {"type": "TYPING", "text": "a\nb"}),
    ({"action": "key", "keys": ["Ctrl", "Shift", "t"]}, "", {"type": "HOTKEY", "keys": ["ctrl", "shift", "t"]}),
    ({"action": "key", "keys": "enter"}, "", {"type": "HOTKEY", "keys": ["enter"]}),
    ({"action": "scroll", "pixels": -5}, "", {"type": "SCROLL", "dy": 5, "dx": 0, "x": None}),
    ({"action": "scroll", "pixels": 3}, "the list", {"type": "SCROLL", "dy": -3, "x": 100, "y": 200}),
    ({"action": "hscroll", "pixels": 4}, "", {"type": "SCROLL", "dx": 4, "dy": 0}),
    ({"action": "scroll", "direction": "down"}, "", {"type": "SCROLL", "dy": 5}),
    ({"action": "scroll", "pixels": -10000}, "", {"type": "SCROLL", "dy": 50}),
    ({"action": "system_button", "button": "Back"}, "", {"type": "SYSTEM_BUTTON", "button": "back"}),
    ({"action": "wait", "time": 3}, "", {"type": "WAIT", "seconds": 3.0}),
    ({"action": "wait"}, "", {"type": "WAIT", "seconds": 1.0}),
    ({"action": "answer", "text": "42"}, "", {"type": "WAIT", "seconds": 0.0}),
    ({"action": "terminate", "status": "success"}, "", {"type": "DONE"}),
    ({"action": "terminate", "status": "failure"}, "", {"type": "FAIL"}),
])
def test_tool_actions_map_to_the_action_space(tool, element, expected):
    dumped, located, _ = _map(tool, element)
    assert {k: dumped[k] for k in expected} == expected
    needs_point = tool["action"] not in ("type", "key", "hscroll", "system_button", "wait", "answer", "terminate") \
        and not (tool["action"] in ("scroll", "swipe") and not element)
    assert bool(located) == needs_point


@pytest.mark.parametrize("tool,element,match", [
    ({"action": "click"}, "", "needs an element_description"),
    ({"action": "fly"}, "x", "unknown tool action 'fly'"),
    ({"action": "swipe", "direction": "sideways"}, "x", "direction"),
    ({"action": "type"}, "", "needs \"text\""),
    ({"action": "key"}, "", "needs \"keys\""),
    ({"action": "system_button", "button": "turbo"}, "", "unknown system button"),
    ({"action": "wait", "time": "soon"}, "", "needs a number"),
    ({"action": "drag"}, "x", "needs \"target\""),
])
def test_unusable_tool_actions(tool, element, match):
    with pytest.raises(PlannerOutputError, match=match):
        _map(tool, element)


def test_history_and_transfer_rendering():
    history = [HistoryEntry(0, "ubuntu", "Open Files", {"type": "CLICK"}),
               HistoryEntry(1, None, "", None, error="action not found: no JSON\nsecond line")]
    assert render_history(history) == ("Step 1 on ubuntu: Open Files\n"
                                       "Step 2 on no platform: (no plan) -- ERROR: action not found: no JSON second line")
    assert render_history([]) == "(none)"
    alist = render_transfer(TRANSFER)
    assert "three dot button" in alist and "folder: /data" in alist
    copyparty = render_transfer({**TRANSFER, "flavour": "copyparty"})
    assert "copyparty" in copyparty and "password: agentPassword" in copyparty
    assert "No file transfer server" in render_transfer({})


def test_preflight_probes_both_models_at_once(monkeypatch):
    """Start-up waits for the slower model, not the sum of both: each probe waits until both are in flight (one
    after the other, the first would wait in vain and the barrier break), then makes its real request."""
    import threading

    with FakeChatServer(api_key=KEY, models=("planner", "grounder")) as server:
        agent = load_agent("holo2", options(server))
        both = threading.Barrier(2, timeout=10)
        for client in (agent.planner, agent.grounder.client):
            monkeypatch.setattr(client, "probe", lambda real=client.probe, **kw: (both.wait(), real(**kw))[1])
        agent.preflight()
    assert sorted(r.model for r in server.requests) == ["grounder", "planner"]
