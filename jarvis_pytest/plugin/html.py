"""pytest-html integration: task columns, the summary tables at the top, first/last screenshots as linked files."""

from __future__ import annotations

import html as _html
import os
from pathlib import Path

import pytest

from jarvis_pytest.plugin.cases import PROPERTY

COLUMNS = ("platform", "category", "subtasks", "steps", "duration (s)")


def _props(report) -> dict | None:
    for name, value in getattr(report, "user_properties", ()):
        if name == PROPERTY:
            return value
    return None


class HtmlHooks:
    """Registered only when pytest-html is active."""

    def __init__(self, config: pytest.Config, session):
        self.config = config
        self.session = session

    def _report_dir(self) -> Path:
        """Where report.html is written: --html when given, else the run directory (the controller's default,
        which xdist workers do not see in their options)."""
        path = getattr(self.config.option, "htmlpath", None)
        return Path(path).resolve().parent if path else self.session.run_dir

    def pytest_html_results_table_header(self, cells: list[str]) -> None:
        cells[2:2] = [f"<th>{c}</th>" for c in COLUMNS]

    def pytest_html_results_table_row(self, report, cells: list[str]) -> None:
        p = _props(report) or {}
        subs = p.get("subtasks", [])
        values = (",".join(p.get("platforms", [])), p.get("category", ""),
                  f"{sum(s['passed'] for s in subs)}/{len(subs)}" if subs else "", p.get("steps", ""),
                  f"{p.get('durations', {}).get('total', 0):.1f}" if p else "")
        cells[2:2] = [f"<td>{_html.escape(str(v))}</td>" for v in values]

    @pytest.hookimpl(hookwrapper=True)
    def pytest_runtest_makereport(self, item, call):
        outcome = yield
        report = outcome.get_result()
        p = _props(report)
        base = self._report_dir()
        if p is None or report.when not in ("call", "setup") or (report.when == "setup" and report.passed):
            return
        import pytest_html

        from jarvis_pytest.results.model import result_key
        from jarvis_pytest.results.writer import safe_name

        task_dir = Path(p["dir"]) / safe_name(result_key(p["task_id"], p.get("trial", 1)))
        extras = getattr(report, "extras", [])
        for label in ("first_screenshot", "last_screenshot"):
            if p.get(label):
                rel = os.path.relpath(task_dir / p[label], base)
                extras.append(pytest_html.extras.url(rel, name=label.replace("_", " ")))
        extras.append(pytest_html.extras.url(os.path.relpath(task_dir / "traj.jsonl", base), name="trajectory"))
        extras.append(pytest_html.extras.url(os.path.relpath(task_dir / "result.json", base), name="result.json"))
        report.extras = extras

    def pytest_html_results_summary(self, prefix, summary, postfix) -> None:
        md = self.session.run_dir / "summary.md"
        if md.exists():
            prefix.append(f"<h2>Task success rates</h2><pre>{_html.escape(md.read_text())}</pre>")


def register(config: pytest.Config, session) -> None:
    """Add the task columns, summary and screenshots to pytest-html's report when it is active."""
    if config.pluginmanager.hasplugin("html"):
        config.pluginmanager.register(HtmlHooks(config, session), "jarvis-html")
