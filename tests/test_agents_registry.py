"""Finding agents: built-ins, the six adapters of agents/, module:Class, a folder of one's own (AGENTS and
GROUNDERS), clear errors for unknown names, broken modules and duplicates; and `jarvis ground` end to end."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import pytest

from jarvis_pytest.agents.grounding import Grounder
from jarvis_pytest.agents.planner import PlannerGrounderAgent
from jarvis_pytest.agents.protocol import Agent
from jarvis_pytest.agents.registry import discover, known_agents, load_agent, load_grounder_class
from jarvis_pytest.cli import main
from jarvis_pytest.errors import ConfigError
from jarvis_pytest.llm.fake_server import FakeChatServer
from screens import screenshot

ADAPTERS = ["qwen3-vl", "holo2", "ui-tars-1.5", "mai-ui", "ui-venus", "gui-owl"]
ENDPOINTS = {"planner": {"base_url": "http://127.0.0.1:9/v1", "model": "p", "api_key": "sk-p"},
             "grounder": {"base_url": "http://127.0.0.1:9/v1", "model": None, "api_key": "sk-g"}}


@pytest.fixture(autouse=True)
def clean_environment(monkeypatch, tmp_path):
    """No JARVIS_* variables and no pyproject [tool.jarvis] of the user's leak into these tests."""
    import os

    for var in [v for v in os.environ if v.startswith("JARVIS_")]:
        monkeypatch.delenv(var)
    monkeypatch.chdir(tmp_path)


def test_all_adapters_are_found():
    assert set(ADAPTERS) <= set(known_agents())
    assert {"oracle", "noop", "replay"} <= set(known_agents())
    assert discover().errors == {}


@pytest.mark.parametrize("name", ADAPTERS)
def test_each_adapter_builds_a_planner_grounder_agent(name):
    agent = load_agent(name, ENDPOINTS)
    assert isinstance(agent, Agent) and isinstance(agent, PlannerGrounderAgent)
    assert agent.name == name
    cls = load_grounder_class(name)
    assert agent.config()["grounder"]["model"] == cls.default_model  # the adapter's model id by default
    assert "sk-" not in json.dumps(agent.config())


def test_builtins_and_module_class():
    assert load_agent("noop", ENDPOINTS).name == "noop"
    agent = load_agent("jarvis_pytest.agents.builtin:NoopAgent", {})
    assert agent.name == "noop"


def test_unknown_name_lists_the_known_ones():
    with pytest.raises(ConfigError) as info:
        load_agent("holo3", ENDPOINTS)
    text = str(info.value)
    assert "unknown agent 'holo3'" in text and "holo2" in text and "oracle" in text
    with pytest.raises(ConfigError, match="cannot import"):
        load_agent("no_such_module_xyz:Agent", {})
    with pytest.raises(ConfigError, match="unknown grounding model 'oracle'"):
        load_grounder_class("oracle")


def test_missing_endpoint_is_a_config_error():
    with pytest.raises(ConfigError, match="--planner-base-url"):
        load_agent("holo2", {"planner": {}, "grounder": {}})


def test_own_folder_with_agents_and_grounders(tmp_path: Path):
    (tmp_path / "mine.py").write_text(
        "from jarvis_pytest.agents.builtin import NoopAgent\n"
        "from jarvis_pytest.agents.grounding import Grounder\n"
        "class MyGrounder(Grounder):\n    name = 'my-grounder'\n    default_model = 'me/model'\n"
        "    def messages(self, instruction, image, size, platform):\n"
        "        return [{'role': 'user', 'content': [image]}]\n"
        "GROUNDERS = {'my-grounder': MyGrounder}\n"
        "AGENTS = {'lazy': lambda options: NoopAgent(options)}\n")
    (tmp_path / "broken.py").write_text("raise RuntimeError('boom')\n")
    (tmp_path / "_private.py").write_text("raise RuntimeError('never loaded')\n")
    with pytest.warns(UserWarning, match="broken.py failed to load"):
        catalog = discover(tmp_path, refresh=True)
    assert sorted(catalog.agents) == ["lazy", "my-grounder"]
    assert issubclass(load_grounder_class("my-grounder", agents_dir=tmp_path), Grounder)
    assert load_agent("lazy", {}, agents_dir=tmp_path).name == "noop"
    with pytest.raises(ConfigError, match=r"broken.py failed to load \(RuntimeError: boom\)"):
        load_agent("nothing", {}, agents_dir=tmp_path)


