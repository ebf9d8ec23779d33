"""The TSR/SSR rollup: every number of a small mixed set checked by hand, intervals, order independence, errors
apart, the files, and invariants under hypothesis."""

from __future__ import annotations

import json
import random

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jarvis_pytest.report.rollup import (load_results, render_markdown, render_terminal, rollup, summary_json,
                                         write_summary)
from jarvis_pytest.results.model import SubtaskVerdict, TaskResult
from jarvis_pytest.results.writer import task_dir


def task(tid: str, category: str, passes: list[bool], platforms=("ubuntu",), status: str | None = None,
         finished: str = "") -> TaskResult:
    subs = [SubtaskVerdict(index=i, template="t", platform=platforms[i % len(platforms)], passed=p)
            for i, p in enumerate(passes)]
    return TaskResult(task_id=tid, category=category, platforms=list(platforms), instruction="x",
                      status=status or ("passed" if passes and all(passes) else "failed"), subtasks=subs,
                      finished=finished)


T, F = True, False
MIXED = [
    task("a-and-1", "atomic", [T], platforms=("android",)),
    task("a-and-2", "atomic", [F], platforms=("android",)),
    task("a-ubu-1", "atomic", [T]),
    task("a-ubu-2", "atomic", [T]),
    task("a-ubu-3", "atomic", [F]),
    task("a-win-err", "atomic", [], platforms=("windows",), status="error"),
    task("sw-1", "sw", [T, F]),
    task("sw-2", "sw", [T, T]),
    task("sw-3", "sw", [F, F, F]),
    task("sw-run", "sw", [], status="running"),
    task("mi-1", "mi", [T, F], platforms=("android", "ubuntu")),
    task("mi-2", "mi", [T, T, T, F], platforms=("android", "ubuntu")),
    task("md-1", "md", [T, T, T, T], platforms=("ubuntu", "windows")),
    task("md-err", "md", [], platforms=("ubuntu", "windows"), status="error"),
    task("md-run", "md", [], platforms=("ubuntu", "windows"), status="running"),
]


def counts(cell) -> tuple:
    return cell.k, cell.n


def test_every_number_of_the_mixed_set():
    s = rollup(MIXED)
    # atomic: android 1/2, windows only an error, ubuntu 2/3, overall 3/5
    assert counts(s.atomic["android"]) == (1, 2) and s.atomic["android"].rate == 0.5
    assert s.atomic["windows"].rate is None and s.atomic["windows"].n == 0 and s.atomic["windows"].ci is None
    assert counts(s.atomic["ubuntu"]) == (2, 3) and s.atomic["ubuntu"].rate == pytest.approx(2 / 3)
    assert counts(s.atomic["overall"]) == (3, 5) and s.atomic["overall"].rate == 0.6
    # SW: ratios 1/2, 1, 0 → SSR 0.5; subtasks 3/7 (pooled 0.4286 ≠ 0.5)
    sw = s.composed["sw"]
    assert counts(sw.tsr) == (1, 3) and sw.tsr.rate == pytest.approx(1 / 3)
    assert sw.ssr.rate == 0.5 and counts(sw.ssr) == (3, 7) and sw.ssr.tasks == 3
    assert sw.ssr.pooled_rate == pytest.approx(3 / 7)
    # MI: ratios 1/2, 3/4 → 0.625; subtasks 4/6
    mi = s.composed["mi"]
    assert counts(mi.tsr) == (0, 2) and mi.tsr.rate == 0.0
    assert mi.ssr.rate == 0.625 and counts(mi.ssr) == (4, 6) and mi.ssr.pooled_rate == pytest.approx(2 / 3)
    # MD: the error and the running task are not counted
    md = s.composed["md"]
    assert counts(md.tsr) == (1, 1) and md.ssr.rate == 1.0 and counts(md.ssr) == (4, 4)
    assert md.tsr.ci == (1.0, 1.0) and md.ssr.ci == (1.0, 1.0)  # one task: every resample is that task
    # composed overall: 2/6 passed; ratios (1/2 + 1 + 0 + 1/2 + 3/4 + 1) / 6 = 0.625; subtasks 11/17
    ov = s.composed["overall"]
    assert counts(ov.tsr) == (2, 6) and ov.tsr.rate == pytest.approx(1 / 3)
    assert ov.ssr.rate == 0.625 and counts(ov.ssr) == (11, 17) and ov.ssr.pooled_rate == pytest.approx(11 / 17)
    assert s.overall["ssr"] == ov.ssr
    assert counts(s.overall["tsr"]) == (5, 11)  # every counted task, atomic and composed
    # success against the number of subtasks
    assert [(b.subtasks, b.n, b.k, round(b.tsr, 4), round(b.ssr, 4)) for b in s.by_subtasks] == [
        (2, 3, 1, 0.3333, 0.6667), (3, 1, 0, 0.0, 0.0), (4, 2, 1, 0.5, 0.875)]
    per_cat = {c: [(b.subtasks, b.n, b.k) for b in bs] for c, bs in s.by_subtasks_category.items()}
    assert per_cat == {"sw": [(2, 2, 1), (3, 1, 0)], "mi": [(2, 1, 0), (4, 1, 0)], "md": [(4, 1, 1)]}
    # not counted
    assert s.errors == {"atomic": 1, "sw": 0, "mi": 0, "md": 1}
    assert s.unfinished == {"atomic": 0, "sw": 1, "mi": 0, "md": 1}
    assert s.tasks == 11 and s.warnings == []


