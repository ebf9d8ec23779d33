"""The exit status of a benchmark run: an agent's failed tasks are its results, not a failed run.

pytest exits 1 when any test failed. For a run with an agent under evaluation that would make every honest run
(`make bench AGENT=<model>`, `pytest tasks --agent X`) a failed job. So a run whose only failures are tasks the
agent failed (status `failed`: the evaluators said no) exits 0. It keeps pytest's status when

- the agent is the oracle (`--agent oracle`, `--qc`) or the GUI oracle (`--agent gui-oracle`): their solutions
  must pass, any failure is a broken task or a broken GUI solution;
- anything else failed: an infrastructure error, a task `timeout`, a failure outside a task's test body (set-up,
  teardown), a test that is not a task;
- pytest's status is not "tests failed" (interrupted, usage error, internal error, nothing collected).
"""

from __future__ import annotations

from typing import Any, Callable

import pytest

from jarvis_pytest.plugin.cases import PROPERTY

PLUGIN_NAME = "jarvis-exit-status"
ORACLE = "oracle"


def task_status(report: pytest.TestReport) -> str | None:
    """The status of the task result a report carries (None: it carries none)."""
    for name, value in getattr(report, "user_properties", ()) or ():
        if name == PROPERTY and isinstance(value, dict):
            return value.get("status")
    return None


def agent_failure(report: pytest.TestReport) -> bool:
    """Whether a failed report is a task the agent failed: the test body failed on a result with status
    `failed` (the task ran to its end and the evaluators said no)."""
    return report.when == "call" and task_status(report) == "failed"


class ExitStatus:
    """Counts failed reports as the agent's failures or not; once the tests ran, pytest's count of failed tests
    is cleared when every failure was the agent's and the agent is not the oracle (pytest then exits 0)."""

    def __init__(self, oracle: bool | Callable[[], bool]):
        self._oracle = oracle
        self.agent_failures = 0
        self.other_failures = 0
        self.forgiven = False

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        if not report.failed or hasattr(report, "wasxfail"):
            return
        if agent_failure(report):
            self.agent_failures += 1
        else:
            self.other_failures += 1

    @property
    def oracle(self) -> bool:
        """Whether the agent is the oracle (asked when needed: the agent is loaded at start-up)."""
        return bool(self._oracle() if callable(self._oracle) else self._oracle)

    def final(self, exitstatus: int) -> int:
        """The run's exit status given pytest's."""
        if (exitstatus == pytest.ExitCode.TESTS_FAILED and not self.oracle and self.agent_failures
                and not self.other_failures):
            return int(pytest.ExitCode.OK)
        return int(exitstatus)

    @pytest.hookimpl(wrapper=True)
    def pytest_runtestloop(self, session: pytest.Session):
        """Once every task ran: the agent's failures no longer count as failed tests, so pytest's status — and
        what every `pytest_sessionfinish` hook and run.json see — is the run's (0 when they were all)."""
        result = yield
        failed = int(pytest.ExitCode.TESTS_FAILED if session.testsfailed else pytest.ExitCode.OK)
        if self.final(failed) != failed:
            session.testsfailed = 0
            self.forgiven = True
        return result

    def pytest_terminal_summary(self, terminalreporter) -> None:
        if self.forgiven:
            terminalreporter.write_line(
                f"jarvis: {self.agent_failures} task(s) failed by the agent are results, not a failed run: exit 0 "
                "(errors, timeouts and any oracle failure exit 1)")


def register(config: pytest.Config, options: Any, agent: Callable[[], Any]) -> None:
    """Register the exit status's hooks for a run with an agent (`options`: the run's `JarvisOptions`; `agent`:
    gives the loaded agent, or None). The oracle is `--agent oracle`, `--qc`, or the built-in oracle's class
    named as module:Class, or exactly the built-in GUI oracle."""
    from jarvis_pytest.agents.gui_oracle import GuiOracleAgent
    from jarvis_pytest.agents.oracle import OracleAgent

    if options.agent:
        config.pluginmanager.register(ExitStatus(oracle=lambda: options.qc or options.agent == ORACLE
                                                 or isinstance(agent(), OracleAgent)
                                                 or type(agent()) is GuiOracleAgent), PLUGIN_NAME)
