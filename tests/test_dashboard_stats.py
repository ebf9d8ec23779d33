"""The dashboard's view of the rollup: headline TSR/SSR, tables and the subtask curve of a real summary."""

from __future__ import annotations

import sys
import types

import pytest

from jarvis_pytest.dashboard import sample, stats
from jarvis_pytest.dashboard.store import ResultsStore
from jarvis_pytest.report import rollup as rollup_module
from jarvis_pytest.report.rollup import load_results, rollup


@pytest.fixture(autouse=True)
def fresh_memo(monkeypatch):
    monkeypatch.setattr(stats, "_memo", {})


def test_headline_tables_and_curve_equal_the_rollup(tmp_path):
    run_dir = sample.write_finished_run(tmp_path)
    results, _ = load_results(run_dir)
    want = rollup([r for r in results if r.status != "running"])
    run = ResultsStore(tmp_path).run(sample.FINISHED_RUN)
    s = run["summary"]
    assert s["available"], s["message"]
    assert run["stats"]["tsr"] == pytest.approx(want.overall["tsr"].rate)
    assert run["stats"]["ssr"] == pytest.approx(want.overall["ssr"].rate)
    assert [(p["subtasks"], p["tasks"], p["passed"]) for p in s["curve"]] == \
        [(b.subtasks, b.n, b.k) for b in want.by_subtasks]
    assert s["curve"], "the sample run has composed tasks"
    assert any(t["title"] == "atomic" for t in s["tables"])


def test_rollup_runs_once_per_set_of_results(tmp_path, monkeypatch):
    calls = []

    def counting(results, **kw):
        calls.append(len(results))
        return rollup(results, **kw)

    monkeypatch.setattr(rollup_module, "rollup", counting)
    sample.write_finished_run(tmp_path)
    store = ResultsStore(tmp_path)
    for _ in range(3):
        store.runs()
        store.run(sample.FINISHED_RUN)
    assert len(calls) == 1


def test_no_rollup_or_a_failing_one_is_reported_not_raised(tmp_path, monkeypatch):
    module = types.ModuleType("jarvis_pytest.report.rollup")
    module.rollup = lambda results: 1 / 0
    monkeypatch.setitem(sys.modules, "jarvis_pytest.report.rollup", module)
    sample.write_finished_run(tmp_path)
    s = ResultsStore(tmp_path).run(sample.FINISHED_RUN)["summary"]
    assert not s["available"] and "ZeroDivisionError" in s["message"]
    monkeypatch.setitem(sys.modules, "jarvis_pytest.report.rollup", None)  # import fails
    monkeypatch.setattr(stats, "_memo", {})
    s = ResultsStore(tmp_path).run(sample.FINISHED_RUN)["summary"]
    assert not s["available"] and "not available" in s["message"]