def test_intervals_are_seeded_contain_the_point_and_are_plausible():
    a, b = rollup(MIXED, seed=3), rollup(MIXED, seed=3)
    assert a == b
    rich = [task(f"t{i:02}", "sw", [(i * j) % 3 != 0 for j in range(1, 2 + i % 4)]) for i in range(30)]
    assert len({rollup(rich, seed=seed).composed["sw"].ssr.ci for seed in range(4)}) > 1  # the seed matters
    for cell in [*a.atomic.values(), *(x.tsr for x in a.composed.values()), *(x.ssr for x in a.composed.values())]:
        if cell.n:
            assert 0 <= cell.ci[0] <= cell.rate <= cell.ci[1] <= 1
    # 10 of 20: the normal approximation gives 0.5 ± 0.22
    half = rollup([task(f"t{i:02}", "atomic", [i % 2 == 0]) for i in range(20)]).atomic["ubuntu"]
    assert half.rate == 0.5 and 0.25 <= half.ci[0] <= 0.35 and 0.65 <= half.ci[1] <= 0.75
    # an interval of the SW group does not move when unrelated tasks are added (one RNG per group)
    more = rollup(MIXED + [task("zz-extra", "atomic", [T])], seed=3)
    assert more.composed["sw"] == a.composed["sw"]


def test_interval_values_are_pinned():
    """Pinned so that a change of RNG use, which would change published intervals, is noticed."""
    s = rollup(MIXED)
    assert s.atomic["ubuntu"].ci == (0.0, 1.0) and s.atomic["overall"].ci == (0.2, 1.0)
    ov = s.composed["overall"]
    assert ov.tsr.ci == pytest.approx((0.0, 5 / 6))
    assert ov.ssr.ci == pytest.approx((1 / 3, 11 / 12)) and ov.ssr.pooled_ci == pytest.approx((1 / 3, 0.9))


def test_shuffled_input_gives_identical_json():
    want = summary_json(rollup(MIXED))
    for seed in range(5):
        shuffled = MIXED[:]
        random.Random(seed).shuffle(shuffled)
        assert summary_json(rollup(shuffled)) == want


