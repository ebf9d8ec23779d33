"""The agent boundary: a third-party agent sees the instruction, the platforms, the drive's login, the observations
and its own history, never the solution, the near-miss states, the evaluators' arguments or the devices; only the
built-in oracle (by its class object) is handed those, through `jarvis_pytest.agents.oracle.brief`.

The spies below are third-party agents, loaded as users load theirs (`--agent module:Class`, the registry). From
everything the harness hands them (their `reset` and `act` arguments, the options they were built with, their
own attributes, and any device-taking hook they define) they walk the object graph through the data it holds
(`gc.get_referents`, closures, bound methods; not classes, modules or globals, which is what `import` gives
any code) and record every type and string they reach.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from jarvis_pytest.agents.oracle import OracleAgent, brief
from jarvis_pytest.agents.registry import load_agent
from jarvis_pytest.agents.protocol import TaskContext
from jarvis_pytest.report.rollup import load_results
from jarvis_pytest.tasks.instances import atomic_task
from jarvis_pytest.tasks.library import read_template_file

REPO = Path(__file__).resolve().parents[1]
TEMPLATE = REPO / "tasks" / "ubuntu" / "thunar_rename_file.json"
TASK = "thunar-rename_file"  # seed 0 with --instances 1

SPY_MODULE = textwrap.dedent('''
    """Third-party agents that look for the answers in whatever the harness hands them."""

    import gc
    import json
    import types
    import weakref

    from jarvis_pytest.agents.oracle import OracleAgent
    from jarvis_pytest.agents.protocol import AgentStep
    from jarvis_pytest.devices.actions import Done, Wait

    CODE = (type, types.ModuleType, types.CodeType, types.FrameType, types.BuiltinFunctionType)
    RECORD = {"hooks": [], "types": set(), "strings": set(), "walked": 0}  # module state: not walked itself


    def walk(*roots, depth=20, limit=300_000):
        """Record every object reachable from `roots` through the data they hold."""
        seen, frontier = set(), list(roots)
        for _ in range(depth):
            following = []
            for obj in frontier:
                if id(obj) in seen or isinstance(obj, CODE) or len(seen) > limit:
                    continue
                seen.add(id(obj))
                RECORD["types"].add(f"{type(obj).__module__}.{type(obj).__qualname__}")
                if isinstance(obj, str):
                    RECORD["strings"].add(obj[:20_000])
                    continue
                if isinstance(obj, types.FunctionType):  # its data: closure and defaults (not its globals)
                    following += [c.cell_contents for c in obj.__closure__ or () if c.cell_contents is not None]
                    following += list(obj.__defaults__ or ()) + list((obj.__kwdefaults__ or {}).values())
                    continue
                if isinstance(obj, weakref.ref):
                    following.append(obj())
                    continue
                following += gc.get_referents(obj)
            frontier = following
        RECORD["walked"] += len(seen)


    def save(options):
        out = dict(RECORD, types=sorted(RECORD["types"]), strings=sorted(RECORD["strings"]))
        with open(options["out"], "w") as f:
            json.dump(out, f)


    class Spying:
        """reset/act/attach_devices that walk what they are given, then WAIT once and DONE."""

        name = "oracle"  # the oracle's name: no privilege comes with it

        def __init__(self, options=None):
            self.options = dict(options or {})
            self.acted = 0

        def reset(self, task):
            RECORD["hooks"].append("reset")
            walk(task, self)
            save(self.options)

        def attach_devices(self, devices):  # what the harness used to call on any agent defining it
            RECORD["hooks"].append("attach_devices")
            walk(devices)
            save(self.options)

        def act(self, observations, history):
            RECORD["hooks"].append("act")
            walk(observations, history, self)
            save(self.options)
            self.acted += 1
            if self.acted == 1:
                return AgentStep(platform="ubuntu", action=Wait(seconds=0), reasoning="look around")
            return AgentStep(platform=None, action=Done(), reasoning="nothing found")

        def config(self):
            return {"name": "spy"}


    class SubclassSpy(Spying, OracleAgent):
        """A subclass of the built-in oracle that calls itself "oracle"."""

        def reset(self, task):
            OracleAgent.reset(self, task)
            Spying.reset(self, task)


    class MaskSpy(Spying):
        """Says it is an OracleAgent to `isinstance` (its `__class__`)."""

        __class__ = property(lambda self: OracleAgent)


    # A look-alike: the oracle's own namespace (its methods, slots, name, module and qualified name) with the
    # spy's methods over it.
    SLOTS = tuple(getattr(OracleAgent, "__slots__", ()))
    DuckSpy = type("OracleAgent", (), {
        **{k: v for k, v in vars(OracleAgent).items() if k not in ("__dict__", "__weakref__", *SLOTS)},
        "__slots__": SLOTS + ("acted",), "__module__": OracleAgent.__module__,
        "__qualname__": OracleAgent.__qualname__, "__init__": Spying.__init__,
        "reset": lambda self, task: (OracleAgent.reset(self, task), Spying.reset(self, task))[0],
        "act": Spying.act, "attach_devices": Spying.attach_devices, "config": Spying.config})
''')

#: Types whose instances carry a task's answers or reach its devices (or are the harness's own state).
FORBIDDEN_MODULES = ("jarvis_pytest.tasks.", "jarvis_pytest.evaluators.", "jarvis_pytest.infra.",
                     "jarvis_pytest.plugin.", "jarvis_pytest.results.", "jarvis_pytest.devices.")
ALLOWED = {"jarvis_pytest.devices.base.Observation"}  # plain values: platform, PNG bytes, size, a11y text


def secrets(task) -> set[str]:
    """The strings of the task's solution, near-miss states and evaluators that its instruction does not say."""
    found: set[str] = set()

    def strings(value):
        if isinstance(value, str):
            found.add(value)
        elif isinstance(value, dict):
            for k, v in value.items():
                if k not in ("kind", "type", "user", "platform"):  # names of the schema, not of this task
                    strings(v)
        elif isinstance(value, (list, tuple)):
            for v in value:
                strings(v)

    for sub in task.formatted_subtasks:
        dumped = sub.model_dump(mode="json")
        strings([dumped["solution"], dumped["negatives"], dumped["evaluate"]])
    return {s for s in found if len(s) >= 6 and s not in task.instruction}


