"""Broken chains of composed tasks (`jarvis qc --composed`): which are made from the oracle's plan, and, on real
devices, that each one fails its task at the subtask that should catch it."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from jarvis_pytest.agents.oracle import PlanItem, oracle_plan
from jarvis_pytest.harness.chain_negatives import Carry, Substitute, chain_negatives
from jarvis_pytest.report.rollup import load_results
from jarvis_pytest.tasks.compose import Draft, Link, build
from jarvis_pytest.tasks.library import load_library
from jarvis_pytest.tasks.model import Task
from tests.test_evaluators_transfer import node

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def append_then_convert() -> Task:
    """Mousepad appends a line on Ubuntu (in place), the file goes to Windows, Notepad converts its line breaks."""
    library = load_library(REPO / "tasks")
    built = build(Draft((node(library, "ubuntu-mousepad-append_line"),
                         node(library, "windows-notepad-crlf_line_endings")), (Link(0, "edited_file", 1, "text_file"),)))
    return Task(id="md-test", category="md", devices=["ubuntu", "windows"], instruction="-", edges=built.edges,
                formatted_subtasks=built.subtasks)


def test_every_kind_of_broken_chain_is_made_from_the_oracles_plan(append_then_convert):
    task = append_then_convert
    plan = oracle_plan(task.formatted_subtasks)
    negs = {n.kind: n for n in chain_negatives(task)}
    assert list(negs) == ["made_up", "substituted", "too_early", "unplaced", "upstream_skipped"]
    assert all(n.transfer == 1 for n in negs.values())
    assert negs["upstream_skipped"].expect == (0, 1) and negs["made_up"].expect == (1,)
    transfer_steps = [p for p in plan if p.subtask == 1]
    assert len(transfer_steps) == 2  # upload, download
    made_up = negs["made_up"].plan
    assert not any(isinstance(p, PlanItem) and p.subtask == 1 for p in made_up)
    (carry,) = [p for p in made_up if isinstance(p, Carry)]
    assert carry.platform == "windows" and carry.source_platform == "ubuntu"
    assert made_up.index(carry) == sum(p.subtask == 0 for p in plan)  # where the transfer was
    (sub,) = [p for p in negs["substituted"].plan if isinstance(p, Substitute)]
    assert negs["substituted"].plan.index(sub) == plan.index(transfer_steps[0])
    early = negs["too_early"].plan
    assert early[:2] == tuple(transfer_steps)  # carried before the append ran
    assert transfer_steps[1] not in negs["unplaced"].plan and transfer_steps[0] in negs["unplaced"].plan
    assert not any(isinstance(p, PlanItem) and p.subtask == 0 for p in negs["upstream_skipped"].plan)


def test_a_chain_whose_upstream_makes_a_new_file_has_no_too_early_negative():
    library = load_library(REPO / "tasks")
    built = build(Draft((node(library, "windows-notepad-write_note"), node(library, "ubuntu-mousepad-append_line")),
                        (Link(0, "note", 1, "list_file"),)))
    task = Task(id="md-test", category="md", devices=["ubuntu", "windows"], instruction="-", edges=built.edges,
                formatted_subtasks=built.subtasks)
    assert [n.kind for n in chain_negatives(task)] == ["made_up", "substituted", "unplaced", "upstream_skipped"]


@pytest.mark.containers
def test_qc_composed_catches_every_broken_chain_at_the_right_subtask(device_images, tmp_path):
    """md-0132 of the default dataset: Mousepad's append, the transfer to Windows, Notepad's conversion; every broken
    chain fails the transfer (and the append, where it is left out), and the oracle passes."""
    proc = subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "qc", "--composed", "-k", "md-0132",
                           "--results-dir", str(tmp_path)], cwd=REPO, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
    assert "| md-0132 | fail | 5/5 caught | pass | - | ok |" in proc.stdout, proc.stdout[-2000:]
    (result,) = load_results(tmp_path)[0]
    kinds = {n.kind: n for n in result.qc_negatives}
    assert set(kinds) == {f"chain:{k}" for k in ("made_up", "substituted", "too_early", "unplaced",
                                                  "upstream_skipped")}
    for n in kinds.values():
        assert not n.passed and all(not n.verdicts[i].passed for i in n.expect), n
        (reason,) = [e.reason for e in n.verdicts[1].evaluators]
        assert "transfer" in n.verdicts[1].template and reason
    assert "never taken off" in kinds["chain:unplaced"].verdicts[1].evaluators[0].reason
    assert "no file named" in kinds["chain:made_up"].verdicts[1].evaluators[0].reason
    assert "input, not its output" in kinds["chain:upstream_skipped"].verdicts[1].evaluators[0].reason