def test_duplicated_task_keeps_the_finished_result_whatever_the_order():
    running = task("sw-1", "sw", [], status="running")
    a, b = rollup(MIXED + [running]), rollup([running] + MIXED)
    assert summary_json(a) == summary_json(b)
    assert counts(a.composed["sw"].tsr) == (1, 3)
    assert a.warnings == ["task 'sw-1' appears 2 times; kept its failed result"]
    late = task("sw-1", "sw", [T, T], finished="2030-01-01T00:00:00+00:00")  # the later finish wins
    assert rollup(MIXED + [late]).composed["sw"].tsr.k == 2 == rollup([late] + MIXED).composed["sw"].tsr.k


def test_errors_are_excluded_from_rates_and_counted():
    ok = [task("a", "atomic", [T]), task("b", "sw", [T, F])]
    errs = [task(f"e{i}", cat, [], status="error") for i, cat in enumerate(["atomic", "atomic", "sw", "mi"])]
    with_errs, without = rollup(ok + errs), rollup(ok)
    assert with_errs.atomic == without.atomic and with_errs.composed == without.composed
    assert with_errs.errors == {"atomic": 2, "sw": 1, "mi": 1, "md": 0} and with_errs.tasks == 2
    md = render_markdown(with_errs)
    assert "| Errors (excluded) | 2 | 1 | 1 | 0 | 4 |" in md and "excluded from every rate" in md


def test_empty_input_and_empty_categories():
    s = rollup([])
    assert all(c.rate is None and c.ci is None for c in s.atomic.values())
    assert all(c.tsr.rate is None and c.ssr.rate is None and c.ssr.pooled_rate is None for c in s.composed.values())
    assert s.by_subtasks == [] and s.tasks == 0
    md, term = render_markdown(s), render_terminal(s)
    assert "| agent | – | – | – | – |" in md and "Table 3" not in md
    assert "–" in term and "0 tasks counted" in term
    only_atomic = rollup([task("a", "atomic", [T], platforms=("windows",))])
    assert only_atomic.atomic["windows"].text() == "100.0 (1/1)" and only_atomic.composed["overall"].tsr.n == 0


def test_ssr_mean_of_ratios_differs_from_pooled_counts():
    # a 1-subtask task that passed and a 9-subtask task with 0 passed: mean of ratios 0.5, pooled 1/10
    s = rollup([task("x", "md", [T]), task("y", "md", [F] * 9)])
    ssr = s.composed["md"].ssr
    assert ssr.rate == 0.5 and (ssr.k, ssr.n, ssr.pooled_rate) == (1, 10, 0.1)
    assert ssr.text() == "50.0 (1/10)"  # headline is the paper's eq. 2; the counts are subtasks
    assert "| MD SSR (pooled) | 10.0 |" in render_markdown(s)
    # TSR ≤ SSR holds for eq. 2 but not for the pooled ratio: TSR 1/2 here, pooled 1/3
    c = rollup([task("x", "sw", [T]), task("y", "sw", [F, F])]).composed["sw"]
    assert c.tsr.rate == 0.5 == c.ssr.rate and c.ssr.pooled_rate == pytest.approx(1 / 3)


def test_inconsistent_and_unknown_results_are_reported():
    s = rollup([task("p", "sw", [T, F], status="passed"), task("q", "sw", [], status="failed"),
                task("w", "atomic", [T], platforms=("android", "ubuntu")), task("z", "weird", [T])])
    assert s.warnings == [
        "1 task(s) of unknown category 'weird' ignored",
        "atomic task 'w' has platforms ['android', 'ubuntu']: counted in Overall only",
        "task 'p' is passed but 1/2 subtasks passed",
        "task 'q' is failed but has no subtask verdicts",
    ]
    assert s.tasks == 3 and s.atomic["overall"].n == 1 and all(s.atomic[p].n == 0 for p in ("android", "ubuntu"))