def leaks(record: dict, task) -> list[str]:
    """What a spy's record shows of the answers: forbidden types, secret strings, a device hook called."""
    bad = [t for t in record["types"]
           if t.startswith(FORBIDDEN_MODULES) and t not in ALLOWED or t == "jarvis_pytest.agents.oracle.PlanItem"]
    hidden = secrets(task)
    assert hidden, "the task has no secrets to look for"
    bad += [f"string {s!r}" for s in sorted(hidden) if any(s in reached for reached in record["strings"])]
    bad += [f"hook {h}" for h in record["hooks"] if h not in ("reset", "act")]
    return bad


@pytest.fixture(scope="module")
def spy_dir(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("spies")
    (folder / "boundary_spy.py").write_text(SPY_MODULE)
    return folder


@pytest.fixture(scope="module")
def task():
    [template] = read_template_file(TEMPLATE)
    return atomic_task(template, 0)


def bench(spy_dir: Path, run_dir: Path, agent: str, *args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(spy_dir))
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist", str(REPO / "tasks"),
           "--results-dir", str(run_dir), "--instances", "1", "-k", TASK, "--agent", agent, *args]
    return subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=600, env=env)


def test_the_spies_find_the_answers_when_handed_them(spy_dir, task, monkeypatch):
    """The walk itself works: handed the subtasks and a device dict, a spy reports them (so an empty report below
    means nothing was there, not a blind walk)."""
    monkeypatch.syspath_prepend(str(spy_dir))
    import boundary_spy

    boundary_spy.RECORD.update(hooks=[], types=set(), strings=set(), walked=0)
    boundary_spy.walk({"context": (tuple(task.formatted_subtasks),)}, lambda: task)
    found = {"hooks": [], "types": sorted(boundary_spy.RECORD["types"]),
             "strings": sorted(boundary_spy.RECORD["strings"])}
    assert any("tasks.model.Subtask" in t for t in found["types"])
    assert len(leaks(found, task)) > 3


