"""The benchmark's own Ubuntu library under the quality gate, on a fixed sample (the full sweep is
`jarvis qc --platform ubuntu`): the first template of every application, seed 0. A broken task, evaluator or
oracle of any application fails `make test`."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from jarvis_pytest.tasks.library import load_library

REPO = Path(__file__).resolve().parents[1]


def sample_ids() -> list[str]:
    """One template per application of the Ubuntu library (the first by id)."""
    first: dict[str, str] = {}
    for tpl in load_library(REPO / "tasks").by_platform("ubuntu"):
        first.setdefault(tpl.app, tpl.id)
    return sorted(first.values())


@pytest.mark.containers
def test_one_template_per_app_passes_the_quality_gate(device_images, tmp_path):
    ids = sample_ids()
    expr = " or ".join(ids)
    proc = subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "qc", "--platform", "ubuntu", "--instances",
                           "1", "-n", "1", "-k", expr, "--results-dir", str(tmp_path / "qc")],
                          cwd=REPO, capture_output=True, text=True, timeout=1200)
    table = (tmp_path / "qc" / "qc.md").read_text() if (tmp_path / "qc" / "qc.md").exists() else proc.stdout
    assert proc.returncode == 0, table + proc.stdout[-2000:] + proc.stderr[-2000:]
    gated = [line.split("|")[1].strip().split("[")[0] for line in table.splitlines() if line.startswith("| ubuntu-")]
    assert sorted(gated) == ids, f"sampled {ids}, gated {gated}"
