"""Bad configuration stops a benchmark run at start-up with one clear error, not a stack trace per test."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def run_bench(*args: str, cwd: Path = REPO) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", str(REPO / "tasks"), *args],
                          cwd=cwd, capture_output=True, text=True, timeout=120)


def assert_one_clear_error(proc: subprocess.CompletedProcess, *needles: str) -> None:
    out = proc.stdout + proc.stderr
    assert proc.returncode == 4, out  # pytest's usage error
    assert "Traceback" not in out and "INTERNALERROR" not in out, out
    errors = [line for line in out.splitlines() if line.startswith("ERROR:")]
    assert len(errors) == 1, out
    for needle in needles:
        assert needle in errors[0], errors[0]


def test_unknown_agent_lists_the_known_ones():
    assert_one_clear_error(run_bench("--agent", "no-such-agent"), "no-such-agent", "oracle", "holo2")


def test_no_agent_says_how_to_choose_one(tmp_path):
    assert_one_clear_error(run_bench("--results-dir", str(tmp_path)), "--agent")


def test_malformed_task_file_names_the_file(tmp_path):
    (tmp_path / "ubuntu").mkdir()
    bad = tmp_path / "ubuntu" / "broken.json"
    bad.write_text('{"id": "ubuntu-x-y", "platform": "ubuntu",')
    assert_one_clear_error(run_bench("--agent", "noop", "--library", str(tmp_path)), str(bad))


def test_unknown_slot_type_names_file_and_field(tmp_path):
    (tmp_path / "ubuntu").mkdir()
    src = (REPO / "tasks" / "ubuntu" / "thunar_rename_file.json").read_text()
    bad = tmp_path / "ubuntu" / "thunar_rename_file.json"
    bad.write_text(src.replace('"type": "file_name"', '"type": "no_such_type"'))
    assert_one_clear_error(run_bench("--agent", "noop", "--library", str(tmp_path)), str(bad), "no_such_type")


def test_unreachable_endpoint(tmp_path):
    with socket.socket() as s:  # a port on loopback that nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    url = f"http://127.0.0.1:{port}/v1"
    proc = run_bench("--agent", "holo2", "--planner-base-url", url, "--grounder-base-url", url,
                     "--results-dir", str(tmp_path))
    assert_one_clear_error(proc, "unreachable", url)


def test_bad_agent_option():
    assert_one_clear_error(run_bench("--agent", "noop", "--agent-option", "novalue"), "KEY=VALUE")


def test_an_alist_drive_that_cannot_be_had_stops_the_run_at_start_up(device_images, tmp_path, monkeypatch):
    """`--transfer alist` pulls its image once at start-up; here the registry is a closed port on 127.0.0.1."""
    monkeypatch.setenv("JARVIS_ALIST_IMAGE", "127.0.0.1:9/jarvis-test/alist:none")
    proc = run_bench("--agent", "oracle", "--transfer", "alist", "--results-dir", str(tmp_path))
    assert_one_clear_error(proc, "--transfer alist", "127.0.0.1:9/jarvis-test/alist:none", "--transfer copyparty")


def test_qc_runs_the_oracle_only(tmp_path):
    assert_one_clear_error(run_bench("--qc", "--agent", "noop", "--results-dir", str(tmp_path)), "--qc", "noop")
