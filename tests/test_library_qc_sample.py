"""The benchmark's own libraries under the quality gate, on a fixed sample (the full sweep is
`jarvis qc --platform ubuntu` / `--platform windows`): the first template of every application that runs on this
machine's backends, seed 0, with its negatives. A broken task, evaluator, negative or oracle of any application
fails `make test`."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from jarvis_pytest.tasks.library import load_library

REPO = Path(__file__).resolve().parents[1]


def sample_ids(platform: str) -> list[str]:
    """One template per application of a platform's library (the first by id that runs on the default backend)."""
    from jarvis_pytest.devices.backend import backend_for

    default = backend_for(platform).name
    first: dict[str, str] = {}
    for tpl in load_library(REPO / "tasks").by_platform(platform):
        if not tpl.backends or default in tpl.backends:
            first.setdefault(tpl.app, tpl.id)
    return sorted(first.values())


@pytest.mark.containers
@pytest.mark.parametrize("platform", ["ubuntu", "windows"])
def test_one_template_per_app_passes_the_quality_gate(device_images, tmp_path, platform):
    ids = sample_ids(platform)
    assert ids, f"no {platform} templates"
    expr = " or ".join(ids)
    proc = subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "qc", "--platform", platform, "--instances",
                           "1", "-n", "1", "-k", expr, "--results-dir", str(tmp_path / "qc")],
                          cwd=REPO, capture_output=True, text=True, timeout=1800)
    table = (tmp_path / "qc" / "qc.md").read_text() if (tmp_path / "qc" / "qc.md").exists() else proc.stdout
    assert proc.returncode == 0, table + proc.stdout[-2000:] + proc.stderr[-2000:]
    gated = [line.split("|")[1].strip().split("[")[0] for line in table.splitlines()
             if line.startswith(f"| {platform}-")]
    assert sorted(gated) == ids, f"sampled {ids}, gated {gated}"
