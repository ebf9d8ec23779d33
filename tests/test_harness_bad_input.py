"""Bad input, as a new user gives it: each case is one clear error at start-up, naming the option, file or field
and the fix, with the exit code of a usage error and never a Python traceback. Nothing boots for any of them."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from jarvis_pytest.llm.fake_server import FakeChatServer

REPO = Path(__file__).resolve().parents[1]
USAGE = 4  # pytest's exit code for a usage error
TEMPLATE = json.loads((REPO / "tasks" / "ubuntu" / "thunar_rename_file.json").read_text())


def run_pytest(*args: str, cwd: Path = REPO, env: dict | None = None) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist", "-q", *args]
    return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=120,
                          env={**os.environ, **(env or {})})


def run_jarvis(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", *args], cwd=REPO, capture_output=True,
                          text=True, timeout=120)


def library_with(root: Path, template: dict) -> Path:
    (root / "ubuntu").mkdir(parents=True)
    (root / "ubuntu" / "t.json").write_text(json.dumps(template))
    return root


def a_run(root: Path, agent_key: str = "0000000000000000", **meta) -> Path:
    """A finished run directory as the harness writes it."""
    root.mkdir(parents=True)
    data = {"format": "jarvis-pytest run", "run_id": root.name, "state": "finished", "agent": {"name": "oracle"},
            "agent_key": agent_key, "pid": 1, "host": "elsewhere", "sessions": [], **meta}
    (root / "run.json").write_text(json.dumps(data))
    (root / "plan.json").write_text(json.dumps({"tasks": [], "categories": {}, "digests": {}}))
    return root


def case_file(tmp: Path) -> tuple[list[str], list[str]]:
    f = tmp / "a_file"
    f.write_text("x")
    return ["--agent", "noop", "--results-dir", str(f)], ["--results-dir", "names a file", str(f)]


def case_not_a_run(tmp: Path):
    (tmp / "some_folder").mkdir()
    return ["--agent", "noop", "--resume", str(tmp / "some_folder")], ["--resume", "not a run directory"]


def case_other_agent(tmp: Path):
    run = a_run(tmp / "run")
    return ["--agent", "noop", "--resume", str(run)], ["--resume", "the run was made with agent", "oracle"]


def case_live_run(tmp: Path):
    import socket

    run = a_run(tmp / "run", state="running", pid=os.getppid(), host=socket.gethostname())
    return ["--agent", "noop", "--resume", str(run)], ["--resume", "still going"]


def case_changed_task(tmp: Path):
    from jarvis_pytest.harness.runner import agent_key
    from jarvis_pytest.harness.loop import LoopLimits

    from jarvis_pytest.results.model import TaskResult
    from jarvis_pytest.results.writer import task_dir

    key = agent_key({"name": "noop"}, LoopLimits())
    run = a_run(tmp / "run", agent_key=key)
    tid = "ubuntu-thunar-rename_file[seed0]"
    (run / "plan.json").write_text(json.dumps({"tasks": [tid], "categories": {tid: "atomic"},
                                                "digests": {tid: "0123456789abcdef"}}))
    verdict = TaskResult(task_id=tid, category="atomic", platforms=["ubuntu"], instruction="x", status="failed",
                         agent={"name": "noop"}, agent_key=key)  # a verdict --resume would keep
    task_dir(run, tid).mkdir(parents=True)
    (task_dir(run, tid) / "result.json").write_text(verdict.model_dump_json())
    return ["--agent", "noop", "--resume", str(run)], ["--resume", "tasks with a result changed", tid]


def case_unknown_evaluator(tmp: Path):
    lib = library_with(tmp / "lib", dict(TEMPLATE, evaluate=[{"func": "no_such_check", "args": {}}]))
    return ["--agent", "noop", "--library", str(lib)], ["t.json", "evaluate[0].func", "no_such_check"]


def case_misspelt_evaluator_argument(tmp: Path):
    evaluate = [dict(spec, args={("pathh" if k == "path" else k): v for k, v in spec["args"].items()})
                for spec in TEMPLATE["evaluate"]]
    lib = library_with(tmp / "lib", dict(TEMPLATE, evaluate=evaluate))
    return ["--agent", "noop", "--library", str(lib)], ["t.json", "evaluate[0].args.pathh", "did you mean `path`?"]


def case_host_fixture(tmp: Path):
    bad = dict(TEMPLATE, config=[{"type": "upload_file", "path": "/home/user/x", "fixture": "/etc/passwd"}])
    lib = library_with(tmp / "lib", bad)
    return ["--agent", "noop", "--library", str(lib)], ["t.json", "config[0]", "fixtures/files"]


def case_upload_outside(tmp: Path):
    bad = dict(TEMPLATE, config=[{"type": "upload_file", "path": "/etc/cron.d/x", "content": "x"}])
    lib = library_with(tmp / "lib", bad)
    return ["--agent", "noop", "--library", str(lib)], ["t.json", "config[0].path", "not where a task may write"]


def case_bad_json_dataset(tmp: Path):
    f = tmp / "d.json"
    f.write_text("{not json")
    return ["--agent", "noop", "--dataset", str(f)], ["d.json", "not valid JSON"]


def case_dataset_unknown_evaluator(tmp: Path):
    from jarvis_pytest.tasks.instances import atomic_instances
    from jarvis_pytest.tasks.library import load_library

    task = next(t.to_json() for t in atomic_instances(load_library(REPO / "tasks"), 1)
                if t.id.startswith("ubuntu-thunar-rename_file"))
    task = dict(task, id="x1", category="sw")
    task["formatted_subtasks"] = [dict(task["formatted_subtasks"][0], evaluate=[{"func": "nope", "args": {}}])] * 2
    task["edges"] = []
    f = tmp / "d.json"
    f.write_text(json.dumps({"tasks": [task]}))
    return ["--agent", "noop", "--dataset", str(f)], ["d.json", "evaluate[0].func", "nope"]


def case_dataset_misspelt_argument(tmp: Path):
    from jarvis_pytest.tasks.instances import atomic_instances
    from jarvis_pytest.tasks.library import load_library

    task = next(t.to_json() for t in atomic_instances(load_library(REPO / "tasks"), 1)
                if t.id.startswith("ubuntu-thunar-rename_file"))
    task = dict(task, id="x1", category="sw", edges=[])
    sub = task["formatted_subtasks"][0]
    evaluate = [dict(sub["evaluate"][0], args={("pathh" if k == "path" else k): v
                                               for k, v in sub["evaluate"][0]["args"].items()})]
    task["formatted_subtasks"] = [sub, dict(sub, evaluate=evaluate)]
    f = tmp / "d.json"
    f.write_text(json.dumps({"tasks": [task]}))
    return ["--agent", "noop", "--dataset", str(f)], ["d.json", "'x1'", "formatted_subtasks[1].evaluate[0].args.pathh",
                                                      "did you mean `path`?"]


CASES = {
    "device-memory": (["--agent", "noop", "--device-memory", "bogus"], ["--device-memory", "4g"]),
    "device-cpus": (["--agent", "noop", "--device-cpus", "-2"], ["--device-cpus", "positive"]),
    "prewarm-reserve-mb": (["--agent", "noop", "--prewarm-reserve-mb", "lots"], ["--prewarm-reserve-mb", "MB"]),
    "task-timeout": (["--agent", "noop", "--task-timeout", "-5"], ["--task-timeout", "positive"]),
    "step-timeout": (["--agent", "noop", "--step-timeout", "0"], ["--step-timeout", "positive"]),
    "instances": (["--agent", "noop", "--instances", "0"], ["--instances", "1 or more"]),
    "max-steps": (["--agent", "noop", "--max-steps", "zero"], ["--max-steps", "whole number"]),
    "agent-option": (["--agent", "noop", "--agent-option", "novalue"], ["--agent-option", "KEY=VALUE"]),
    "unknown agent": (["--agent", "no_such_agent"], ["--agent no_such_agent"]),
    "qc with agent": (["--qc", "--agent", "noop"], ["--agent", "--qc"]),
    "windows backend": (["--agent", "noop", "--windows-backend", "vmware"], ["--windows-backend", "wine"]),
    "missing dataset": (["--agent", "noop", "--dataset", "/nonexistent/d.json"], ["--dataset", "no such dataset"]),
    "missing library": (["--agent", "noop", "--library", "/nonexistent/lib"], ["--library", "no such library"]),
    "missing resume": (["--agent", "noop", "--resume", "/nonexistent/run"], ["--resume", "no such run"]),
    "results-dir is a file": case_file,
    "resume a folder that is no run": case_not_a_run,
    "resume with another agent": case_other_agent,
    "resume a live run": case_live_run,
    "resume with changed tasks": case_changed_task,
    "unknown evaluator": case_unknown_evaluator,
    "misspelt evaluator argument": case_misspelt_evaluator_argument,
    "host file as fixture": case_host_fixture,
    "upload outside the home": case_upload_outside,
    "dataset not JSON": case_bad_json_dataset,
    "dataset with unknown evaluator": case_dataset_unknown_evaluator,
    "dataset with a misspelt evaluator argument": case_dataset_misspelt_argument,
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_bad_input_is_one_clear_usage_error(name, tmp_path):
    case = CASES[name]
    args, expected = case(tmp_path) if callable(case) else case
    proc = run_pytest("tasks", *args, "--results-dir" if "--results-dir" not in args and "--resume" not in args
                      else "--maxfail", str(tmp_path / "out") if "--results-dir" not in args and "--resume" not in args
                      else "1")
    out = proc.stdout + proc.stderr
    assert proc.returncode == USAGE, out[-3000:]
    assert "Traceback" not in out and "INTERNALERROR" not in out, out[-3000:]
    for text in expected:
        assert text in out, f"{text!r} not in:\n{out[-3000:]}"
    assert not list(tmp_path.glob("out/tasks")), "nothing may run"


def test_model_endpoint_problems_are_found_before_any_device_boots(tmp_path):
    """One real one-token request per model at start-up: an unreachable endpoint, a wrong key and a wrong model
    name each give one clear error naming the option (not one error per task after its devices booted)."""
    with FakeChatServer(api_key="sk-right", models=("planner", "grounder")) as fake:
        base = ["tasks", "--agent", "holo2", "--planner-base-url", fake.url, "--grounder-base-url", fake.url,
                "--grounder-model", "grounder", "--results-dir", str(tmp_path / "out")]
        wrong_key = run_pytest(*base, "--planner-model", "planner", "--planner-api-key", "sk-wrong",
                               "--grounder-api-key", "sk-right")
        wrong_model = run_pytest(*base, "--planner-model", "plannr", "--planner-api-key", "sk-right",
                                 "--grounder-api-key", "sk-right")
        right = run_pytest(*base, "--planner-model", "planner", "--planner-api-key", "sk-right",
                           "--grounder-api-key", "sk-right", "--collect-only")
    unreachable = run_pytest("tasks", "--agent", "holo2", "--planner-base-url", "http://127.0.0.1:9/v1",
                             "--planner-model", "p", "--grounder-base-url", "http://127.0.0.1:9/v1",
                             "--grounder-model", "g", "--results-dir", str(tmp_path / "out"))
    for proc, words in ((wrong_key, ["--planner-api-key", "refused the API key"]),
                        (wrong_model, ["--planner-model", "does not serve model 'plannr'"]),
                        (unreachable, ["--planner-base-url", "unreachable"])):
        out = proc.stdout + proc.stderr
        assert proc.returncode == USAGE and "Traceback" not in out, out[-2000:]
        assert all(w in out for w in words), out[-2000:]
    assert right.returncode == 0, (right.stdout + right.stderr)[-2000:]


@pytest.mark.parametrize("args, words", [
    (["images", "build", "--only", "no_such_image"], ["--only", "no_such_image"]),
    (["templates", "--library", "/nonexistent"], ["no such library"]),
    (["compose", "--library", "/nonexistent", "--seed", "0", "--count", "1", "--out", "/tmp/x.json"], ["no such library"]),
    (["qc", "--instances", "0"], ["--instances", "1 or more"]),
])
def test_jarvis_command_bad_input_is_one_line(args, words):
    proc = run_jarvis(*args)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 2 and "Traceback" not in out, out[-2000:]
    assert all(w in out for w in words), out


def test_collect_only_creates_no_run(tmp_path):
    proc = run_pytest("tasks", "--agent", "noop", "--collect-only", "--results-dir", str(tmp_path / "run"))
    assert proc.returncode == 0, proc.stdout[-2000:]
    assert not (tmp_path / "run" / "run.json").exists() and not (tmp_path / "run" / "plan.json").exists()


def test_no_path_with_workers_selects_exactly_the_benchmark(tmp_path):
    """`pytest -n 2 --agent noop` with no path (and a path-valued option, which once made pytest miss the
    project's configuration) selects the cases of `pytest tasks`, never the project's own tests, with no
    unknown-marker warning — in the controller and in the xdist workers."""
    def collected(*args: str) -> tuple[list[str], str]:
        cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "--collect-only", "-q", "--agent", "noop",
               "--results-dir", str(tmp_path / "r"), *args]
        proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=120)
        return sorted(l for l in proc.stdout.splitlines() if "::" in l), proc.stdout + proc.stderr

    plain, _ = collected("tasks")
    no_path, out = collected()
    assert plain and no_path == plain, out[-2000:]
    # the workers: a unit test's name selects nothing (it once ran and "passed" as a benchmark case)
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-n", "2", "--agent", "noop",
           "-k", "test_answer_usage_and_request_shape", "--results-dir", str(tmp_path / "w")]
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=300)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 5 and "no tests ran" in out, out[-3000:]
    assert "PytestUnknownMarkWarning" not in out and "Unknown pytest.mark" not in out, out[-3000:]
