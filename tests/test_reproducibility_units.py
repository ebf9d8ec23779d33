"""Reproducible runs without devices: trials (case ids, result keys, the rollup's pass@K, pass^K and unstable
tasks), the run card (what it compares, what it warns about, the command it replays) and the models' sampling
parameters and seeds, sent on every call to a real HTTP server."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from jarvis_pytest.agents.protocol import TaskContext
from jarvis_pytest.agents.registry import load_agent
from jarvis_pytest.devices.base import Observation
from jarvis_pytest.errors import ConfigError
from jarvis_pytest.llm.fake_server import FakeChatServer, fail
from jarvis_pytest.plugin.cases import TaskCase
from jarvis_pytest.report import run_card
from jarvis_pytest.report.rollup import _pass_k, render_markdown, render_terminal, rollup
from jarvis_pytest.results.model import SubtaskVerdict, TaskResult, result_key, trial_seed
from jarvis_pytest.results.run_state import merge_plan, read_plan
from jarvis_pytest.agents.planner import render_step
from tests.screens import screenshot


def result(task: str, trial: int, passed: bool, status: str | None = None, category: str = "atomic",
           platform: str = "ubuntu", subtasks: int = 1) -> TaskResult:
    return TaskResult(task_id=task, category=category, platforms=[platform], instruction="-", trial=trial,
                      status=status or ("passed" if passed else "failed"),
                      subtasks=[SubtaskVerdict(index=i, template="t", platform=platform, passed=passed or i == 0)
                                for i in range(subtasks)])


# -- trials --------------------------------------------------------------------------------------------------------
def test_trial_cases_share_one_task_and_have_their_own_ids_and_keys():
    made = []
    case = TaskCase("ubuntu-x[seed0]", "atomic", ["ubuntu"], ["App"], 1, lambda: made.append(1) or "the task")
    trials = case.trial_cases(3)
    assert [c.param_id for c in trials] == [f"ubuntu-x[seed0]-trial{n}" for n in (1, 2, 3)]
    assert [c.key for c in trials] == ["ubuntu-x[seed0]", "ubuntu-x[seed0]#trial2", "ubuntu-x[seed0]#trial3"]
    assert {c.task for c in trials} == {"the task"} and made == [1]  # made once, on first use
    assert case.param_id == "ubuntu-x[seed0]"  # one trial: the id is the task's


def test_keys_and_seeds_are_stable_and_differ_per_trial():
    assert result_key("a[seed0]") == "a[seed0]" and result_key("a[seed0]", 2) == "a[seed0]#trial2"
    seeds = [trial_seed("ubuntu-x[seed0]", n) for n in (1, 2, 3)]
    assert len(set(seeds)) == 3 and all(0 <= s < 2**31 for s in seeds)
    assert seeds == [trial_seed("ubuntu-x[seed0]", n) for n in (1, 2, 3)]  # a pure function of task and trial
    assert trial_seed("ubuntu-terminal-count_matches[seed0]", 2) == 1181800656  # recorded by a run on this machine


def test_plan_keeps_trials_apart_and_digests_per_task(tmp_path):
    class T:
        id, category = "ubuntu-x[seed0]", "atomic"

        def to_json(self):
            return {"id": self.id}

    merge_plan(tmp_path, [(result_key(T.id, n), T()) for n in (1, 2, 3)])
    plan = read_plan(tmp_path)
    assert plan["tasks"] == ["ubuntu-x[seed0]", "ubuntu-x[seed0]#trial2", "ubuntu-x[seed0]#trial3"]
    assert set(plan["digests"]) == {"ubuntu-x[seed0]"} and len(plan["categories"]) == 3


def test_pass_at_k_and_pass_all_k_estimators():
    assert _pass_k(3, 1, 3) == (1.0, 0.0) and _pass_k(3, 3, 3) == (1.0, 1.0) and _pass_k(3, 0, 3) == (0.0, 0.0)
    at, every = _pass_k(5, 2, 3)  # 5 trials, 2 passed, K = 3: 1 - C(3,3)/C(5,3), C(2,3)/C(5,3)
    assert math.isclose(at, 0.9) and every == 0.0


def test_rollup_over_trials_gives_the_mean_pass_at_k_pass_all_k_and_unstable_tasks():
    wins = {"a": (1, 1, 1), "b": (0, 1, 0), "c": (1, 1, 0), "d": (0, 0, 0)}
    results = [result(f"ubuntu-{t}[seed0]", n + 1, bool(w)) for t, ws in wins.items() for n, w in enumerate(ws)]
    s = rollup(list(reversed(results)))
    cell = s.trials.cells["atomic/ubuntu"]
    assert s.trials.k == 3 and s.tasks == 4
    assert math.isclose(cell.mean, (1 + 1 / 3 + 2 / 3 + 0) / 4)
    assert cell.pass_at_k == 0.75 and cell.pass_all_k == 0.25 and cell.incomplete == 0
    assert s.trials.unstable == ["ubuntu-b[seed0]", "ubuntu-c[seed0]"]
    assert [(t.task_id, t.passed, t.counted) for t in s.trials.tasks][1] == ("ubuntu-b[seed0]", 1, 3)
    # the main table is the mean over trials; its counts are trials, its interval resamples tasks
    assert math.isclose(s.atomic["ubuntu"].rate, cell.mean) and (s.atomic["ubuntu"].k, s.atomic["ubuntu"].n) == (6, 12)
    terminal = render_terminal(s)
    assert "pass@3" in terminal and "pass^3" in terminal and "unstable tasks (trials disagree): 2" in terminal
    assert "ubuntu-b[seed0] (1/3)" in terminal
    md = render_markdown(s)
    assert "Table 7. 3 trials per task" in md and "| ubuntu-c[seed0] | atomic | 2/3 |" in md
    assert rollup(results).model_dump() == s.model_dump()  # any order, the same summary


def test_a_trial_that_errored_leaves_its_task_out_of_pass_at_k_only():
    results = [result("ubuntu-a[seed0]", 1, True), result("ubuntu-a[seed0]", 2, False, status="error"),
               result("ubuntu-a[seed0]", 3, True), *(result("ubuntu-b[seed0]", n, False) for n in (1, 2, 3))]
    s = rollup(results)
    cell = s.trials.cells["all"]
    assert cell.tasks == 1 and cell.incomplete == 1 and cell.pass_at_k == 0.0 and cell.mean == 0.5
    assert s.errors["atomic"] == 1 and s.trials.unstable == []


def test_one_trial_per_task_has_no_trials_section_and_planned_trials_count_as_not_run():
    s = rollup([result("ubuntu-a[seed0]", 1, True)])
    assert s.trials is None and s.atomic["ubuntu"].n == 1
    s = rollup([result("ubuntu-a[seed0]", 1, True)],
               planned={"ubuntu-a[seed0]": "atomic", "ubuntu-a[seed0]#trial2": "atomic"})
    assert s.not_run["atomic"] == 1 and s.trials.k == 2 and s.trials.cells["all"].incomplete == 1


# -- the run card --------------------------------------------------------------------------------------------------
CARD = {
    "format": 1, "harness": {"version": "0.1.0", "commit": "abc", "dirty": False},
    "agent": {"name": "holo2", "planner": {"base_url": "http://127.0.0.1:1/v1", "model": "qwen3-vl-plus"},
              "planner_params": {"temperature": 0.0, "top_p": 1.0, "max_tokens": 2048}, "seed": "derived",
              "model_input": {"planner": {"encoding": "PNG", "screen": {"ubuntu": [1920, 1080]},
                                          "sent": {"ubuntu": [1920, 1080]}}}},
    "limits": {"max_steps": 50, "step_timeout": 300.0, "task_timeout": 3600.0}, "trials": 1, "workers": 3,
    "instances": 2, "tasks": {"templates_digest": "t1", "planned": 3, "plan_digest": "p1"},
    "devices": {"ubuntu": {"backend": "ubuntu (docker)", "image": "jarvis/ubuntu:latest", "image_ids": ["sha256:aa"],
                           "os": ["Debian 12"], "timezone": "Etc/UTC"},
                "transfer": {"image": "jarvis/transfer:latest", "image_id": "sha256:tt"}},
    "environment": {"egress": False}, "selection": {"argv": ["tasks", "-n", "3"]}, "machine": {"cpus": 2},
}


def changed(card: dict, path: str, value) -> dict:
    card = json.loads(json.dumps(card))
    *parents, last = path.split(".")
    node = card
    for p in parents:
        node = node[p]
    node[last] = value
    return card


def test_a_card_meets_itself_and_names_each_condition_it_does_not():
    here = changed(changed(CARD, "devices.ubuntu.image_ids", []), "devices.ubuntu.image_id", "sha256:aa")
    assert run_card.reproduction_differences(CARD, changed(here, "machine.cpus", 16)) == []  # where, not what
    assert run_card.reproduction_differences(CARD, changed(here, "devices.ubuntu.os", ["other"])) == []  # known later
    found = run_card.reproduction_differences(CARD, changed(changed(here, "limits.max_steps", 30),
                                                            "agent.planner_params.temperature", 0.7))
    assert found == ["agent.planner_params.temperature: the run had 0.0, here 0.7",
                     "limits.max_steps: the run had 50, here 30"]
    other_image = run_card.reproduction_differences(CARD, changed(here, "devices.ubuntu.image_id", "sha256:bb"))
    assert len(other_image) == 1 and other_image[0].startswith("devices.ubuntu: the image jarvis/ubuntu:latest here")
    missing = run_card.reproduction_differences(CARD, changed(here, "devices.ubuntu.image_id", None))
    assert "is not on this machine" in missing[0]
    assert any(d.startswith("harness.commit") for d in
               run_card.reproduction_differences(CARD, changed(here, "harness.commit", "def")))


def test_the_card_warns_about_settings_that_change_scores():
    assert run_card.unusual(CARD) == []
    warnings = run_card.unusual(changed(changed(changed(CARD, "limits.max_steps", 20),
                                                "agent.planner_params.temperature", 0.8), "harness.dirty", True))
    assert any("under the paper's 50" in w for w in warnings)
    assert any("temperature > 0 with one trial" in w for w in warnings)
    assert any("uncommitted changes" in w for w in warnings)
    shot = changed(CARD, "agent.model_input.grounder", {"encoding": "PNG", "screen": {"android": [1080, 2400]},
                                                          "sent": {"android": [728, 1624]}})
    assert any("downscaled" in w and "android 1080x2400 sent as 728x1624" in w for w in run_card.unusual(shot))
    lines = run_card.settings_lines(CARD)
    assert any("temperature=0.0" in line and "seed derived" in line for line in lines)
    assert any("step limit 50" in line for line in lines)


def test_the_replayed_command_drops_where_results_go():
    argv = ["tasks", "--results-dir", "reports/x", "--resume=reports/y", "-n", "3", "--reproduce", "r",
            "--allow-differences", "--agent", "oracle"]
    assert run_card.replay_argv(argv) == ["tasks", "-n", "3", "--agent", "oracle"]


def test_reproduce_replaces_the_selection_and_asks_only_for_keys(tmp_path, monkeypatch):
    from jarvis_pytest.report import reproduce

    card = changed(CARD, "selection.argv", ["tasks", "-k", "calc", "-mubuntu", "--agent", "holo2",
                                            "--planner-api-key", "***", "-n", "3"])
    env = {"JARVIS_PLANNER_API_KEY": "sk-1"}
    cmd, _ = reproduce.command(tmp_path, card, tmp_path / "new", False, env, ask=False)
    assert cmd[3:] == ["tasks", "--agent", "holo2", "-n", "3", "--reproduce", str(tmp_path.resolve()),
                       "--results-dir", str(tmp_path / "new")]
    with pytest.raises(ConfigError, match="JARVIS_PLANNER_API_KEY is not set"):
        reproduce.command(tmp_path, card, tmp_path / "new", True, {}, ask=False)
    monkeypatch.setattr(reproduce.getpass, "getpass", lambda prompt: "typed-key")
    env = {}
    cmd, _ = reproduce.command(tmp_path, card, tmp_path / "new", True, env, ask=True)
    assert env["JARVIS_PLANNER_API_KEY"] == "typed-key" and "typed-key" not in cmd and "--allow-differences" in cmd


# -- models called reproducibly ------------------------------------------------------------------------------------
def _options(server, **more) -> dict:
    return {"planner": {"base_url": server.url, "model": "planner"},
            "grounder": {"base_url": server.url, "model": "grounder"},
            "planner_max_retries": "0", "grounder_max_retries": "0", **more}


def test_sampling_parameters_and_the_trials_seed_go_with_every_call():
    shots = {"ubuntu": Observation("ubuntu", screenshot(1280, 720, [(10, 10, 20, 20)]), 1280, 720)}
    with FakeChatServer() as server:
        server.script(*[render_step("ubuntu", "Click it", {"action": "left_click"}, "the box")] * 2, model="planner")
        server.respond_with(lambda req: "[15, 15]", model="grounder")
        agent = load_agent("holo2", _options(server, planner_temperature="0.6"))
        steps = []
        for trial in (1, 2):
            agent.reset(TaskContext("ubuntu-x[seed0]", "click", ("ubuntu",), trial=trial,
                                    seed=trial_seed("ubuntu-x[seed0]", trial)))
            steps.append(agent.act(shots, []))
        planner = [r.body for r in server.requests_for("planner")]
        grounder = [r.body for r in server.requests_for("grounder")]
        resized = load_agent("ui-tars-1.5", _options(server)).config()["model_input"]["grounder"]["sent"]["ubuntu"]
    assert resized == [1932, 1092]  # an absolute-pixel model gets the screenshot smart-resized
    assert [b["seed"] for b in planner] == [trial_seed("ubuntu-x[seed0]", n) for n in (1, 2)]
    assert [b["seed"] for b in grounder] == [b["seed"] for b in planner]
    assert [s.extra["system_fingerprint"] for s in steps] == ["fp_fake"] * 2  # the server's build, per step
    assert all(b["temperature"] == 0.6 and b["top_p"] == 1.0 and b["max_tokens"] == 2048 for b in planner)
    assert all({"temperature", "top_p", "max_tokens"} <= set(b) for b in grounder)
    config = agent.config()
    assert config["planner_params"] == {"temperature": 0.6, "top_p": 1.0, "max_tokens": 2048}
    assert config["seed"] == "derived" and len(config["prompts"]["planner"]) == 16
    assert config["model_input"]["grounder"]["sent"]["ubuntu"] == [1920, 1080]  # holo2 answers in relative units


def test_seed_none_sends_no_seed_and_a_server_that_refuses_seeds_is_named_at_start():
    shots = {"ubuntu": Observation("ubuntu", screenshot(1280, 720), 1280, 720)}
    with FakeChatServer(models=("planner", "grounder")) as server:
        server.script(render_step("ubuntu", "Type", {"action": "type", "text": "x"}), model="planner")
        agent = load_agent("holo2", _options(server, seed="none"))
        agent.reset(TaskContext("t", "type", ("ubuntu",), trial=1, seed=5))
        agent.act(shots, [])
        assert "seed" not in server.requests_for("planner")[-1].body
        server.probe_reply = fail(400, message="Unrecognized request argument supplied: seed")
        agent = load_agent("holo2", _options(server))
        with pytest.raises(ConfigError) as exc:
            agent.preflight()
        assert "refused the request field 'seed'" in str(exc.value)
        assert "--agent-option seed=none" in str(exc.value)
        with pytest.raises(ConfigError, match="seed 'sometimes'"):
            load_agent("holo2", _options(server, seed="sometimes"))
        with pytest.raises(ConfigError, match="planner_top_p 3.0 is out of range"):
            load_agent("holo2", _options(server, planner_top_p="3"))


def test_the_dashboard_shows_each_cell_over_trials_and_each_tasks_trials():
    from jarvis_pytest.dashboard import stats

    results = [result("ubuntu-a[seed0]", n, n == 2) for n in (1, 2, 3)]
    tables = {t["title"]: t for t in stats.summary(results)["tables"]}
    cells = tables["trials / cells"]
    row = next(r for r in cells["rows"] if r[0] == "atomic/ubuntu")
    assert dict(zip(cells["columns"], row))["pass_at_k"] == "100.0%"
    assert dict(zip(cells["columns"], row))["pass_all_k"] == "0.0%"
    assert tables["trials / tasks"]["rows"] == [["ubuntu-a[seed0]", "atomic", "1", "3"]]


def test_input_files_of_every_composed_task_are_paths_of_their_own_platform():
    """A transfer's inputs live on another device, and a slot's value may be another platform's path: neither is
    asked of the subtask's device (a Windows device refuses a POSIX path as a bad request)."""
    from jarvis_pytest.harness.inputs import input_paths
    from jarvis_pytest.tasks.dataset import load_tasks

    tasks = load_tasks(sorted((Path(__file__).resolve().parents[1] / "tasks" / "composed").glob("*.json")))
    paths = [(p, path) for t in tasks for p, path in input_paths(t.formatted_subtasks)]
    assert len(paths) > 100
    assert all((p == "windows") == (path[1:3] in (":\\", ":/")) for p, path in paths)
    assert all(p == "windows" or path.startswith("/") for p, path in paths)