@pytest.mark.containers
@pytest.mark.parametrize("spy", ["SubclassSpy", "DuckSpy"])
def test_a_third_party_agent_reaches_no_answer_through_what_it_is_given(device_images, spy_dir, tmp_path, task,
                                                                        spy):
    """A real run of a real task with a spy as the agent: it saw the instruction and the drive's login, and
    nothing of the solution, the near-miss states, the evaluators' arguments or the devices."""
    out = tmp_path / "spy.json"
    proc = bench(spy_dir, tmp_path / "run", f"boundary_spy:{spy}", "--agent-option", f"out={out}")
    [result] = load_results(tmp_path / "run")[0]
    assert result.status == "failed", proc.stdout[-3000:] + proc.stderr[-3000:]  # it did nothing: the agent failed
    assert result.task_id == task.id and result.instruction == task.instruction
    record = json.loads(out.read_text())
    assert leaks(record, task) == []
    assert record["hooks"] == ["reset", "act", "act"] and record["walked"] > 10
    assert task.instruction in record["strings"] and "jarvis_pytest.devices.base.Observation" in record["types"]
    assert "jarvis_pytest.agents.protocol.HistoryEntry" in record["types"]  # its own first step, fed back


@pytest.mark.containers
def test_the_builtin_oracle_still_solves_the_task(device_images, spy_dir, tmp_path, task):
    proc = bench(spy_dir, tmp_path, "oracle")
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    [result] = load_results(tmp_path)[0]
    assert result.task_id == task.id and result.status == "passed"


@pytest.mark.parametrize("spy", ["SubclassSpy", "DuckSpy", "MaskSpy", "Spying"])
def test_brief_hands_the_solution_to_the_builtin_oracle_only(spy_dir, task, monkeypatch, tmp_path, spy):
    """Through the registry, as the harness loads agents: the oracle is briefed; a subclass, a look-alike of its
    class, a class that tells `isinstance` it is one, and a class named "oracle" with `attach_devices` get
    nothing, and their walk finds nothing."""
    monkeypatch.syspath_prepend(str(spy_dir))
    devices = {"ubuntu": object()}
    context = TaskContext(task.id, task.instruction, ("ubuntu",))
    oracle = load_agent("oracle", {})
    oracle.reset(context)
    assert brief(oracle, task.formatted_subtasks, devices) and oracle.queue and oracle.devices == devices

    agent = load_agent(f"boundary_spy:{spy}", {"out": str(tmp_path / "spy.json")})
    assert agent.name == "oracle"
    import boundary_spy

    boundary_spy.RECORD.update(hooks=[], types=set(), strings=set(), walked=0)
    agent.reset(context)
    assert brief(agent, task.formatted_subtasks, devices) is False
    agent.act({}, [])
    record = json.loads((tmp_path / "spy.json").read_text())
    assert leaks(record, task) == [] and "ubuntu" not in getattr(agent, "devices", {})


def test_the_oracle_cannot_be_given_other_methods(task):
    """An adapter's factory may return the real oracle, but cannot swap its methods for ones that read what it is
    handed (slots: an instance has no attributes of its own to put them in). Then it runs as the oracle."""
    oracle = load_agent("oracle", {})
    for method in ("act", "reset", "config"):
        with pytest.raises(AttributeError):
            setattr(oracle, method, lambda *a: None)
    assert not hasattr(oracle, "__dict__") and oracle.config() == {"name": "oracle"}


def test_an_unbriefed_oracle_fails_at_once():
    oracle = OracleAgent()
    oracle.reset(TaskContext("t", "-", ("ubuntu",)))
    step = oracle.act({}, [])
    assert step.action.type == "FAIL" and "no solution" in step.reasoning
