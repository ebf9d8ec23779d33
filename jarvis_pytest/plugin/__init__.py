"""The jarvis pytest plugin (entry point `pytest11: jarvis`): options, then one `JarvisSession` per process,
registered as a plugin, which implements the hooks (collection, the task fixture, results, the rollup)."""

from __future__ import annotations

import pytest

from jarvis_pytest.plugin import exit_status
from jarvis_pytest.plugin import session as _session
from jarvis_pytest.plugin.options import addoption
from jarvis_pytest.plugin.rootdir import redetermine


def pytest_addoption(parser: pytest.Parser) -> None:
    addoption(parser)


@pytest.hookimpl(tryfirst=True)
def pytest_load_initial_conftests(early_config: pytest.Config, parser: pytest.Parser, args: list[str]) -> None:
    redetermine(early_config, args)


@pytest.hookimpl(tryfirst=True)
def pytest_configure(config: pytest.Config) -> None:
    _session.configure(config)
    session = _session.get(config)
    exit_status.register(config, session.options, lambda: session.agent)


@pytest.fixture
def jarvis_result(request: pytest.FixtureRequest, jarvis_task):
    """Run the parametrized task and give its TaskResult; infrastructure errors surface as pytest errors."""
    return _session.get(request.config).run_case(request, jarvis_task)
