"""The jarvis pytest plugin (entry point `pytest11: jarvis`): options, task collection, the task fixture,
results and the TSR/SSR rollup. Each concern lives in its own module; this one only wires pytest hooks."""

from __future__ import annotations

import pytest

from jarvis_pytest.plugin import session as _session
from jarvis_pytest.plugin.options import addoption


def pytest_addoption(parser: pytest.Parser) -> None:
    addoption(parser)


@pytest.hookimpl(tryfirst=True)
def pytest_configure(config: pytest.Config) -> None:
    _session.configure(config)


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    if "jarvis_task" in metafunc.fixturenames:
        _session.parametrize(metafunc)


def pytest_collection_modifyitems(session: pytest.Session, config: pytest.Config, items: list[pytest.Item]) -> None:
    _session.check_collected(config, items)


def pytest_collection_finish(session: pytest.Session) -> None:
    _session.write_plan(session)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None):
    _session.prewarm_next(item, nextitem)
    yield


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    _session.collect_report(report)


def pytest_terminal_summary(terminalreporter, exitstatus, config: pytest.Config) -> None:
    _session.terminal_summary(terminalreporter, config)


@pytest.hookimpl(tryfirst=True)
def pytest_sessionfinish(session: pytest.Session, exitstatus) -> None:
    _session.finish(session)


@pytest.fixture
def jarvis_result(request: pytest.FixtureRequest, jarvis_task):
    """Run the parametrized task and give its TaskResult; infrastructure errors surface as pytest errors."""
    return _session.run_case(request, jarvis_task)