def test_markdown_has_the_papers_tables():
    md = render_markdown(rollup(MIXED, agent="oracle"))
    assert md.startswith("# JarvisGUI results — oracle\n")
    assert "| oracle | 50.0 (1/2) | – | 66.7 (2/3) | 60.0 (3/5) |" in md
    assert ("| oracle | 33.3 (1/3) | 50.0 (3/7) | 0.0 (0/2) | 62.5 (4/6) | 100.0 (1/1) | 100.0 (4/4) "
            "| 33.3 (2/6) | 62.5 (11/17) |") in md
    assert r"50.0 & – & 66.7 & 60.0 & 33.3 & 50.0 & 0.0 & 62.5 & 100.0 & 100.0 & 33.3 & 62.5 \\" in md
    assert "| MD TSR | 100.0 | [100.0, 100.0] | 1/1 tasks |" in md
    assert "| 2 | 3 | 33.3 (1/3) | 66.7 | 50.0 (1/2) | 0.0 (0/1) | – |" in md
    assert "| Unfinished | 0 | 1 | 0 | 1 | 2 |" in md


def test_terminal_is_fixed_width():
    lines = render_terminal(rollup(MIXED)).splitlines()
    assert "60.0 (3/5)" in lines[1] and "62.5 (11/17)" in lines[4]
    assert len({len(line) for line in lines[:5]}) == 1  # right-aligned columns line up
    assert "errors (not in rates): atomic 1, md 1; timeouts: 0; skipped (cannot run here): 0; unfinished: 2" in lines[-1]


def write_run(run_dir, results):
    for r in results:
        d = task_dir(run_dir, r.task_id)
        d.mkdir(parents=True)
        (d / "result.json").write_text(r.model_dump_json())


def test_load_skips_broken_files_and_write_is_stable(tmp_path):
    write_run(tmp_path, MIXED)
    for name, data in [("truncated", b'{"task_id": '), ("schema", b'{"task_id": "x"}'), ("empty", b""),
                       ("binary", b"\xff\xfe\x00")]:
        (tmp_path / "tasks" / name).mkdir()
        (tmp_path / "tasks" / name / "result.json").write_bytes(data)
    results, problems = load_results(tmp_path)
    assert len(results) == len(MIXED) and len(problems) == 4
    assert all("skipped" in p for p in problems) and any("/truncated/" in p for p in problems)
    s = write_summary(tmp_path, results, {"name": "noop", "kind": "builtin"})
    text = (tmp_path / "summary.json").read_text(encoding="utf-8")
    assert text == summary_json(s) and text.endswith("}\n") and text.startswith('{\n  "agent": "noop"')
    assert json.loads(text) == s.model_dump(mode="json")
    assert (tmp_path / "summary.md").read_text(encoding="utf-8") == render_markdown(s)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["summary.json", "summary.md", "tasks"]  # no temp files
    shuffled = results[::-1]
    write_summary(tmp_path, shuffled, {"name": "noop"})  # e.g. results gathered from xdist workers
    assert (tmp_path / "summary.json").read_text(encoding="utf-8") == text


def test_n_boot_must_be_positive():
    with pytest.raises(ValueError):
        rollup(MIXED, n_boot=0)


tasks_strategy = st.lists(
    st.tuples(st.sampled_from(["atomic", "sw", "mi", "md"]), st.lists(st.booleans(), min_size=1, max_size=5),
              st.sampled_from(["done", "done", "done", "error", "running"])),
    min_size=1, max_size=14)


@settings(max_examples=100, deadline=None)
@given(tasks_strategy, st.randoms(use_true_random=False))
def test_invariants(items, rnd):
    results = [task(f"t{i:02}", cat, ps if cat != "atomic" else ps[:1], status=None if how == "done" else how)
               for i, (cat, ps, how) in enumerate(items)]
    s = rollup(results, n_boot=100)
    for name, c in s.composed.items():
        if c.tsr.n == 0:
            continue
        # a passed task has every subtask passed, so TSR ≤ SSR, also in every (paired) resample. Not so for the
        # pooled SSR: a passed 1-subtask task and a failed 2-subtask task give TSR 1/2, pooled 1/3.
        assert c.tsr.rate <= c.ssr.rate
        assert c.tsr.ci[0] <= c.ssr.ci[0] and c.tsr.ci[1] <= c.ssr.ci[1]
        for rate, ci in [(c.tsr.rate, c.tsr.ci), (c.ssr.rate, c.ssr.ci), (c.ssr.pooled_rate, c.ssr.pooled_ci)]:
            assert 0 <= ci[0] <= rate <= ci[1] <= 1, (name, rate, ci)
    for c in s.atomic.values():
        assert c.n == 0 or 0 <= c.ci[0] <= c.rate <= c.ci[1] <= 1
    assert s.tasks + sum(s.errors.values()) + sum(s.unfinished.values()) == len(results)
    shuffled = results[:]
    rnd.shuffle(shuffled)
    assert summary_json(rollup(shuffled, n_boot=100)) == summary_json(s)


