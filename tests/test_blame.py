"""Who is to blame decides the status (issue 37): every row of `harness/blame.py`'s table, with the exceptions and
device answers the harness really meets (httpx's, pydantic's, the model client's, an adapter's own)."""

from __future__ import annotations

import httpx
import pytest
from pydantic import ValidationError

from jarvis_pytest.devices import actions as A
from jarvis_pytest.devices.base import ActionOutcome
from jarvis_pytest.errors import ConfigError, DeviceFault, InfrastructureError
from jarvis_pytest.harness.blame import MESSAGE_LIMIT, blame
from jarvis_pytest.harness.loop import NotAStep, StepDeadline


def _validation_error(data: dict) -> ValidationError:
    try:
        A.parse_action(data)
    except ValidationError as exc:
        return exc
    raise AssertionError(f"{data} is a valid action")


def _raised(make):
    try:
        make()
    except BaseException as exc:  # noqa: BLE001 - the table wants the real exception, whatever it is
        return exc
    raise AssertionError("nothing was raised")


def _status(code: int) -> httpx.HTTPStatusError:
    request = httpx.Request("POST", "http://model/v1/chat/completions")
    return httpx.HTTPStatusError("bad", request=request, response=httpx.Response(code, request=request))


class APIConnectionError(Exception):  # what the openai SDK raises when its endpoint cannot be reached
    pass


class RateLimitError(Exception):  # the openai SDK's 429 after its retries
    pass


class Unprintable(Exception):
    def __str__(self):
        raise RuntimeError("no str")


class AdapterGaveUp(BaseException):  # an adapter's own BaseException: it ends its turn on purpose
    pass


ENDPOINT = ("infrastructure", "error")
STEP = ("agent", "step")
END = ("agent", "end")

