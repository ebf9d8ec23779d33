"""The TSR/SSR rollup: hand-computed numbers, order independence, errors apart, invariants."""

from __future__ import annotations

import json
import random

from hypothesis import given, settings
from hypothesis import strategies as st

from jarvis_pytest.report.rollup import load_results, render_markdown, rollup, write_summary
from jarvis_pytest.results.model import SubtaskVerdict, TaskResult
from jarvis_pytest.results.writer import task_dir


def task(tid: str, category: str, passes: list[bool], platforms=("ubuntu",), status: str | None = None) -> TaskResult:
    subs = [SubtaskVerdict(index=i, template="t", platform=platforms[0], passed=p) for i, p in enumerate(passes)]
    return TaskResult(task_id=tid, category=category, platforms=list(platforms), instruction="x",
                      status=status or ("passed" if passes and all(passes) else "failed"), subtasks=subs)


MIXED = [
    task("a1", "atomic", [True]), task("a2", "atomic", [False]), task("a3", "atomic", [True]),
    task("a4", "atomic", [True], platforms=("android",)), task("a5", "atomic", [], status="error"),
    task("s1", "sw", [True, False]), task("s2", "sw", [True, True]),
    task("m1", "mi", [False, False, True], platforms=("android", "ubuntu")),
    task("d1", "md", [True, True, True, True], platforms=("ubuntu", "windows")),
    task("d2", "md", [], platforms=("ubuntu", "windows"), status="error"),
    task("r1", "sw", [], status="running"),
]


def test_hand_computed_table():
    s = rollup(MIXED)
    assert (s.atomic["ubuntu"].k, s.atomic["ubuntu"].n) == (2, 3)
    assert (s.atomic["android"].k, s.atomic["android"].n) == (1, 1)
    assert s.atomic["windows"].rate is None and s.atomic["windows"].n == 0
    assert (s.atomic["overall"].k, s.atomic["overall"].n) == (3, 4)
    assert s.composed["sw"].tsr.rate == 0.5 and s.composed["sw"].ssr.rate == (0.5 + 1.0) / 2
    assert s.composed["sw"].subtasks == (3, 4)
    assert s.composed["mi"].tsr.rate == 0.0 and abs(s.composed["mi"].ssr.rate - 1 / 3) < 1e-12
    assert s.composed["md"].tsr.rate == 1.0 and s.composed["md"].tsr.n == 1  # the error is not counted
    overall = s.composed["overall"]
    assert (overall.tsr.k, overall.tsr.n) == (2, 4)
    assert abs(overall.ssr.rate - (0.5 + 1 + 1 / 3 + 1) / 4) < 1e-12
    assert s.errors == {"atomic": 1, "md": 1} and s.unfinished == 1 and s.tasks == 8
    assert (s.overall["tsr"].k, s.overall["tsr"].n) == (5, 8)
    assert [(b.subtasks, b.n, b.k) for b in s.by_subtasks] == [(2, 2, 1), (3, 1, 0), (4, 1, 1)]


def test_markdown_has_the_papers_cells():
    md = render_markdown(rollup(MIXED, agent="oracle"))
    assert "66.7 (2/3)" in md and "50.0 (2/4)" in md and "atomic: 1, md: 1" in md and "oracle" in md


def test_intervals_deterministic_and_contain_point():
    a, b = rollup(MIXED, seed=3), rollup(MIXED, seed=3)
    assert a == b
    c = a.atomic["ubuntu"]
    assert c.ci[0] <= c.rate <= c.ci[1]
    assert a.composed["md"].tsr.ci == (1.0, 1.0)


def test_order_independent(tmp_path):
    shuffled = MIXED[:]
    random.Random(7).shuffle(shuffled)
    assert json.dumps(rollup(shuffled).model_dump(mode="json"), sort_keys=True) == \
        json.dumps(rollup(MIXED).model_dump(mode="json"), sort_keys=True)


def test_write_and_load_round_trip(tmp_path):
    for r in MIXED:
        d = task_dir(tmp_path, r.task_id)
        d.mkdir(parents=True)
        (d / "result.json").write_text(r.model_dump_json())
    bad = task_dir(tmp_path, "broken")
    bad.mkdir(parents=True)
    (bad / "result.json").write_text('{"task_id": ')
    results, problems = load_results(tmp_path)
    assert len(results) == len(MIXED) and len(problems) == 1 and "broken" in problems[0]
    s = write_summary(tmp_path, results, {"name": "noop"})
    assert json.loads((tmp_path / "summary.json").read_text()) == s.model_dump(mode="json")
    assert (tmp_path / "summary.md").read_text().startswith("# Results — noop")


composed_tasks = st.lists(
    st.tuples(st.sampled_from(["sw", "mi", "md"]), st.lists(st.booleans(), min_size=1, max_size=5)),
    min_size=1, max_size=12)


@settings(max_examples=60, deadline=None)
@given(composed_tasks)
def test_tsr_never_above_ssr_and_ci_bounds(items):
    s = rollup([task(f"t{i}", c, ps) for i, (c, ps) in enumerate(items)], n_boot=200)
    for cat in ("sw", "mi", "md", "overall"):
        cell = s.composed[cat]
        if cell.tsr.rate is None:
            continue
        assert cell.tsr.rate <= cell.ssr.rate + 1e-12
        for c in (cell.tsr, cell.ssr):
            assert 0 <= c.ci[0] <= c.rate <= c.ci[1] <= 1