def test_failure_modes_are_classified_from_verdicts_graph_and_trajectory():
    from jarvis_pytest.results.failure_modes import classify

    def v(i, ok, platform="ubuntu", template="t"):
        return SubtaskVerdict(index=i, template=template, platform=platform, passed=ok)

    both = {"ubuntu", "windows"}
    assert classify([v(0, T), v(1, T)], [(0, 1)], "done", both) is None
    assert classify([v(0, T), v(1, F)], [(0, 1)], "max_steps", both) == "step limit"
    assert classify([v(0, F)], [], "fail", both) == "gave up"
    transfer = [v(0, T, "windows"), v(1, F, "ubuntu", "transfer-windows-to-ubuntu"), v(2, F)]
    assert classify(transfer, [(0, 1), (1, 2)], "done", both) == "transfer failed"
    # the upstream passed, the downstream fed by it failed: the output was not carried on
    assert classify([v(0, T, "windows"), v(1, T, template="transfer-windows-to-ubuntu"), v(2, F)],
                    [(0, 1), (1, 2)], "done", both) == "context lost"
    # independent subtasks, DONE with the Windows one never touched
    assert classify([v(0, T), v(1, F, "windows")], [], "done", {"ubuntu"}) == "done early"
    assert classify([v(0, T), v(1, F, "windows")], [], "done", both) == "subtask failed"
    # a failed upstream makes its downstream's failure no context loss
    assert classify([v(0, F), v(1, F)], [(0, 1)], "done", both) == "subtask failed"


def test_failure_modes_devices_and_stand_ins_in_the_summary():
    a = task("md-a", "md", [T, F], platforms=("ubuntu", "windows"))
    a.failure_mode, a.stand_ins, a.backends = "context lost", ["windows"], {"windows": "windows (wine)"}
    b = task("mi-b", "mi", [T, T], platforms=("ubuntu", "windows"))
    b.stand_ins, b.backends = ["windows"], {"windows": "windows (wine)"}
    c = task("sw-c", "sw", [F, F])
    c.failure_mode = "subtask failed"
    w = task("a-win", "atomic", [T], platforms=("windows",))
    w.stand_ins, w.backends = ["windows"], {"windows": "windows (wine)"}
    s = rollup([a, b, c, w])
    assert s.failure_modes == {"md": {"context lost": 1}, "sw": {"subtask failed": 1}}
    assert [(d.devices, d.k, d.n) for d in s.by_devices] == [(1, 0, 1), (2, 1, 2)]
    assert s.stand_ins == {"windows": ["windows (wine)"]}
    md = render_markdown(s)
    assert "Windows ran on windows (wine)" in md and "| Windows* |" in md
    assert s.stand_in_categories == ["atomic", "md", "mi"]  # sw-c ran on Ubuntu only
    assert "| SW TSR | SW SSR | MI TSR* | MI SSR* | MD TSR* | MD SSR* | Overall TSR* |" in md
    assert "| Model | Android | Windows* | Ubuntu | Overall* |" in md
    term = render_terminal(s)
    assert "MI*" in term and "SW*" not in term and "stand-in device" in term
    assert "Table 4. Success against the number of devices" in md and "Table 5. Failure modes" in md
    assert "| context lost | 0 | 1 | 1 |" in md
