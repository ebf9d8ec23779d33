"""The readiness wait shared by the control servers (`/health?wait=S`): held until ready, never past its time."""

from __future__ import annotations

import time

from jarvis_pytest.devices.control_http import HEALTH_RECHECK, readiness_within


def test_a_held_readiness_answer_comes_once_everything_is_up():
    calls = []

    def check() -> dict[str, bool]:
        calls.append(time.monotonic())
        return {"display": True, "panel": len(calls) >= 3}

    assert readiness_within(check, 5.0) == {"display": True, "panel": True}
    assert len(calls) == 3  # asked again every HEALTH_RECHECK seconds, and not once more after it was up
    assert all(b - a >= HEALTH_RECHECK * 0.9 for a, b in zip(calls, calls[1:]))


def test_a_held_readiness_answer_ends_with_the_last_state_when_its_time_is_up():
    calls = []

    def check() -> dict[str, bool]:
        calls.append(1)
        return {"display": True, "painted": False}

    t0 = time.monotonic()
    assert readiness_within(check, 0.3) == {"display": True, "painted": False}
    assert time.monotonic() - t0 < 1.0  # not held past its time (0.3 s; the slack is for a loaded machine)
    assert 2 <= len(calls) <= 0.3 / HEALTH_RECHECK + 1
    calls.clear()
    assert readiness_within(check, 0.0) == {"display": True, "painted": False} and calls == [1]  # no wait: one look