def test_duplicate_names_are_refused(tmp_path: Path):
    for stem in ("a", "b"):
        (tmp_path / f"{stem}.py").write_text("AGENTS = {'same': lambda options: None}\n")
    with pytest.raises(ConfigError, match="declared twice"):
        discover(tmp_path, refresh=True)


@pytest.mark.parametrize("model,answer,size,expected", [
    ("holo2", '{"x": 250, "y": 500}', (1920, 1080), {"x": 480, "y": 540}),
    ("ui-venus", "[100,100,300,200]", (1280, 720), None),  # absolute in the resized image: computed below
])
def test_jarvis_ground_prints_the_pixel(tmp_path, capsys, model, answer, size, expected):
    image = tmp_path / "shot.png"
    image.write_bytes(screenshot(*size))
    with FakeChatServer(lambda req: answer, api_key="sk-cli") as server:
        code = main(["ground", "--model", model, "--base-url", server.url, "--api-key", "sk-cli",
                     "--image", str(image), "--instruction", "the Save button", "--json"])
        (req,) = server.requests_for(load_grounder_class(model).default_model)
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    if expected is None:  # UI-Venus saw 1904x1064: centre (200, 150) maps to (200*1280/1904, 150*720/1064)
        assert req.image_sizes() == [(1904, 1064)]
        expected = {"x": round(200 * 1280 / 1904), "y": round(150 * 720 / 1064)}
    assert out == expected


def test_jarvis_ground_errors(tmp_path, capsys):
    image = tmp_path / "shot.png"
    image.write_bytes(screenshot(200, 100))
    with FakeChatServer(lambda req: "no idea") as server:
        code = main(["ground", "--model", "qwen3-vl", "--base-url", server.url, "--image", str(image),
                     "--instruction", "x", "--json"])
    assert code == 2 and "no point or box found" in capsys.readouterr().err
    code = main(["ground", "--model", "qwen9", "--base-url", "http://127.0.0.1:9/v1", "--image", str(image),
                 "--instruction", "x"])
    assert code == 2 and "unknown grounding model 'qwen9'" in capsys.readouterr().err
    (tmp_path / "x.txt").write_text("not a png")
    code = main(["ground", "--model", "holo2", "--base-url", "http://127.0.0.1:9/v1", "--image",
                 str(tmp_path / "x.txt"), "--instruction", "x"])
    assert code == 2 and "not a PNG" in capsys.readouterr().err


class _Adapter:
    name = "probe"

    def __init__(self, options=None):
        pass

    def reset(self, task):
        pass

    def act(self, observations, history):
        raise AssertionError

    def config(self):
        return {"name": self.name}


def _raises(exc: BaseException):
    def boom(*args, **kwargs):
        raise exc
    return boom


@pytest.mark.parametrize("make, problem", [
    (_raises(RuntimeError("no key")), "building it raised RuntimeError: no key"),
    (lambda options: type("NoAct", (), {"reset": lambda s, t: None, "config": lambda s: {}})(), "no act method"),
    (lambda options: type("BadCfg", (_Adapter,), {"config": _raises(ValueError("x"))})(), "config() raised"),
    (lambda options: type("ListCfg", (_Adapter,), {"config": lambda s: ["probe"]})(), "not a dict"),
    (lambda options: type("ObjCfg", (_Adapter,), {"config": lambda s: {"o": object()}})(), "not plain JSON"),
    (lambda options: type("NanCfg", (_Adapter,), {"config": lambda s: {"t": float("nan")}})(), "not plain JSON"),
])
def test_a_broken_adapter_is_one_config_error_at_load(monkeypatch, make, problem):
    """An adapter whose constructor or config() raises, that lacks a method of the protocol, or whose config is no
    plain JSON (written into run.json) used to be an INTERNALERROR; now it is one error naming the agent."""
    module = type(sys)("probe_adapters")
    module.Make = make
    monkeypatch.setitem(sys.modules, "probe_adapters", module)
    with pytest.raises(ConfigError, match=re.escape(problem)) as info:
        load_agent("probe_adapters:Make", {})
    assert "probe_adapters:Make" in str(info.value) and info.value.field == "--agent"
    module.Make = _Adapter
    assert isinstance(load_agent("probe_adapters:Make", {}), _Adapter)


def test_the_agent_options_help_names_every_built_in_agent():
    """`pytest --help` lists the built-in agents by name: one added to BUILTIN_AGENTS is named there too."""
    import inspect

    from jarvis_pytest.agents.builtin import BUILTIN_AGENTS
    from jarvis_pytest.plugin import options

    source = inspect.getsource(options.addoption)
    assert [name for name in BUILTIN_AGENTS if name not in source] == []
