"""The dashboard's server without a browser: the JSON API over a results directory, robustness to bad files,
path traversal refused (raw HTTP against 127.0.0.1), and the two ways to start it."""

from __future__ import annotations

import argparse
import http.client
import json
import os
import subprocess
import sys
from pathlib import Path

import httpx
import pytest

from jarvis_pytest.dashboard import commands, sample
from jarvis_pytest.dashboard.server import serving
from jarvis_pytest.results.writer import safe_name

REPO = Path(__file__).resolve().parents[1]
SECRET = "top-secret-outside-the-results"


@pytest.fixture(scope="module")
def results(tmp_path_factory) -> Path:
    """A finished run, a run in progress, a damaged copy, and traps: a secret file next to the results root and
    symlinks inside it that point at the secret."""
    base = tmp_path_factory.mktemp("dash")
    (base / "secret.txt").write_text(SECRET)
    root = base / "results"
    sample.write_finished_run(root)
    sample.write_live_run(root)
    damaged = sample.write_finished_run(root, "20250103-100000-cccccc")
    (damaged / "tasks" / safe_name("ubuntu-calc-sum[seed0]") / "result.json").write_text('{"task_id": "ubu')
    with open(damaged / "tasks" / safe_name("md-photo-to-doc[seed1]") / "traj.jsonl", "a") as f:
        f.write('{"index": 5, "platform": "ubuntu", "act')
    (damaged / "plan.json").write_text("[not json")
    (root / sample.FINISHED_RUN / "tasks" / safe_name("ubuntu-calc-sum[seed0]") / "evil.png").symlink_to(base / "secret.txt")
    (root / "escape").symlink_to(base, target_is_directory=True)
    outside_run = sample.write_finished_run(base, "outside-run")
    (root / "linked-run").symlink_to(outside_run, target_is_directory=True)
    (root / sample.LIVE_RUN / "tasks" / "linked-task").symlink_to(outside_run / "tasks" / safe_name("ubuntu-calc-sum[seed0]"))
    return root


@pytest.fixture(scope="module")
def base_url(results):
    with serving(results) as server:
        host, port = server.server_address[:2]
        yield f"http://{host}:{port}"


def raw_get(base_url: str, path: str) -> tuple[int, bytes]:
    """GET with the request target sent exactly as given (no client-side `..` normalisation)."""
    host, port = base_url.removeprefix("http://").split(":")
    conn = http.client.HTTPConnection(host, int(port), timeout=10)
    try:
        conn.request("GET", path)
        resp = conn.getresponse()
        return resp.status, resp.read()
    finally:
        conn.close()


# -- path traversal ---------------------------------------------------------------------------------------------

LITERAL = ["/files/../../etc/passwd", "/files/../secret.txt", "/../secret.txt", "/files/./../secret.txt",
           "/api/runs/../tasks/x", "/files/x/..", "/files//etc/passwd", "/files/..\\secret.txt",
           f"/files/{sample.FINISHED_RUN}/tasks/../../../secret.txt"]
ENCODED = ["/files/%2e%2e/%2e%2e/etc/passwd", "/files/%2E%2E/secret.txt", "/files/..%2f..%2fetc%2fpasswd",
           "/files/%2Fetc%2Fpasswd", "/files/%2e%2e%5csecret.txt", "/files/C:%5CWindows%5Cwin.ini",
           "/api/runs/%2e%2e", "/api/runs/%2e%2e/tasks/secret.txt", "/api/compare?a=..&b=%2e%2e",
           "/files/%00/etc/passwd", "/files/%ff%fe"]
SYMLINKS = [f"/files/{sample.FINISHED_RUN}/tasks/{safe_name('ubuntu-calc-sum[seed0]')}/evil.png",
            "/files/escape/secret.txt", "/api/runs/escape", "/api/runs/linked-run",
            f"/api/runs/{sample.LIVE_RUN}/tasks/linked-task", "/files/linked-run/run.json"]


@pytest.mark.parametrize("path", LITERAL)
def test_literal_dot_segments_are_refused(base_url, path):
    status, body = raw_get(base_url, path)
    assert status == 403, (path, status, body[:200])
    assert SECRET.encode() not in body and b"root:" not in body


@pytest.mark.parametrize("path", ENCODED + SYMLINKS)
def test_encoded_and_symlinked_escapes_are_refused(base_url, path):
    r = httpx.get(base_url + path)
    assert r.request.url.raw_path == path.encode()  # httpx sent it as written
    assert r.status_code == 403, (path, r.status_code, r.text[:200])
    assert SECRET not in r.text and "root:" not in r.text


