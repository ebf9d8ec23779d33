"""Device faults: a device that fails to start a program that exists (Wine's cmd does so now and then, as if the
program were missing) says so in the command's result (`fault`), and the harness does the work again on fresh
devices instead of blaming the task: set-up, the oracle and each near-miss state, up to
`DEVICE_FAULT_ATTEMPTS` times, with every fault kept in the result.

What is real: the Wine device and its server's detection (a file that exists but is no program: Wine's cmd
answers exactly as it did in the CI run where `reg` failed to start), the Ubuntu devices, the pool, the task's
set-up, oracle, evaluators and negatives. What is injected: which commands fault in the retry tests (a fault
cannot be had on demand), by a wrapper around the real device client that answers one command as the Wine
server answers a fault instead of running it."""

from __future__ import annotations

import json
import uuid
from pathlib import Path

import pytest

from jarvis_pytest.devices.base import CommandResult
from jarvis_pytest.errors import DEVICE_FAULT_ATTEMPTS, DeviceFault
from jarvis_pytest.infra.cleanup import cleanup

pytestmark = pytest.mark.containers
TEMPLATE = Path(__file__).resolve().parents[1] / "tasks" / "ubuntu" / "terminal_zip_folder.json"


def test_wine_says_when_a_program_that_exists_could_not_start(lifecycle):
    env = lifecycle.boot(("windows",))
    try:
        device = env.devices["windows"]
        device.upload(r"C:\faulty\tool.exe", b"not a program\r\n")
        broken = device.run(r"reg add HKCU\Software\Faults /v a /d 1 /f && C:\faulty\tool.exe && echo after")
        assert "tool.exe" in broken.stderr and "completed successfully" in broken.stdout, broken
        assert broken.fault and r"C:\faulty\tool.exe exists" in broken.fault, broken
        # Wine's cmd goes on after a program that could not start (`&&` or not): a later program's return code
        # would hide it, so only `fault` tells
        assert broken.stdout.rstrip().endswith("after"), broken
        hidden = device.run(r"C:\faulty\tool.exe & reg query HKCU\Software\Faults")
        assert hidden.returncode == 0 and hidden.fault, hidden
        missing = device.run("no_such_program_here /x")
        assert missing.returncode == 9009 and missing.fault is None, missing  # really missing: the command's own
        failing = device.run("reg query HKCU\\Software\\NoSuchKeyHere")
        assert failing.returncode == 1 and failing.fault is None, failing
        assert device.run("echo fine").fault is None
    finally:
        env.close()


class FaultyEnvironments:
    """The real pool, except that in the environments handed out as number `faulty` (1-based) the first command
    is answered as a device fault, not run."""

    def __init__(self, pool, faulty: set[int] | None = None, always: bool = False):
        self.pool, self.faulty, self.always, self.handed = pool, faulty or set(), always, 0

    def acquire(self, platforms):
        env = self.pool.acquire(platforms)
        self.handed += 1
        if self.always or self.handed in self.faulty:
            device = env.devices["ubuntu"]
            real_run, state = device.run, {"faulted": False}

            def run(command, **kw):
                if state["faulted"]:
                    return real_run(command, **kw)
                state["faulted"] = True
                return CommandResult(9009, "", "Can't recognize 'zip'", fault=f"injected fault #{self.handed}")

            device.run = run
        return env

    def prewarm(self, platforms):
        self.pool.prewarm(platforms)

    def close(self):
        self.pool.close()


def _run(tmp_path, environments):
    from jarvis_pytest.agents.builtin import OracleAgent
    from jarvis_pytest.harness.runner import RunContext, run_task
    from jarvis_pytest.tasks.instances import atomic_task
    from jarvis_pytest.tasks.library import read_template_file

    [template] = read_template_file(TEMPLATE)
    ctx = RunContext(run_dir=tmp_path, agent=OracleAgent(), environments=environments, qc=True)
    return lambda: run_task(atomic_task(template, 0), ctx)


@pytest.fixture
def pool(device_images):
    from jarvis_pytest.environments.lifecycle import Lifecycle
    from jarvis_pytest.environments.pool import Pool

    run_id = f"test-faults-{uuid.uuid4().hex[:8]}"
    with Pool(Lifecycle(run_id, "test"), enabled=False) as p:
        yield p
    removed = cleanup(run_id)
    assert not any(removed.values()), f"environments left behind: {removed}"


def test_a_device_fault_runs_the_work_again_on_fresh_devices(tmp_path, pool):
    """Environment 1 (the task) faults in set-up: the task runs again on environment 2 and passes the gate;
    environment 3 (the first near-miss state) faults: that negative runs again on environment 4."""
    environments = FaultyEnvironments(pool, faulty={1, 3})
    run = _run(tmp_path, environments)
    result = run()
    assert result.status == "passed", result.error
    assert len(result.device_faults) == 1 and "injected fault #1" in result.device_faults[0]
    assert [len(n.device_faults) for n in result.qc_negatives] == [1] + [0] * (len(result.qc_negatives) - 1)
    assert "injected fault #3" in result.qc_negatives[0].device_faults[0]
    assert not any(n.passed or n.error for n in result.qc_negatives)
    gui_checks = sum(1 for g in result.qc_gui or [] if g.state in ("passed", "failed"))  # each on fresh devices
    assert [g.state for g in result.qc_gui or []] in ([], ["passed"], ["none"]), result.qc_gui
    assert environments.handed == 2 + len(result.qc_negatives) + 1 + gui_checks
    [stored] = [json.loads(p.read_text()) for p in tmp_path.rglob("result.json")]
    assert stored["status"] == "passed" and len(stored["device_faults"]) == 1


def test_a_device_that_keeps_faulting_is_an_infrastructure_error(tmp_path, pool):
    environments = FaultyEnvironments(pool, always=True)
    run = _run(tmp_path, environments)
    with pytest.raises(DeviceFault, match="injected fault"):
        run()
    assert environments.handed == DEVICE_FAULT_ATTEMPTS
    [stored] = [json.loads(p.read_text()) for p in tmp_path.rglob("result.json")]
    assert stored["status"] == "error" and "device fault" in stored["error"]
    assert len(stored["device_faults"]) == DEVICE_FAULT_ATTEMPTS - 1
