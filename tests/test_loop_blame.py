"""An agent's garbage is its own failure, never an infrastructure error (issue 37), probed end to end: each
garbage step goes through `run_loop` on a real Ubuntu device, comes back as that step's error in the trajectory,
and the device carries out the agent's next action as if nothing had happened. Then the whole harness: an agent
that emits garbage and exits ends `failed` (end reason `agent_error`) and stays in the rates."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from jarvis_pytest.agents.protocol import AgentStep
from jarvis_pytest.devices import actions as A
from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.harness.blame import AGENT_CRASH_LIMIT
from jarvis_pytest.harness.loop import LoopLimits, run_loop
from jarvis_pytest.report.rollup import load_results
from jarvis_pytest.results.model import TaskResult
from jarvis_pytest.results.writer import TaskRecorder

pytestmark = pytest.mark.containers
REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def device(ubuntu_env):
    return ubuntu_env.devices["ubuntu"]


class Scripted:
    """An agent adapter that plays its moves: a step, or a callable (its code) that returns or raises one."""

    name = "scripted"

    def __init__(self, moves):
        self.moves = list(moves)
        self.histories = []

    def reset(self, task):
        pass

    def config(self):
        return {"name": self.name}

    def act(self, observations, history):
        self.histories.append(history)
        move = self.moves.pop(0)
        return move() if callable(move) else move


def run(agent, device, tmp_path: Path, **limits):
    """`run_loop` of `agent` on `device`; its outcome and the trajectory as written."""
    result = TaskResult(task_id="probe", category="atomic", platforms=["ubuntu"], instruction="probe",
                        status="running")
    recorder = TaskRecorder(tmp_path, result)
    try:
        out = run_loop(agent, {"ubuntu": device}, {}, recorder, LoopLimits(**limits))
    finally:
        recorder.finish()
    steps = [json.loads(line) for line in (recorder.dir / "traj.jsonl").read_text(encoding="utf-8").splitlines()]
    return out, steps


def move(x: int) -> AgentStep:
    return AgentStep(platform="ubuntu", action=A.MoveTo(x=x, y=300))


def raises(exc: BaseException):
    def code():
        raise exc
    return code


def built(cls, **fields):
    """An action an adapter built without validation (`model_construct`), as a careless adapter may."""
    return cls.model_construct(**fields)


class Booby(AgentStep):
    """A step whose token counts raise when read."""

    def __getattribute__(self, name):
        if name == "usage":
            raise RuntimeError("booby-trapped usage")
        return super().__getattribute__(name)


class Sly(str):
    """A string whose own methods raise."""

    def __str__(self):
        raise RuntimeError("sly")

    def splitlines(self, *a):
        raise RuntimeError("sly")


def deep(n: int) -> list:
    nest: list = []
    for _ in range(n):
        nest = [nest]
    return nest


GARBAGE = {  # name → (the agent's move, words in its step's error)
    "nan scroll": (AgentStep("ubuntu", built(A.Scroll, dy=float("nan"))), "SCROLL.dy: Input should be a finite"),
    "nan scroll in the adapter": (lambda: AgentStep("ubuntu", A.Scroll(dy=float("nan"))), "agent error"),
    "infinite coordinate": (AgentStep("ubuntu", built(A.Click, x=float("inf"), y=10)), "CLICK.x"),
    "infinite coordinate in the adapter": (lambda: AgentStep("ubuntu", A.Click(x=round(float("inf")), y=1)),
                                           "agent error: OverflowError"),
    "huge coordinate": (AgentStep("ubuntu", {"type": "CLICK", "x": 1e300, "y": 1}), "CLICK.x"),
    "lone surrogate typed": (AgentStep("ubuntu", built(A.Typing, text="a\ud800b")), "lone surrogate (U+D800)"),
    "a million characters": (AgentStep("ubuntu", built(A.Typing, text="x" * 1_000_000)),
                             "at most 10000 characters"),
    "scroll of 1e9": (AgentStep("ubuntu", {"type": "SCROLL", "dy": 1e9}), "less than or equal to 100"),
    "scroll of 1e9, built": (AgentStep("ubuntu", built(A.Scroll, dx=0, dy=10 ** 9)), "less than or equal to 100"),
    "script exits": (AgentStep("ubuntu", A.Pyautogui(script="import sys\nsys.exit(3)")),
                     "the script exited the interpreter (sys.exit(3))"),
    "script ends its interpreter": (AgentStep("ubuntu", A.Pyautogui(script="import os\nos._exit(0)")),
                                    "ended its interpreter (exit status 0)"),
    "script crashes its interpreter": (AgentStep("ubuntu", A.Pyautogui(script="import ctypes\nctypes.string_at(0)")),
                                       "ended its interpreter (exit status -11)"),
    "script raises": (AgentStep("ubuntu", A.Pyautogui(script="pyautogui.nosuchcall()")), "AttributeError"),
    "adapter raises": (raises(ValueError("the model said 'click the thing'")), "agent error: ValueError"),
    "adapter returns None": (lambda: None, "returned NoneType, not an AgentStep"),
    "adapter returns a dict": (lambda: {"type": "DONE"}, "returned dict, not an AgentStep"),
    # held-out garbage, as an adversary would try it
    "negative duration": (AgentStep("ubuntu", built(A.LongPress, x=5, y=5, duration=-5)), "duration"),
    "huge key combo": (AgentStep("ubuntu", built(A.Hotkey, keys=["a"] * 5000)), "at most 16 items"),
    "empty key": (AgentStep("ubuntu", built(A.KeyDown, key="")), "at least 1 character"),
    "empty hotkey": (AgentStep("ubuntu", {"type": "HOTKEY", "keys": []}), "HOTKEY.keys"),
    "bool for int": (AgentStep("ubuntu", {"type": "CLICK", "x": True, "y": 1}), "not a boolean"),
    "string for action": (AgentStep("ubuntu", "CLICK 10 10"), "not str"),
    "platform as list": (AgentStep(["ubuntu"], A.MoveTo(x=1, y=1)), "device unavailable"),
    "unknown platform": (AgentStep("ubuntu\ud800", A.MoveTo(x=1, y=1)), "device unavailable"),
    "off-screen click": (AgentStep("ubuntu", A.Click(x=32_000, y=10)), "off the"),
    "a step whose fields raise": (Booby("ubuntu", A.MoveTo(x=1, y=1)), "agent error: RuntimeError: booby-trapped"),
}


@pytest.mark.parametrize("name", list(GARBAGE))
def test_garbage_is_the_agents_step_error_and_the_device_answers_after_it(device, tmp_path, name):
    garbage, words = GARBAGE[name]
    agent = Scripted([garbage, move(400), AgentStep(platform=None, action=A.Done())])
    t0 = time.monotonic()
    out, steps = run(agent, device, tmp_path)
    assert out.end_reason == "done" and out.steps == 3, (out, steps[0]["error"])
    assert steps[0]["error"] and words in steps[0]["error"], steps[0]["error"]
    assert steps[1]["error"] is None and steps[1]["action"] == {"type": "MOVE_TO", "x": 400, "y": 300}
    assert words in agent.histories[1][0].error  # fed back to the agent
    print(f"{name}: {steps[0]['error'][:100]!r} ({time.monotonic() - t0:.2f} s for the three steps)")


def test_a_script_that_sleeps_is_stopped_and_the_device_answers_after_it(device, tmp_path):
    agent = Scripted([AgentStep("ubuntu", A.Pyautogui(script="import time\ntime.sleep(3600)")), move(410),
                      AgentStep(platform=None, action=A.Done())])
    t0 = time.monotonic()
    out, steps = run(agent, device, tmp_path)
    elapsed = time.monotonic() - t0
    assert out.end_reason == "done", steps
    assert "ran past its 20 s limit and was stopped" in steps[0]["error"]
    assert steps[1]["error"] is None
    print(f"a sleeping script: stopped, loop of three steps took {elapsed:.1f} s")


def test_garbage_in_what_the_agent_says_is_recorded_not_fatal(device, tmp_path):
    """Lone surrogates in the plan and the raw answer, token counts that are no numbers, extra facts that are no
    JSON (an object, a 100,000-deep nesting): the step goes through and traj.jsonl and result.json stay JSON."""
    odd = AgentStep(platform="ubuntu", action=A.MoveTo(x=20, y=20), reasoning="plan \ud800 first\nsecond",
                    raw_output="raw \udfff", usage={"prompt_tokens": "many", "completion_tokens": float("nan"),
                                                    "total_tokens": 7, "negative": -1},
                    extra={"nest": deep(100_000)})
    also = AgentStep(platform="ubuntu", action=A.MoveTo(x=30, y=30), extra={"thing": object(), "ok": 1},
                     reasoning=Sly("sly plan"), raw_output=Sly("sly"))
    out, steps = run(Scripted([odd, also, AgentStep(None, A.Done())]), device, tmp_path)
    assert out.end_reason == "done" and [s["error"] for s in steps] == [None, None, None]
    assert steps[0]["reasoning"] == "plan \\ud800 first\nsecond" and steps[0]["raw_output"] == "raw \\udfff"
    assert steps[0]["usage"] == {"total_tokens": 7} and out.usage == {"total_tokens": 7}
    assert "not JSON" in steps[0]["extra"]["unrecorded"]
    assert steps[1]["extra"]["ok"] == 1 and steps[1]["extra"]["thing"].startswith("<object object")
    assert steps[1]["reasoning"] == "sly plan"
    result = json.loads((tmp_path / "tasks" / "probe" / "result.json").read_text(encoding="utf-8"))
    assert result["task_id"] == "probe"


def test_an_agent_that_exits_ends_the_task_as_its_failure(device, tmp_path):
    out, steps = run(Scripted([move(50), raises(SystemExit(0)), move(60)]), device, tmp_path)
    assert out.end_reason == "agent_error" and out.steps == 2
    assert "the agent's code ended its own turn: SystemExit: 0" in steps[1]["error"]


def test_an_agent_that_keeps_crashing_ends_the_task_as_its_failure(device, tmp_path):
    crashes = [raises(KeyError("tool"))] * AGENT_CRASH_LIMIT
    out, steps = run(Scripted([raises(KeyError("x")), move(70), *crashes, move(80)]), device, tmp_path)
    assert out.end_reason == "agent_error" and out.steps == 2 + AGENT_CRASH_LIMIT
    assert steps[1]["error"] is None  # a crash, then a good step: the count starts again
    assert f"raised on {AGENT_CRASH_LIMIT} steps in a row" in steps[-1]["error"]


def test_the_model_endpoint_failing_stays_an_infrastructure_error(device, tmp_path):
    failing = raises(InfrastructureError("http://127.0.0.1:9/v1 (model m) failed after 5 attempt(s)"))
    with pytest.raises(InfrastructureError, match="failed after 5"):
        run(Scripted([move(90), failing]), device, tmp_path)
    with pytest.raises(ConnectionRefusedError):  # a third-party client's own network error: the endpoint's
        run(Scripted([raises(ConnectionRefusedError(111, "Connection refused"))]), device, tmp_path / "b")


def test_the_longest_text_is_typed_or_cut_within_the_devices_answer_time(device, tmp_path):
    """The longest TYPING the action space takes (10,000 characters), of which 2,000 distinct characters the
    keyboard map lacks (each bound to a spare keycode first): the device types what fits its 20 s for an action and
    refuses the rest in words, within the harness's 30 s wait; it answers the next action. Prints the times."""
    for text in [("abc def\n" * 1250)[:A.MAX_TEXT],
                 ("".join(chr(0x4E00 + i) for i in range(2000)) + "abc def\n" * 1000)[:A.MAX_TEXT]]:
        t0 = time.monotonic()
        outcome = device.act(A.Typing(text=text))
        elapsed = time.monotonic() - t0
        assert outcome.ok or "the rest did not fit the 20 s one action may take" in outcome.error, outcome.error
        assert elapsed < 25, elapsed
        assert device.act(A.MoveTo(x=10, y=10)).ok
        print(f"TYPING of {len(text)} characters ({len(set(text))} distinct): {elapsed:.1f} s, "
              f"{'typed' if outcome.ok else outcome.error}")


