"""Who is to blame when a step goes wrong, and what that does to the task (issue 37).

The agent (its adapter code and its model's answers) is to blame for what it produced: an exception of its own
code, an answer it cannot parse, an action the action space or the device refuses. That is its step's error, fed
back in its history, or — where it cannot go on (its code exited the interpreter, ran out of memory, or crashed
`AGENT_CRASH_LIMIT` steps in a row) — the end of the task as the agent's failure (end reason `agent_error`,
status `failed` unless the state it left passes anyway). Either way the task stays in TSR and SSR.

The harness, a device and the model *endpoint* (unreachable, HTTP 5xx or 429 after the retries, too slow) are to
blame for the rest: status `error`, which the rates leave out. An agent's garbage must never land there, or an
agent that emits garbage when stuck would raise its own success rate.

`blame(problem, source)` is the one place that decides; `tests/test_blame.py` holds every row of its table.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from pydantic import ValidationError

from jarvis_pytest.devices.base import ActionOutcome
from jarvis_pytest.errors import ConfigError, InfrastructureError

Source = Literal["agent", "action", "device"]
AGENT_ERROR = "agent_error"  # the end reason of a task the agent's own failure ended
AGENT_CRASH_LIMIT = 3  # the agent's code raising this many steps in a row ends the task as its failure
MESSAGE_LIMIT = 500  # characters of an exception's text kept in a step error

# Exceptions of third-party model clients that mean the endpoint, not the adapter, failed (matched by class name
# along the exception's classes, so that no client library needs importing): openai's, and the standard library's.
ENDPOINT_ERRORS = frozenset({"APIConnectionError", "APITimeoutError", "InternalServerError", "RateLimitError",
                             "ServiceUnavailableError", "TransportError", "HTTPStatusError", "ConnectionError",
                             "TimeoutError", "Timeout", "ReadTimeout"})


@dataclass(frozen=True)
class Verdict:
    """Whose fault a problem is (`party`) and what follows: `step` (the agent's step error, the task goes on),
    `end` (the task ends as the agent's failure, end reason `agent_error`) or `error` (status `error`)."""

    party: Literal["agent", "infrastructure"]
    effect: Literal["step", "end", "error"]
    message: str


def describe(exc: BaseException) -> str:
    """`Type: message` (a pydantic error as `field: problem; ...`), cut to MESSAGE_LIMIT characters."""
    if isinstance(exc, ValidationError):
        text = "; ".join(f"{'.'.join(map(str, e['loc']))}: {e['msg']}" for e in exc.errors(include_url=False))
    else:
        try:
            text = f"{exc.__class__.__name__}: {exc}" if str(exc) else exc.__class__.__name__
        except Exception:  # an exception whose str() raises
            text = exc.__class__.__name__
    return text if len(text) <= MESSAGE_LIMIT else text[:MESSAGE_LIMIT - 3] + "..."


def _endpoint_failure(exc: BaseException) -> bool:
    names = {cls.__name__ for cls in type(exc).__mro__}
    if "HTTPStatusError" in names:  # httpx: only the server's own failures and rate limits are the endpoint's
        status = getattr(getattr(exc, "response", None), "status_code", 0)
        return status >= 500 or status == 429
    return bool(names & ENDPOINT_ERRORS)


def blame(problem: BaseException | ActionOutcome, source: Source) -> Verdict:
    """Whose fault `problem` is. `source`: `agent` (raised by `agent.act`: its code, its parsing, its model
    client), `action` (the agent's step is not a valid step of the action space), `device` (raised by or answered
    from `device.act` for a valid action)."""
    agent, infra = "agent", "infrastructure"
    if isinstance(problem, ActionOutcome):  # the device answered: a refusal of the action is the agent's to read
        if problem.ok:
            raise ValueError("an outcome that is ok is nobody's fault")
        return Verdict(agent, "step", problem.error or "action failed")
    if isinstance(problem, KeyboardInterrupt):  # the run was stopped, whoever's thread saw it
        return Verdict(infra, "error", "interrupted (the run was stopped)")
    if isinstance(problem, (InfrastructureError, ConfigError)):  # raised by the harness's own code, never by garbage
        return Verdict(infra, "error", str(problem))
    if source == "action":
        return Verdict(agent, "step", f"invalid action: {describe(problem)}")
    if source == "device":
        if isinstance(problem, ValueError):  # the action could not be encoded for the device (e.g. a lone surrogate)
            return Verdict(agent, "step", f"the device could not be sent this action: {describe(problem)}")
        return Verdict(infra, "error", f"the harness failed to send an action: {describe(problem)}")
    if _endpoint_failure(problem):
        return Verdict(infra, "error", f"the agent's model endpoint failed: {describe(problem)}")
    if isinstance(problem, MemoryError) or not isinstance(problem, Exception):  # SystemExit, GeneratorExit, ...
        return Verdict(agent, "end", f"the agent's code ended its own turn: {describe(problem)}")
    return Verdict(agent, "step", f"agent error: {describe(problem)}")
