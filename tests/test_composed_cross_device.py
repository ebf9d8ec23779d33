"""A composed multi-device task end to end on real devices: Windows (Wine) and Ubuntu on one task network with
the transfer drive. The oracle makes a file on Windows, carries it through the drive (S: on Windows, curl on
Ubuntu) and uses it on Ubuntu; from the result files alone: every subtask passed, the transfer's evaluator saw
the file the drive received and served on the destination, with the source's bytes, and the result says which
backends ran (Windows as a stand-in). `noop` fails the same task."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from jarvis_pytest.report.rollup import load_results
from jarvis_pytest.tasks.dataset import load_dataset
from jarvis_pytest.tasks.transfer import TransferLinks, transfer_links

pytestmark = pytest.mark.containers
REPO = Path(__file__).resolve().parents[1]
DATASET = REPO / "tasks" / "composed" / "jarvis_150.json"


def windows_to_ubuntu_task() -> str:
    """The first MD task of the default dataset that goes from Windows to Ubuntu, runs here (no backend-specific
    template) and compares both sides of its transfer (no later subtask changes the source or the received
    file)."""
    for task in load_dataset(DATASET).tasks:
        transfers = [t for t, s in enumerate(task.formatted_subtasks) if s.template == "transfer-windows-to-ubuntu"]
        whole = transfers and all(transfer_links(task.formatted_subtasks, task.edges, t) == TransferLinks(
            upstream=t - 1, downstream=(t + 1,)) for t in transfers)
        if task.category == "md" and whole and set(task.devices) == {"ubuntu", "windows"}:
            return task.id
    raise AssertionError("the default dataset has no Windows → Ubuntu MD task")


def run(tmp_path: Path, agent: str, task_id: str) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist", str(REPO / "tasks" / "test_composed.py"),
           "--agent", agent, "-k", task_id, "--results-dir", str(tmp_path)]
    return subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=900)


def test_md_task_carries_a_file_from_windows_to_ubuntu_unchanged(device_images, tmp_path):
    task_id = windows_to_ubuntu_task()
    proc = run(tmp_path / "oracle", "oracle", task_id)
    assert proc.returncode == 0, proc.stdout[-4000:]
    (result,) = load_results(tmp_path / "oracle")[0]
    assert result.status == "passed" and result.category == "md" and all(s.passed for s in result.subtasks)
    assert result.backends == {"ubuntu": "ubuntu (docker)", "windows": "windows (wine)"}
    assert result.stand_ins == ["windows"]
    (transfer,) = [s for s in result.subtasks if s.template == "transfer-windows-to-ubuntu"]
    (check,) = transfer.evaluators
    # "... found /data/<name> (sha256 X, N bytes, served 1×) arrived through the drive; <destination> holds it"
    assert check.func == "transfer_arrived_unchanged" and check.passed
    assert "served 1×) arrived through the drive" in check.reason and "holds it" in check.reason, check.reason
    folder = next((tmp_path / "oracle" / "tasks").iterdir())
    ledger = [json.loads(line) for line in (folder / "drive_ledger.jsonl").read_text().splitlines()]
    assert [r["ev"] for r in ledger if r["ev"] in ("mark", "write", "read")] == ["mark", "write", "read", "mark"]
    # the commands of the oracle ran on both devices, and the summary marks the Windows numbers as a stand-in's
    steps = [json.loads(l) for l in next((tmp_path / "oracle" / "tasks").iterdir()).joinpath("traj.jsonl").read_text().splitlines()]
    assert {"windows", "ubuntu"} <= {c["platform"] for s in steps for c in s["extra"].get("commands", [])}
    assert "Windows ran on windows (wine)" in (tmp_path / "oracle" / "summary.md").read_text()
    noop = run(tmp_path / "noop", "noop", task_id)
    (failed,) = load_results(tmp_path / "noop")[0]
    assert noop.returncode == 0 and failed.status == "failed" and not any(s.passed for s in failed.subtasks)
    assert failed.failure_mode == "done early"
