"""Preparing a golden, from the host: one runner container in `prepare` mode (`runner.py`) with the golden folder
mounted read-write, no network unless one is given, waited for, then removed. What it leaves is the golden's
`snapshot/` folder with READY (`golden.py`), or nothing READY and one error that says why.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any, Sequence

from jarvis_pytest.devices.vm import golden as golden_files
from jarvis_pytest.devices.vm.profile import Profile
from jarvis_pytest.devices.vm.runner import EXIT_CONFIG, GOLDEN, SPEC_ENV, events
from jarvis_pytest.errors import ConfigError, InfrastructureError

RUNNER_IMAGE = "vm-runner"       # fixtures/images/vm-runner/
SAVE_ALLOWANCE = 900.0           # seconds beyond the guest's boot for the commands, the save and the quit
QEMU_OVERHEAD_MB = 512           # memory the runner container gets beyond the guest's RAM


def runner_image() -> str:
    from jarvis_pytest.infra.images import image_tag

    return image_tag(RUNNER_IMAGE)


def accel_options(profile: Profile) -> dict[str, Any]:
    """docker-py options a profile's accelerator needs: /dev/kvm for KVM, nothing for TCG."""
    return {"devices": ["/dev/kvm:/dev/kvm:rwm"]} if profile.accel == "kvm" else {}


def runner_memory(profile: Profile) -> str:
    return f"{profile.memory_mb + QEMU_OVERHEAD_MB}m"


def check_files(golden: Path, profile: Profile) -> None:
    """ConfigError naming the first file the profile names that the golden folder lacks."""
    for name, value in profile.file_fields().items():
        if not (Path(golden) / value).is_file():
            raise ConfigError("a file the machine profile names is not in the golden folder",
                              path=Path(golden) / value, field=f"profile.{name}",
                              fix="put the file there, or name another in the profile")


def failure_of(container: Any, code: int, logs: str, golden: Path) -> Exception:
    """The error a runner that exited with `code` reported (its last `error` event), as the host raises it: a
    ConfigError for bad input (paths in it name the golden on the host), else an InfrastructureError."""
    errors = [e for e in events(logs) if e.get("vm") == "error"]
    if code == EXIT_CONFIG and errors and errors[-1].get("kind") == "config":
        return ConfigError(errors[-1].get("message", "bad input").replace(f"{GOLDEN}/", f"{golden}/"))
    said = errors[-1]["message"] if errors else "no error reported"
    return InfrastructureError(f"VM runner {container.name} exited with code {code}: {said}\n"
                               f"--- last lines of `docker logs {container.name}` ---\n"
                               + "\n".join(logs.splitlines()[-30:]))


def prepare_snapshot(golden: Path, profile: Profile, *, source: dict[str, Any] | None = None,
                     commands: Sequence[str] = (), ready_timeout: float = 600.0, settle: float = 0.0,
                     docker: Any = None, network: str | None = None, labels: dict[str, str] | None = None,
                     options: dict[str, Any] | None = None) -> golden_files.Record:
    """Cold-boot `golden`'s disk with `profile` in a runner container, wait (at most `ready_timeout` s) until the
    guest's control server answers, run `commands` in the guest (each must exit 0; their output is recorded),
    wait `settle` s, save the memory state and mark the golden READY; returns its record. `source` is recorded
    (e.g. the guest image and its digest). `network`: a Docker network the runner joins (default none: the guest
    reaches nothing while it is prepared). `options` are more docker-py options of the container. One prepare of
    a golden at a time (a lock file in it)."""
    from filelock import FileLock

    from jarvis_pytest.infra import containers as ctr
    from jarvis_pytest.infra.engine import client

    golden = Path(golden).resolve()
    profile.check()
    if not golden.is_dir():
        raise ConfigError("the golden folder does not exist", path=golden, fix="give the folder of the base disk")
    check_files(golden, profile)
    docker = docker or client(timeout=600)
    spec = {"profile": profile.to_dict(), "source": source or {}, "commands": list(commands),
            "ready_timeout": ready_timeout, "settle": settle}
    opts = {"command": ["prepare"], "environment": {SPEC_ENV: json.dumps(spec)},
            "volumes": {str(golden): {"bind": str(GOLDEN), "mode": "rw"}}, **accel_options(profile)}
    if network is None:
        opts["network_mode"] = "none"
    opts.update(options or {})
    name = ctr.docker_name("jarvis-vm-prepare", profile.name, str(int(time.time() * 1000)))
    with FileLock(str(golden / ".prepare.lock")):
        container = ctr.start_container(
            docker, runner_image(), name, network=None, port=None, memory=runner_memory(profile),
            labels=labels or ctr.labels("vm-prepare", "main", "vm-prepare", profile.name),
            options={**opts, **({"network": network} if network else {})})
        try:
            try:
                code = container.wait(timeout=ready_timeout + SAVE_ALLOWANCE)["StatusCode"]
            except Exception as exc:  # the engine's read timeout: the runner is stuck
                limit = ready_timeout + SAVE_ALLOWANCE
                raise InfrastructureError(f"preparing {golden} took longer than {limit:.0f} s "
                                          f"({exc.__class__.__name__}); last lines:\n{ctr.logs(container)}") from None
            logs = container.logs().decode("utf-8", "replace")
            if code != 0:
                raise failure_of(container, code, logs, golden)
        finally:
            ctr.remove_all([container])
    record = golden_files.check(golden, profile, None)
    golden_files.check_stream(golden_files.snapshot_dir(golden) / golden_files.STATE)
    return record
