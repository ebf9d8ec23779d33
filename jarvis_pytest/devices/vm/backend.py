"""A task's VM, from the host: a device backend (`devices/backend.py`) whose device is a runner container in
`restore` mode. The rest is the harness's ordinary device boot (`infra/containers.boot_container`): the container
on the task's network with its labels, its control port published on 127.0.0.1, its default route cut (the
guest's slirp reaches what the container reaches: the task network, where the drive is), ready when the control
server answers, removed with its anonymous volumes (the task's overlay lives in the container's own layer).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from jarvis_pytest.devices.backend import Backend
from jarvis_pytest.devices.vm import golden as golden_files
from jarvis_pytest.devices.vm.prepare import RUNNER_IMAGE, accel_options, failure_of, runner_memory
from jarvis_pytest.devices.vm.profile import Profile
from jarvis_pytest.devices.vm.runner import GOLDEN, SPEC_ENV, events
from jarvis_pytest.errors import ConfigError, InfrastructureError

RESTORE_TIMEOUT = 60.0   # seconds from the container's creation until the restored guest answers (TCG: about 2)
QEMU_MEMORY_MB = 160     # what QEMU holds beside the guest's RAM (TCG's code cache included), about


def task_options(golden: Path, profile: Profile, ready_timeout: float = RESTORE_TIMEOUT) -> dict[str, Any]:
    """docker-py options of a task's runner container: `restore`, the golden read-only, the profile it must have
    been saved with, /dev/kvm where the profile needs it."""
    spec = {"profile": profile.to_dict(), "ready_timeout": ready_timeout}
    return {"command": ["restore"], "environment": {SPEC_ENV: json.dumps(spec)},
            "volumes": {str(Path(golden).resolve()): {"bind": str(GOLDEN), "mode": "ro"}}, **accel_options(profile)}


def restore_figures(container: Any) -> dict[str, Any]:
    """The runner's `ready` event (`seconds` from its start, `phases`, `epoch`) and `created_to_ready`: seconds
    from the engine's creation of the container to that event (one clock: the container's is the host's)."""
    import re
    from datetime import datetime

    ready = [e for e in events(container.logs().decode("utf-8", "replace")) if e.get("vm") == "ready"]
    if not ready:
        return {}
    stamp = re.match(r"(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d)(\.\d{1,6})?", container.attrs["Created"])
    created = datetime.fromisoformat(f"{stamp.group(1)}{stamp.group(2) or ''}+00:00").timestamp()
    return {**ready[-1], "created_to_ready": round(ready[-1]["epoch"] - created, 3)}


@dataclass(frozen=True)
class VmBackend(Backend):
    """A backend whose devices are VMs restored from `golden` with `profile` (see `vm_backend`)."""

    golden: Path = Path(".")
    profile: Profile = field(default_factory=lambda: Profile(name="unset"))

    def boot(self, request: Any) -> Any:
        """Refuse a golden this profile may not restore from (before any container exists), then the ordinary
        boot; an error the runner reports about its input is raised as that ConfigError."""
        golden_files.check(self.golden, self.profile)
        try:
            return super().boot(request)
        except InfrastructureError as exc:
            for c in request.started:
                if c.name == request.name:
                    try:
                        c.reload()
                        state = c.attrs.get("State") or {}
                        logs = c.logs().decode("utf-8", "replace")
                    except Exception:
                        break
                    if not state.get("Running"):
                        failure = failure_of(c, state.get("ExitCode", -1), logs, self.golden)
                        if isinstance(failure, ConfigError):
                            raise failure from None
            raise exc


def unavailable_reason(golden: Path, profile: Profile) -> Callable[[], str | None]:
    def why() -> str | None:
        if profile.accel == "kvm" and not Path("/dev/kvm").exists():
            return "no /dev/kvm on this machine (the profile asks for KVM)"
        try:
            golden_files.check(golden, profile)
        except ConfigError as exc:
            return str(exc)
        return None

    return why


def vm_backend(platform: str, golden: Path, profile: Profile, *, name: str = "vm",
               connect: Callable[[str], Any] | None = None, ready_timeout: float = RESTORE_TIMEOUT,
               memory: str | None = None, stand_in: bool = False, how_to_run: str = "") -> VmBackend:
    """A backend for `platform` whose every device is a VM restored from `golden` (prepared with `profile`):
    register it (`devices.backend.register_backend`) and `Lifecycle.boot` makes task VMs like any device. The
    device is a `DesktopDevice` unless `connect` says otherwise; readiness is its control server's /health."""
    from jarvis_pytest.devices.desktop import DesktopDevice, wait_ready

    golden = Path(golden).resolve()
    return VmBackend(platform=platform, name=name, image=RUNNER_IMAGE, port=profile.control_port,
                     connect=connect or (lambda url: DesktopDevice(url, platform=platform)), wait_ready=wait_ready,
                     container_options=task_options(golden, profile, ready_timeout), ready_timeout=ready_timeout,
                     memory=memory or runner_memory(profile), booted_memory_mb=profile.memory_mb + QEMU_MEMORY_MB,
                     cpus=None, stand_in=stand_in, unavailable=unavailable_reason(golden, profile),
                     how_to_run=how_to_run, golden=golden, profile=profile)
