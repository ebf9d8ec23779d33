"""A model agent through the real harness on a real Ubuntu task: a scripted planner and a Holo2-format grounder
behind a loopback OpenAI-compatible server; a malformed planner answer becomes an error step; `replay`
replays the recorded trajectory to the same verdict."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from jarvis_pytest.agents.planner import render_step
from jarvis_pytest.llm.fake_server import FakeChatServer
from jarvis_pytest.report.rollup import load_results
from jarvis_pytest.tasks.instances import atomic_instances
from jarvis_pytest.tasks.library import load_library

pytestmark = pytest.mark.containers
REPO = Path(__file__).resolve().parents[1]
TASK = "ubuntu-mousepad-write_note[seed0]"


def bench(run_dir: Path, *args: str) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist", str(REPO / "tasks"),
           "--results-dir", str(run_dir), "--instances", "1", "-k", "mousepad-write_note", *args]
    return subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=300)


def steps(run_dir: Path) -> list[dict]:
    return [json.loads(l) for l in (run_dir / "tasks" / "ubuntu-mousepad-write_note_seed0" / "traj.jsonl")
            .read_text().splitlines()]


@pytest.fixture(scope="module")
def model_run(device_images, tmp_path_factory):
    task = next(t for t in atomic_instances(load_library(REPO / "tasks"), 1) if t.id == TASK)
    text = task.formatted_subtasks[0].input["note_text"].value
    fake = FakeChatServer(models=("planner", "grounder"))
    fake.script(
        "I would type the note now.",  # no <step>: must come back as an error step, not a crash
        render_step("ubuntu", "Click into the editor", {"action": "left_click"}, "the text area of the editor"),
        render_step("ubuntu", "Type the note", {"action": "type", "text": text}),
        render_step("ubuntu", "Save the file", {"action": "key", "keys": ["ctrl", "s"]}),
        render_step("ubuntu", "The note is saved", {"action": "terminate", "status": "success"}),
        model="planner")
    fake.script('{"x": 500, "y": 500}', model="grounder")  # the middle of the screen: the editor's text area
    run_dir = tmp_path_factory.mktemp("holo2")
    with fake:
        proc = bench(run_dir, "--agent", "holo2", "--planner-base-url", fake.url, "--planner-model", "planner",
                     "--grounder-base-url", fake.url, "--grounder-model", "grounder",
                     "--planner-api-key", "sk-secret-never-written")
        probes = [r for r in fake.requests if isinstance(r.body, dict) and r.body.get("max_tokens") == 1]
        grounder_requests = [r for r in fake.requests_for("grounder") if r not in probes]
        prompt = [r for r in fake.requests_for("planner") if r not in probes][0].text()
    assert sorted(r.model for r in probes) == ["grounder", "planner"]  # one start-up probe per model
    assert "copyparty" in prompt and "http://transfer:5244" in prompt and "/data" in prompt  # the real drive
    return run_dir, proc, grounder_requests


def test_scripted_model_solves_a_real_task(model_run):
    run_dir, proc, grounder_requests = model_run
    assert proc.returncode == 0, proc.stdout[-4000:]
    (result,) = load_results(run_dir)[0]
    assert result.status == "passed" and result.end_reason == "done"
    assert grounder_requests and grounder_requests[0].image_sizes() == [(1920, 1080)]


def test_malformed_answer_is_an_error_step(model_run):
    run_dir, _, _ = model_run
    first, click = steps(run_dir)[:2]
    assert first["action"] is None and "action not found" in first["error"]
    assert click["action"] == {"type": "CLICK", "x": 960, "y": 540, "button": "left", "clicks": 1}
    assert click["error"] is None


def test_api_keys_are_not_written(model_run):
    run_dir, _, _ = model_run
    for path in run_dir.rglob("*"):
        if path.is_file() and path.suffix in (".json", ".jsonl", ".html", ".md"):
            assert "sk-secret-never-written" not in path.read_text(errors="replace"), path


def test_replay_reproduces_the_run(model_run, tmp_path):
    run_dir, _, _ = model_run
    traj = run_dir / "tasks" / "ubuntu-mousepad-write_note_seed0" / "traj.jsonl"
    proc = bench(tmp_path, "--agent", "replay", "--agent-option", f"file={traj}")
    assert proc.returncode == 0, proc.stdout[-3000:]
    assert [s["action"]["type"] for s in steps(tmp_path)] == ["CLICK", "TYPING", "HOTKEY", "DONE"]