TABLE = [
    # -- raised by agent.act: the model endpoint and the harness are `error` ------------------------------------
    ("agent", InfrastructureError("http://m/v1 (model q) failed after 5 attempt(s)"), ENDPOINT, "failed after 5"),
    ("agent", StepDeadline("the agent gave no decision"), ENDPOINT, "no decision"),
    ("agent", ConfigError("refused the API key", field="api_key"), ENDPOINT, "refused the API key"),
    ("agent", DeviceFault("wine could not start it"), ENDPOINT, "wine"),
    ("agent", KeyboardInterrupt(), ENDPOINT, "interrupted"),
    ("agent", httpx.ConnectError("connection refused"), ENDPOINT, "model endpoint failed: ConnectError"),
    ("agent", httpx.ReadTimeout("read timed out"), ENDPOINT, "ReadTimeout"),
    ("agent", _status(503), ENDPOINT, "HTTPStatusError"),
    ("agent", _status(429), ENDPOINT, "HTTPStatusError"),
    ("agent", ConnectionRefusedError(111, "refused"), ENDPOINT, "ConnectionRefusedError"),
    ("agent", TimeoutError("timed out"), ENDPOINT, "TimeoutError"),
    ("agent", APIConnectionError("Connection error."), ENDPOINT, "APIConnectionError"),
    ("agent", RateLimitError("429"), ENDPOINT, "RateLimitError"),
    # -- raised by agent.act: the adapter's code and its parsing of the model's answer are the agent's ------------
    ("agent", _status(400), STEP, "agent error: HTTPStatusError"),  # the adapter sent a bad request
    ("agent", _raised(lambda: int(float("nan"))), STEP, "agent error: ValueError: cannot convert float NaN"),
    ("agent", _raised(lambda: round(float("inf"))), STEP, "agent error: OverflowError"),
    ("agent", _raised(lambda: A.Scroll(dy=10 ** 9)), STEP, "dy: Input should be less than or equal to 100"),
    ("agent", _raised(lambda: A.Typing(text="\ud800")), STEP, "lone surrogate"),
    ("agent", _raised(lambda: {}["action"]), STEP, "agent error: KeyError: 'action'"),
    ("agent", _raised(lambda: None.x), STEP, "agent error: AttributeError"),
    ("agent", RecursionError("maximum recursion depth exceeded"), STEP, "RecursionError"),
    ("agent", NotAStep("the agent's act() returned NoneType, not an AgentStep"), STEP, "returned NoneType"),
    ("agent", Unprintable(), STEP, "agent error: Unprintable"),
    ("agent", ValueError("x" * 10_000), STEP, "agent error: ValueError: xxx"),
    # -- raised by agent.act where the agent cannot go on: the task ends as its failure -------------------------
    ("agent", SystemExit(0), END, "ended its own turn: SystemExit"),
    ("agent", SystemExit("bye"), END, "SystemExit: bye"),
    ("agent", GeneratorExit(), END, "GeneratorExit"),
    ("agent", AdapterGaveUp("stuck"), END, "AdapterGaveUp: stuck"),
    ("agent", MemoryError(), END, "MemoryError"),
    # -- the agent's step is not an action of the action space ---------------------------------------------------
    ("action", _validation_error({"type": "SCROLL", "dy": float("nan")}), STEP, "invalid action: SCROLL.dy"),
    ("action", _validation_error({"type": "CLICK", "x": 1e300, "y": 1}), STEP, "CLICK.x"),
    ("action", _validation_error({"type": "TYPING", "text": "a" * 1_000_000}), STEP, "at most 10000 characters"),
    ("action", _validation_error({"type": "CLIK"}), STEP, "invalid action"),
    ("action", _validation_error({"type": "CLICK", "x": True, "y": 1}), STEP, "CLICK.x: Value error, must be a number"),
    ("action", _validation_error({"type": "WAIT", "seconds": False}), STEP, "WAIT.seconds"),
    ("action", _validation_error({"type": "HOTKEY", "keys": ["ctrl"] * 17}), STEP, "HOTKEY.keys"),
    ("action", _validation_error({"type": "KEY_DOWN", "key": ""}), STEP, "KEY_DOWN.key"),
    ("action", TypeError("an action must be an action of the unified action space, not str"), STEP, "not str"),
    ("action", KeyboardInterrupt(), ENDPOINT, "interrupted"),
    # -- device.act for a valid action: a refusal is the agent's, a failing device the harness's -------------------
    ("device", ActionOutcome(ok=False, error="point (5000, 10) is off the 1920x1080 screen"), STEP, "off the"),
    ("device", ActionOutcome(ok=False, error="PYAUTOGUI script failed: the script ran past its 20 s limit"), STEP,
     "20 s limit"),
    ("device", ActionOutcome(ok=False), STEP, "action failed"),
    ("device", InfrastructureError("ubuntu device at http://127.0.0.1:1 did not answer POST /action"), ENDPOINT,
     "did not answer"),
    ("device", _raised(lambda: "\ud800".encode()), STEP, "could not be sent this action: UnicodeEncodeError"),
    ("device", _raised(lambda: A.Typing.model_construct(text="\ud800").model_dump_json()), STEP,
     "PydanticSerializationError"),
    ("device", AttributeError("'NoneType' object has no attribute 'post'"), ENDPOINT, "harness failed"),
    ("device", KeyboardInterrupt(), ENDPOINT, "interrupted"),
]


@pytest.mark.parametrize("source, problem, verdict, words", TABLE,
                         ids=[f"{i}-{row[0]}-{type(row[1]).__name__}" for i, row in enumerate(TABLE)])
def test_every_row_of_the_table(source, problem, verdict, words):
    got = blame(problem, source)
    assert (got.party, got.effect) == verdict, got
    assert words in got.message, got.message
    if verdict != ENDPOINT:  # an agent's step error is short, whatever it raised (the text is its prefix and a cut)
        assert len(got.message) <= MESSAGE_LIMIT + 60, got.message


def test_an_outcome_that_went_through_is_nobodys_fault():
    with pytest.raises(ValueError, match="nobody's fault"):
        blame(ActionOutcome(ok=True), "device")
