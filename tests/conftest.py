"""Shared fixtures of the project's own tests. Container tests never skip: without an engine they fail loudly."""

from __future__ import annotations

import os
import tempfile
import uuid
from pathlib import Path

import pytest
from filelock import FileLock

# Every run the tests start, in this process or a subprocess, keeps its run lock in one folder of its own: each
# test's start-up sweep then sees the locks and kept records of the others' runs (a sweep reading another folder
# would take a live test run for a dead one), and the host's own runs' records stay out of the tests' reach.
TEST_LOCKS = Path(tempfile.gettempdir()) / "jarvis-runs-of-tests"
os.environ["JARVIS_RUN_LOCKS"] = str(TEST_LOCKS)


CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update",
                 "--no-first-run", "--disable-sync"]


@pytest.fixture(scope="session")
def browser():
    """Debian's Chromium driven by Playwright, one per test process.

    Playwright's sync API runs its event loop in the calling thread, so a second `sync_playwright()` in the same
    process fails while the first is open ("Sync API inside the asyncio loop"): every browser test shares this one.
    """
    from playwright.sync_api import sync_playwright

    if not os.access(CHROMIUM, os.X_OK):
        pytest.fail(f"{CHROMIUM} is missing: install Debian's chromium (apt-get install -y chromium)")
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield b
        b.close()


@pytest.fixture(scope="session")
def device_images(tmp_path_factory) -> dict[str, str]:
    """The device images, built if missing (one builder at a time across xdist workers)."""
    from jarvis_pytest.infra import engine, images

    engine.ensure_engine()  # raises with the fix when no engine can be had: the test errors, loudly
    lock = FileLock(str(tmp_path_factory.getbasetemp().parent / "jarvis-images.lock"))
    with lock:
        return images.build_all()


@pytest.fixture
def lifecycle(device_images):
    """A Lifecycle under a run id of its own; whatever the test leaves is removed after it."""
    from jarvis_pytest.infra.cleanup import cleanup
    from jarvis_pytest.environments.lifecycle import Lifecycle

    run_id = f"test-{uuid.uuid4().hex[:8]}"
    yield Lifecycle(run_id, "test")
    cleanup(run_id)


@pytest.fixture(scope="module")
def ubuntu_env(device_images):
    """One booted Ubuntu environment (device + transfer drive) shared by a module's tests."""
    from jarvis_pytest.infra.cleanup import cleanup
    from jarvis_pytest.environments.lifecycle import Lifecycle

    run_id = f"test-{uuid.uuid4().hex[:8]}"
    env = Lifecycle(run_id, "test").boot(("ubuntu",))
    yield env
    env.close()
    cleanup(run_id)


STANDIN_PLATFORMS = ("standin-a", "standin-b")


def _standin_ready(url: str, timeout: float) -> None:
    """A stand-in device is ready when its `http.server` answers."""
    import time

    import httpx

    from jarvis_pytest.errors import InfrastructureError

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            if httpx.get(url, timeout=1).status_code == 200:
                return
        except httpx.HTTPError:
            pass
        time.sleep(0.05)
    raise InfrastructureError(f"stand-in device at {url} not ready after {timeout:.1f} s")


def standin_backend(platform: str, **changes):
    """A light stand-in device backend for infrastructure tests: a real container of the transfer image whose
    "control server" is `python3 -m http.server` on port 8000 (ready when it answers); a device is its URL.
    `changes` set other fields (e.g. `holder=True`)."""
    from jarvis_pytest.devices.backend import Backend

    return Backend(platform=platform, image="transfer", port=8000, connect=lambda url: url,
                   wait_ready=_standin_ready,
                   container_options={"command": ["python3", "-m", "http.server", "8000"]}, **changes)


def register_standin_backends() -> tuple[str, ...]:
    """Two stand-in device platforms (`standin_backend`), registered."""
    from jarvis_pytest.devices.backend import register_backend

    for platform in STANDIN_PLATFORMS:
        register_backend(standin_backend(platform))
    return STANDIN_PLATFORMS


@pytest.fixture(scope="session")
def standin_platforms(device_images) -> tuple[str, ...]:
    """The stand-in platforms, registered (see `register_standin_backends`)."""
    return register_standin_backends()


def within_rules(network_name: str) -> int:
    """How many firewall rules accept traffic inside the closed task network `network_name`
    (`egress.open_within`): 1 while it exists, 0 once it is removed."""
    import subprocess

    from jarvis_pytest.infra.egress import bridge_name

    bridge = bridge_name(network_name, egress=False)
    rules = subprocess.run(["iptables", "-S", "DOCKER-USER"], capture_output=True, text=True, check=True).stdout
    return rules.count(f"-i {bridge} -o {bridge} -j ACCEPT")


@pytest.fixture
def only_kept_test():
    """`jarvis cleanup --kept` removes every ended run's kept devices: the tests that keep devices or call it take
    turns (under xdist one would remove what another kept while it checks them)."""
    with FileLock(str(TEST_LOCKS.parent / "jarvis-kept-tests.lock")):
        yield
