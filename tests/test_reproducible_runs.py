"""Reproducible runs through pytest itself, on real containers: `--trials K` with a scripted agent that succeeds in
some trials only (pass@K, pass^K, the unstable task, a resume that adds a trial); `jarvis reproduce` giving the
same verdicts, refusing another image unless told, and `jarvis diff` naming a changed setting; and devices that do
not drift: the same instances, set up with the host's clock years apart and in other time zones, give the same
input bytes and the same verdicts."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from jarvis_pytest.report.rollup import load_results
from tests import test_plugin_exit_status as exit_status
from jarvis_pytest.results.model import trial_seed

pytestmark = pytest.mark.containers
REPO = Path(__file__).resolve().parents[1]
AGENTS = REPO / "tests" / "data" / "agents"

# the exit-status tests' task, with an input file set-up writes
MAKE_FILE = dict(exit_status.MAKE_FILE,
                 config=[{"type": "upload_file", "path": "/home/user/Documents/notes.txt", "content": "kept\n"}],
                 baseline=["/home/user/Documents/notes.txt"])
# the same, with a terminal open where the scripted agent clicks
MAKE_NOTE = dict(MAKE_FILE, id="ubuntu-terminal-make_note",
                 config=[{"type": "launch", "app": "xfce4-terminal", "args": ["--geometry=80x24+100+100"]}],
                 baseline=[])


@pytest.fixture(scope="module")
def library(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("library")
    (root / "ubuntu").mkdir()
    for t in (MAKE_FILE, MAKE_NOTE):
        (root / "ubuntu" / f"{t['id'].rsplit('-', 1)[1]}.json").write_text(json.dumps(t))
    (root / "none.json").write_text('{"tasks": []}')
    return root


def bench(library: Path, run_dir: Path, select: str, *args: str) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist", str(REPO / "tasks"),
           "--library", str(library), "--dataset", str(library / "none.json"), "--instances", "1",
           "--results-dir", str(run_dir), "-k", select, *args]
    return subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=400,
                          env=dict(os.environ, PYTHONPATH=str(AGENTS)))


def jarvis(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", *args], cwd=REPO, capture_output=True,
                          text=True, timeout=400, env=dict(os.environ, PYTHONPATH=str(AGENTS)))


def summary(run_dir: Path) -> dict:
    return json.loads((run_dir / "summary.json").read_text())


def by_trial(run_dir: Path) -> dict[int, object]:
    return {r.trial: r for r in load_results(run_dir)[0]}


def test_trials_of_an_agent_that_succeeds_in_one_of_three(device_images, library, tmp_path):
    run = tmp_path / "run"
    proc = bench(library, run, "make_note", "--agent", "trial_agent:SometimesAgent", "--agent-option", "wins=2",
                 "--trials", "3", "-v")
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-3000:]  # an agent's failures are results
    task = "ubuntu-terminal-make_note[seed0]"
    for n in (1, 2, 3):
        assert f"test_atomic[{task}-trial{n}]" in out
    trials = by_trial(run)
    assert {n: r.status for n, r in trials.items()} == {1: "failed", 2: "passed", 3: "failed"}
    assert {n: r.seed for n, r in trials.items()} == {n: trial_seed(task, n) for n in (1, 2, 3)}
    traj = (run / "tasks" / "ubuntu-terminal-make_note_seed0_trial2" / "traj.jsonl").read_text()
    assert f"trial 2, seed {trial_seed(task, 2)}" in traj  # what the agent was told
    s = summary(run)
    cell = s["trials"]["cells"]["atomic/ubuntu"]
    assert s["trials"]["k"] == 3 and s["trials"]["unstable"] == [task]
    assert (cell["pass_at_k"], cell["pass_all_k"]) == (1.0, 0.0) and abs(cell["mean"] - 1 / 3) < 1e-9
    assert (s["atomic"]["ubuntu"]["k"], s["atomic"]["ubuntu"]["n"]) == (1, 3)
    assert "pass@3" in out and f"unstable tasks (trials disagree): 1: {task} (1/3)" in out
    card = json.loads((run / "run.json").read_text())["card"]
    assert card["trials"] == 3 and card["agent"] == {"name": "sometimes", "wins": [2]}
    # a fourth trial, added by --resume: the three kept, only the new one runs
    before = {n: r.finished for n, r in trials.items()}
    proc = bench(library, run, "make_note", "--agent", "trial_agent:SometimesAgent", "--agent-option", "wins=2",
                 "--trials", "4", "--resume", str(run))
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-3000:]
    trials = by_trial(run)
    assert {n: r.finished for n, r in trials.items() if n < 4} == before and trials[4].status == "failed"
    assert summary(run)["trials"]["k"] == 4 and summary(run)["trials"]["cells"]["atomic/ubuntu"]["pass_all_k"] == 0.0


def test_reproduce_gives_the_same_verdicts_and_diff_names_a_changed_setting(device_images, library, tmp_path):
    first, again, shorter = tmp_path / "first", tmp_path / "again", tmp_path / "shorter"
    proc = bench(library, first, "make_file", "--agent", "oracle", "--trials", "2")
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-3000:]
    proc = jarvis("reproduce", str(first), "--results-dir", str(again))
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-3000:]
    assert "verdicts: 2 of 2 task trials the same; 0 differ" in out and "conditions that differ: 0" in out
    assert {n: r.status for n, r in by_trial(again).items()} == {1: "passed", 2: "passed"}
    card = json.loads((again / "run.json").read_text())["card"]
    assert card["reproduces"]["run"] == "first" and card["reproduces"]["differences"] == []
    assert {r.key: r.inputs for r in load_results(first)[0]} == {r.key: r.inputs for r in load_results(again)[0]}
    assert jarvis("diff", str(first), str(again)).returncode == 0
    # a changed setting: diff names it (the verdicts stay)
    proc = bench(library, shorter, "make_file", "--agent", "oracle", "--trials", "2", "--max-steps", "30")
    assert proc.returncode == 0 and "WARNING: the step limit 30 is under the paper's 50" in proc.stdout
    proc = jarvis("diff", str(first), str(shorter))
    assert proc.returncode == 1 and "conditions that differ: 1\n  limits.max_steps\n    A: 50\n    B: 30" in proc.stdout
    assert "verdicts: 2 of 2 task trials the same" in proc.stdout
    # a run made with another image: refused before any device boots, then run when told to
    other = tmp_path / "other"
    shutil.copytree(first, other)
    meta = json.loads((other / "run.json").read_text())
    meta["card"]["devices"]["ubuntu"]["image_ids"] = ["sha256:" + "0" * 64]
    (other / "run.json").write_text(json.dumps(meta))
    proc = jarvis("reproduce", str(other), "--results-dir", str(tmp_path / "refused"))
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0 and "this run would not reproduce it" in out, out[-3000:]
    assert "devices.ubuntu: the image jarvis/ubuntu:latest here is" in out and "Traceback" not in out
    assert not (tmp_path / "refused" / "tasks").exists()
    proc = jarvis("reproduce", str(other), "--results-dir", str(tmp_path / "allowed"), "--allow-differences")
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-3000:]
    card = json.loads((tmp_path / "allowed" / "run.json").read_text())["card"]
    assert card["reproduces"]["differences"][0].startswith("devices.ubuntu: the image")


# Real templates whose input files come from a generator (xlsx, rtf), from ImageMagick, zip and LibreOffice on the
# device, and one whose verdict depends on the device's date (WordPad's Insert > Date and time).
DRIFT_TASKS = "terminal-zip_folder or terminal-unzip_archive or impress-add_slide or wordpad-insert_date or " \
              "calc-sum_total"


def test_devices_do_not_drift_with_the_hosts_clock_or_time_zone(device_images, tmp_path):
    """The same instances, set up once with the host's clock in 2031 and its time zone 14 hours east of UTC, and once
    at the real time 10 hours west of it: the same input bytes, the same verdicts, the devices' own time zone."""
    faketime = shutil.which("faketime")
    assert faketime, "faketime (Debian package faketime) is missing: `make host-packages` installs it"
    runs = {"shifted": tmp_path / "shifted", "plain": tmp_path / "plain"}
    # one task at a time (no xdist): the suite's own workers keep the cores busy beside it
    base = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist",
            str(REPO / "tasks" / "test_atomic.py"),
            "--instances", "1", "--agent", "oracle", "-k", DRIFT_TASKS]
    procs = {
        "shifted": subprocess.run([faketime, "-f", "@2031-07-04 23:59:50", *base, "--results-dir", str(runs["shifted"])],
                                  cwd=REPO, capture_output=True, text=True, timeout=900,
                                  env=dict(os.environ, TZ="Pacific/Kiritimati")),
        "plain": subprocess.run([*base, "--results-dir", str(runs["plain"])], cwd=REPO, capture_output=True,
                                text=True, timeout=900, env=dict(os.environ, TZ="America/Adak")),
    }
    for name, proc in procs.items():
        assert proc.returncode == 0, f"{name}: {(proc.stdout + proc.stderr)[-3000:]}"
    results = {name: {r.task_id: r for r in load_results(d)[0]} for name, d in runs.items()}
    assert set(results["shifted"]) == set(results["plain"]) and len(results["plain"]) == 5
    assert json.loads((runs["shifted"] / "run.json").read_text())["started"].startswith("2031-07-04")
    for task, plain in results["plain"].items():
        shifted = results["shifted"][task]
        assert plain.inputs and plain.inputs == shifted.inputs, task
        assert [s.passed for s in plain.subtasks] == [s.passed for s in shifted.subtasks] == [True], task
    card = json.loads((runs["plain"] / "run.json").read_text())["card"]
    assert card["devices"]["ubuntu"]["timezone"] == "Etc/UTC" and card["devices"]["windows"]["hostname"] == "windows-pc"


def test_a_device_has_its_platforms_hostname_time_zone_and_locale(ubuntu_env):
    res = ubuntu_env.devices["ubuntu"].run("echo $(hostname) $TZ $LANG $LC_ALL; date +%Z")
    assert res.stdout.split() == ["ubuntu-desktop", "Etc/UTC", "C.UTF-8", "C.UTF-8", "UTC"]
