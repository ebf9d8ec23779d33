"""Checks every desktop device's control server must pass, shared by the platforms' device tests."""

from __future__ import annotations

import threading

import httpx

from jarvis_pytest.devices import actions as A


def check_concurrent_requests(device, threads: int = 4, rounds: int = 4) -> None:
    """Actions and screenshots from several threads at once all succeed and leave the desktop healthy."""
    errors: list[BaseException] = []

    def worker(i: int) -> None:
        try:
            for j in range(rounds):
                assert device.act(A.MoveTo(x=100 + i * 10 + j, y=100)).ok
                assert len(device.screenshot()) > 1000
        except BaseException as exc:  # noqa: BLE001 - reported below
            errors.append(exc)

    pool = [threading.Thread(target=worker, args=(i,)) for i in range(threads)]
    for t in pool:
        t.start()
    for t in pool:
        t.join()
    assert not errors and device.health().desktop, errors


def check_refusals_keep_the_server_usable(device, url: str) -> None:
    """A refused upload does not poison a kept-alive connection, and an action the platform lacks is refused."""
    with httpx.Client(base_url=url) as keep_alive:
        assert keep_alive.put("/files", params={"path": "x"}, content=b"GET / HTTP/1.1\r\n\r\n").status_code == 400
        assert keep_alive.get("/health").json()["desktop"]
        for bad in ("soon", "-1", "60"):  # a readiness request may be held 0-5 s, no more
            refused = keep_alive.get("/health", params={"wait": bad})
            assert refused.status_code == 400 and "`wait`" in refused.json()["error"], bad
        assert keep_alive.get("/health", params={"wait": "5"}).json() == {"ok": True, "desktop": True,
                                                                          "details": {"ready": True}}
    assert device.health().desktop
    outcome = device.act(A.SystemButton(button="home"))
    assert not outcome.ok and "SYSTEM_BUTTON" in outcome.error