def test_absolute_form_request_target_is_confined(base_url):
    status, body = raw_get(base_url, base_url + "/files/../secret.txt")
    assert status == 403 and SECRET.encode() not in body
    status, body = raw_get(base_url, "http://127.0.0.1/etc/passwd")
    assert status == 404 and b"root:" not in body


def test_unknown_paths_are_404(base_url):
    for path in ("/files/nope/x.png", "/api/runs/nope", f"/api/runs/{sample.FINISHED_RUN}/tasks/nope", "/etc/passwd",
                 "/api/nope", "/server.py", "/static/viewer.js"):
        assert httpx.get(base_url + path).status_code == 404, path


# -- files and API ------------------------------------------------------------------------------------------------

def test_static_viewer_and_files(base_url):
    r = httpx.get(base_url + "/")
    assert r.status_code == 302 and r.headers["location"] == "/viewer.html"
    for name, ctype in (("viewer.html", "text/html"), ("viewer.js", "text/javascript"), ("viewer.css", "text/css")):
        r = httpx.get(f"{base_url}/{name}")
        assert r.status_code == 200 and r.headers["content-type"].startswith(ctype), name
    html = httpx.get(base_url + "/viewer.html").text
    assert "http://" not in html and "https://" not in html  # nothing from outside this server
    shot = f"/files/{sample.FINISHED_RUN}/tasks/{safe_name('ubuntu-calc-sum[seed0]')}/step_0000_ubuntu.png"
    r = httpx.get(base_url + shot)
    assert r.status_code == 200 and r.headers["content-type"] == "image/png" and r.content[:4] == b"\x89PNG"
    again = httpx.get(base_url + shot, headers={"If-None-Match": r.headers["etag"]})
    assert again.status_code == 304


def test_runs_lists_progress_and_state(base_url):
    runs = {r["id"]: r for r in httpx.get(base_url + "/api/runs").json()["runs"]}
    assert set(runs) == {sample.FINISHED_RUN, sample.LIVE_RUN, "20250103-100000-cccccc"}  # not linked-run
    live_tasks = httpx.get(f"{base_url}/api/runs/{sample.LIVE_RUN}").json()["tasks"]
    assert "linked-task" not in {t["name"] for t in live_tasks}
    done = runs[sample.FINISHED_RUN]
    assert done["state"] == "finished" and done["agent_name"] == "oracle"
    assert {k: done["counts"][k] for k in ("passed", "failed", "error", "running", "pending", "total")} == \
        {"passed": 1, "failed": 2, "error": 1, "running": 0, "pending": 0, "total": 4}
    live = runs[sample.LIVE_RUN]
    assert live["state"] == "in progress"
    assert (live["counts"]["done"], live["counts"]["running"], live["counts"]["pending"]) == (1, 1, 2)


def test_run_shows_running_tasks_latest_step_and_pending(base_url):
    run = httpx.get(f"{base_url}/api/runs/{sample.LIVE_RUN}").json()
    assert sorted(run["pending"]) == ["md-photo-to-doc[seed1]", "windows-notepad-save[seed0]"]
    running = [t for t in run["tasks"] if t["status"] == "running"]
    assert len(running) == 1
    t = running[0]
    assert t["steps"] == 2 and t["latest_step"]["action"]["type"] == "RIGHT_CLICK"
    assert t["latest_screenshots"] == {"ubuntu": "step_0001_ubuntu.png"}


def test_task_has_steps_verdicts_and_final_state(base_url):
    task = httpx.get(f"{base_url}/api/runs/{sample.FINISHED_RUN}/tasks/{safe_name('md-photo-to-doc[seed1]')}").json()
    assert [s["index"] for s in task["steps_detail"]] == [0, 1, 2, 3, 4]
    assert task["steps_detail"][1]["error"].startswith("device unavailable")
    assert task["steps_detail"][0]["screenshots"] == {"android": "step_0000_android.png", "ubuntu": "step_0000_ubuntu.png"}
    assert task["extra_screenshots"] == [{"index": 5, "screenshots": {"android": "step_0005_android.png",
                                                                      "ubuntu": "step_0005_ubuntu.png"}}]
    failed = [e for s in task["subtasks"] for e in s["evaluators"] if not e["passed"]]
    assert failed[0]["reason"] == "notes.odt has no image (0 images, expected 1)"