def _run_one_task(tmp_path: Path, agent: str):
    """One `pytest tasks` run of thunar-rename_file with `agent` (from tests/data/agents): its result and output."""
    env = dict(os.environ, PYTHONPATH=str(REPO / "tests" / "data" / "agents"))
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist", str(REPO / "tasks"),
           "--results-dir", str(tmp_path), "--instances", "1", "-k", "thunar-rename_file", "--agent", agent]
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=600, env=env)
    (result,) = load_results(tmp_path)[0]
    return result, proc.stdout + proc.stderr


def test_the_whole_harness_counts_an_agents_exit_as_its_failure(device_images, tmp_path):
    """`pytest tasks --agent garbage_agent:GarbageAgent`: garbage on every step, then `sys.exit()` in the adapter.
    The task is `failed` with end reason `agent_error`, counted in TSR (n = 1) and not among the errors."""
    result, out = _run_one_task(tmp_path, "garbage_agent:GarbageAgent")
    assert result.status == "failed" and result.end_reason == "agent_error", out[-3000:]
    assert result.failure_mode == "agent error" and result.error is None
    traj = [json.loads(line) for line in next(tmp_path.glob("tasks/*/traj.jsonl")).read_text().splitlines()]
    assert all(step["error"] for step in traj), traj
    assert "SystemExit" in traj[-1]["error"]
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["atomic"]["overall"]["n"] == 1 and summary["atomic"]["overall"]["k"] == 0
    assert summary["errors"]["atomic"] == 0
    assert summary["failure_modes"]["atomic"] == {"agent error": 1}


