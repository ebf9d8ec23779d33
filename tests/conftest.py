"""Shared fixtures of the project's own tests. Container tests never skip: without an engine they fail loudly."""

from __future__ import annotations

import uuid

import pytest
from filelock import FileLock


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
    from jarvis_pytest.infra.lifecycle import Lifecycle

    run_id = f"test-{uuid.uuid4().hex[:8]}"
    yield Lifecycle(run_id, "test")
    cleanup(run_id)


@pytest.fixture(scope="module")
def ubuntu_env(device_images):
    """One booted Ubuntu environment (device + transfer drive) shared by a module's tests."""
    from jarvis_pytest.infra.cleanup import cleanup
    from jarvis_pytest.infra.lifecycle import Lifecycle

    run_id = f"test-{uuid.uuid4().hex[:8]}"
    env = Lifecycle(run_id, "test").boot(("ubuntu",))
    yield env
    env.close()
    cleanup(run_id)