def test_damaged_files_are_problems_not_failures(base_url):
    run = httpx.get(f"{base_url}/api/runs/20250103-100000-cccccc").json()
    problems = {p["file"].split("/", 1)[1]: p["message"] for p in run["problems"]}
    assert "not valid JSON" in problems["plan.json"]
    assert "not valid JSON" in problems[f"tasks/{safe_name('ubuntu-calc-sum[seed0]')}/result.json"]
    assert "half-written" in problems[f"tasks/{safe_name('md-photo-to-doc[seed1]')}/traj.jsonl"]
    status = {t["name"]: t["status"] for t in run["tasks"]}
    assert status[safe_name("ubuntu-calc-sum[seed0]")] == "unknown" and len(status) == 4
    task = httpx.get(f"{base_url}/api/runs/20250103-100000-cccccc/tasks/{safe_name('md-photo-to-doc[seed1]')}").json()
    assert len(task["steps_detail"]) == 5 and task["problems"]
    # the damaged run still lists, with its problems counted
    runs = {r["id"]: r for r in httpx.get(base_url + "/api/runs").json()["runs"]}
    assert len(runs["20250103-100000-cccccc"]["problems"]) == 3


def test_compare_task_by_task(base_url):
    data = httpx.get(f"{base_url}/api/compare", params={"a": sample.FINISHED_RUN, "b": sample.LIVE_RUN}).json()
    change = {r["task_id"]: r["change"] for r in data["rows"]}
    assert change == {"ubuntu-calc-sum[seed0]": "broken", "sw-rename-and-zip[seed2]": "incomplete",
                      "md-photo-to-doc[seed1]": "only in A", "windows-notepad-save[seed0]": "only in A"}
    assert httpx.get(f"{base_url}/api/compare", params={"a": sample.FINISHED_RUN}).status_code == 404


# -- starting it ----------------------------------------------------------------------------------------------------

def test_arguments_and_registration():
    from jarvis_pytest import cli

    assert "jarvis_pytest.dashboard.commands" in cli.COMMAND_MODULES
    parser = argparse.ArgumentParser(prog="jarvis")
    commands.register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["dashboard"])
    assert (args.port, args.results, args.host, args.func) == (8000, Path("reports"), "127.0.0.1", commands.serve)
    args = parser.parse_args(["dashboard", "--port", "9001", "--results", "/tmp/r"])
    assert (args.port, args.results) == (9001, Path("/tmp/r"))


def test_start_dashboard_script_serves_viewer(results):
    proc = subprocess.Popen([sys.executable, str(REPO / "start_dashboard.py"), "--port", "0", "--results", str(results)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO,
                            env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        line = proc.stdout.readline()
        assert line.startswith("dashboard: http://localhost:"), (line, proc.stderr.read() if proc.poll() else "")
        url = line.split()[1]
        assert url.endswith("/viewer.html")
        port = int(url.split(":")[2].split("/")[0])
        r = httpx.get(f"http://127.0.0.1:{port}/viewer.html")
        assert r.status_code == 200 and "viewer.js" in r.text
        runs = json.loads(httpx.get(f"http://127.0.0.1:{port}/api/runs").text)["runs"]
        assert len(runs) == 3
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def test_interrupted_and_resumed_runs(tmp_path):
    from jarvis_pytest.dashboard.store import ResultsStore

    run_dir = sample.write_finished_run(tmp_path)
    stuck = sample.start_task(run_dir, "stuck-task[0]", "atomic", ["ubuntu"], "Never ends.")
    stuck.result.started = "2025-01-01T10:05:00+00:00"  # before run.json's "finished": its session ended
    stuck.save_result()
    store = ResultsStore(tmp_path)
    run = store.run(run_dir.name)
    assert run["state"] == "finished" and run["counts"]["interrupted"] == 1 and run["counts"]["running"] == 0
    # --resume: a new session rewrites plan.json and reruns the task (it starts after the last session ended)
    os.utime(run_dir / "run.json", (1, 1))
    (run_dir / "plan.json").write_text(json.dumps({"tasks": ["stuck-task[0]", "next-task[0]"]}))
    sample.start_task(run_dir, "stuck-task[0]", "atomic", ["ubuntu"], "Runs again.")
    run = store.run(run_dir.name)
    assert run["state"] == "in progress" and run["counts"]["running"] == 1 and run["pending"] == ["next-task[0]"]