def test_another_clients_timeout_at_the_task_deadline_is_the_deadlines(device, tmp_path):
    """A third-party model client that gives up with its own TimeoutError as the task's time runs out: the task
    ends as a `timeout`, as it does when the project's own client gives up there."""
    def slow():
        time.sleep(1.0)
        raise TimeoutError("read timed out")
    out, steps = run(Scripted([slow]), device, tmp_path, task_timeout=1.0)
    assert out.end_reason == "timeout" and "time limit (1 s) passed" in steps[0]["error"], steps


def test_an_agent_whose_reset_raises_fails_the_task_in_the_rates(device_images, tmp_path):
    """An adapter whose `reset()` raises used to end the task as `error`, out of the rates; now the task is
    `failed` with end reason `agent_error`, judged on the untouched devices, and the devices are given back."""
    result, out = _run_one_task(tmp_path, "garbage_agent:ResetRaises")
    assert result.status == "failed" and result.end_reason == "agent_error", out[-3000:]
    assert result.error is None and result.steps == 1
    (step,) = [json.loads(line) for line in next(tmp_path.glob("tasks/*/traj.jsonl")).read_text().splitlines()]
    assert "reset() failed" in step["error"] and "KeyError" in step["error"]
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["atomic"]["overall"]["n"] == 1 and summary["errors"]["atomic"] == 0


class _SlowReset:
    name = "slow"

    def reset(self, task):
        time.sleep(30)

    def act(self, observations, history):  # pragma: no cover - never reached
        raise AssertionError

    def config(self):
        return {"name": self.name}


class _RaisingReset(_SlowReset):
    def reset(self, task):
        raise SystemExit("gave up")


def test_begin_bounds_the_agents_reset():
    """`begin`: a reset that raises is the agent's failure (a message, no exception); one that does not end within
    the step time limit is the endpoint's (raises StepDeadline, an infrastructure error) and never hangs the run."""
    from jarvis_pytest.agents.protocol import TaskContext
    from jarvis_pytest.harness.loop import LoopLimits, StepDeadline, begin

    context = TaskContext(task_id="t", instruction="i", platforms=("ubuntu",))
    assert "SystemExit" in begin(_RaisingReset(), context, LoopLimits(step_timeout=5))
    t0 = time.monotonic()
    with pytest.raises(StepDeadline, match="reset"):
        begin(_SlowReset(), context, LoopLimits(step_timeout=0.5))
    assert time.monotonic() - t0 < 10
