"""PID 1 of a VM runner container (`fixtures/images/vm-runner/`): `prepare` a golden or `restore` a task from it.

    python3 -m jarvis_pytest.devices.vm.runner prepare|restore      (the spec: JSON in $JARVIS_VM)

prepare  (golden mounted read-write at /golden): cold-boot an overlay of the base disk, wait until the guest's
         control server answers, run the spec's commands through it, pause, save the memory state to a file
         (migration to a descriptor passed over QMP), check the stream is complete, quit, write READY. Exits 0.
restore  (golden mounted read-only at /golden): check the golden (`golden.check`, with this QEMU's version), make
         the task's overlay of the snapshot disk in /task (the container's own layer, gone with it), start QEMU
         with the same profile and `-incoming`, load the state, resume, set the guest's clock (a restored guest's
         wall clock is the snapshot's) through its control server, run the profile's `after_restore` commands
         there (each must exit 0), and only then forward the control port to the container's port (so "it
         answers" means "it is ready"). Runs until QEMU ends or the container is removed.

One JSON line per event on stdout (`{"vm": "ready", ...}`; the host reads them); the VM's serial console goes
to /run/vm/console.log and its tail into the error event. Exit codes: 2 bad input (ConfigError), 3 the VM failed.
Standard library only: the container has Debian's python3.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
import urllib.error
import urllib.request
import uuid
from pathlib import Path
from typing import Any

from jarvis_pytest.devices.vm import golden
from jarvis_pytest.devices.vm.profile import RUNNER_PORT, Profile, overlay_command
from jarvis_pytest.devices.vm.qmp import Qmp, QmpError
from jarvis_pytest.errors import ConfigError

GOLDEN, TASK, RUN = Path("/golden"), Path("/task"), Path("/run/vm")
SPEC_ENV = "JARVIS_VM"
EXIT_CONFIG, EXIT_FAILED = 2, 3
SAVE_TIMEOUT = 1800.0   # seconds the memory may take to reach its file (4 GiB of a Windows VM: well under a minute)
LOAD_TIMEOUT = 600.0
GUEST_TIMEOUT = 60.0    # seconds a restored guest's control server may take to answer (it was answering)
AFTER_RESTORE_TIMEOUT = 90.0  # seconds each of the profile's `after_restore` commands may take in the guest


class Failure(Exception):
    """The VM, not the input, failed."""


def emit(event: str, **fields: Any) -> None:
    print(json.dumps({"vm": event, **fields}), flush=True)


def events(logs: str) -> list[dict[str, Any]]:
    """The events in a runner's output (its lines that are `emit`'s JSON; the rest is not ours)."""
    found = []
    for line in logs.splitlines():
        if line.startswith('{"vm": '):
            try:
                found.append(json.loads(line))
            except ValueError:
                pass
    return found


def qemu_version() -> str:
    out = subprocess.run(["qemu-system-x86_64", "--version"], capture_output=True, text=True, check=True).stdout
    return out.splitlines()[0].strip()


def tail(path: Path, lines: int = 30) -> str:
    try:
        return "\n".join(path.read_text(errors="replace").splitlines()[-lines:])
    except OSError:
        return ""


class Vm:
    """A running QEMU and its QMP session."""

    def __init__(self, command: list[str]):
        RUN.mkdir(parents=True, exist_ok=True)
        self.log = RUN / "qemu.log"
        self.console = RUN / "console.log"
        self.relay: subprocess.Popen | None = None
        with self.log.open("wb") as out:
            self.proc = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT)
        try:
            self.qmp = Qmp.connect(str(RUN / "qmp.sock"), alive=self.alive)
        except QmpError as exc:
            raise self.failure(str(exc)) from None

    def alive(self) -> bool:
        return self.proc.poll() is None

    def execute(self, command: str, arguments: dict[str, Any] | None = None, fds: list[int] | None = None) -> Any:
        """A QMP command; its failure (QEMU's error, or QEMU gone) says what QEMU and the guest printed last."""
        try:
            return self.qmp.execute(command, arguments, fds)
        except QmpError as exc:
            raise self.failure(str(exc)) from None

    def failure(self, what: str) -> Failure:
        if self.alive():
            self.proc.kill()
        return Failure(f"{what}\n--- QEMU ---\n{tail(self.log)}\n--- guest console ---\n{tail(self.console)}")



def relay_command(profile: Profile) -> list[str]:
    """The container's control port, relayed to the runner's loopback forward. Not a second slirp forward: slirp
    shows a connection from outside the container to the guest with its real source address, which a guest
    without a default route (ours has none) cannot answer; through loopback it comes from slirp's own address."""
    return ["socat", f"TCP-LISTEN:{profile.control_port},fork,reuseaddr", f"TCP:127.0.0.1:{RUNNER_PORT}"]


def guest(profile: Profile, method: str, path: str, body: dict | None = None, timeout: float = 10.0) -> dict:
    """A request to the guest's control server through the runner's own loopback forward."""
    data = json.dumps(body).encode() if body is not None else None
    request = urllib.request.Request(f"http://127.0.0.1:{RUNNER_PORT}{path}", data=data, method=method,
                                     headers={"Content-Type": "application/json"} if data else {})
    with urllib.request.urlopen(request, timeout=timeout) as answer:
        return json.loads(answer.read())


def wait_guest(vm: Vm, profile: Profile, timeout: float) -> None:
    """Until the guest's control server answers /health with `desktop` true. The first asks are short: a restored
    guest's network stack answers at once, but slirp forgot the guest's MAC address (its ARP table is not in the
    state), so the first connection's SYN may wait for slirp's own retransmission (about a second)."""
    deadline = time.monotonic() + timeout
    probe, last = 0.2, "no answer"
    while time.monotonic() < deadline:
        if not vm.alive():
            raise vm.failure(f"QEMU exited (code {vm.proc.returncode}) before the guest's control server answered")
        try:
            if guest(profile, "GET", "/health", timeout=probe).get("desktop"):
                return
            last = "not ready"
        except (OSError, ValueError) as exc:
            last = f"{exc.__class__.__name__}: {exc}"
            time.sleep(0.05)
        probe = min(probe * 2, 2.0)
    raise vm.failure(f"the guest's control server did not answer within {timeout:.0f} s ({last})")


def guest_run(vm: Vm, profile: Profile, command: str, timeout: float = 120.0) -> str:
    """Run `command` in the guest (its control server's /run); its stdout, or a failure naming it."""
    try:
        answer = guest(profile, "POST", "/run", {"command": command, "timeout": timeout}, timeout=timeout + 10)
    except (OSError, ValueError) as exc:
        raise vm.failure(f"guest command {command!r}: no answer ({exc})") from None
    if answer.get("returncode") != 0:
        raise vm.failure(f"guest command {command!r} exited {answer.get('returncode')}: "
                         f"{(answer.get('stderr') or '').strip()[-500:]}")
    return answer.get("stdout", "")


def command_for(profile: Profile, disk: Path, vars_copy: Path | None, vmgenid: str, incoming: bool) -> list[str]:
    return profile.command(root=str(GOLDEN), disk=str(disk), firmware_vars=str(vars_copy or ""),
                           qmp=str(RUN / "qmp.sock"), console=str(RUN / "console.log"), vmgenid=vmgenid,
                           incoming=incoming)


def missing_files(profile: Profile) -> None:
    for name, value in profile.file_fields().items():
        if not (GOLDEN / value).is_file():
            raise ConfigError("a file the profile names is not in the golden folder", path=GOLDEN / value,
                              field=f"profile.{name}", fix="put the file there, or name another")


def own_disk(profile: Profile, backing: str, backing_format: str, vars_from: Path,
             into: Path) -> tuple[Path, Path | None]:
    """The disk and UEFI variables this VM may write, in `into`: an overlay of `backing` (`golden.DISK`) and a copy
    of the variables in `vars_from` (None without UEFI)."""
    disk = into / golden.DISK
    subprocess.run(overlay_command(backing, backing_format, str(disk)), check=True, capture_output=True)
    if not profile.firmware_vars:
        return disk, None
    shutil.copyfile(vars_from / profile.firmware_vars, into / profile.firmware_vars)
    return disk, into / profile.firmware_vars


def prepare(profile: Profile, spec: dict[str, Any]) -> None:
    missing_files(profile)
    version = qemu_version()
    snap = golden.snapshot_dir(GOLDEN)
    if snap.exists():
        shutil.rmtree(snap)
    snap.mkdir()
    disk, vars_copy = own_disk(profile, f"../{profile.disk}", profile.disk_format, GOLDEN, snap)
    t0 = time.monotonic()
    vm = Vm(command_for(profile, disk, vars_copy, str(uuid.uuid4()), incoming=False))
    emit("booting", qemu=version)
    wait_guest(vm, profile, float(spec.get("ready_timeout", 600)))
    booted = time.monotonic() - t0
    emit("guest-ready", seconds=round(booted, 3))
    outputs = [guest_run(vm, profile, c) for c in spec.get("commands", [])]
    time.sleep(float(spec.get("settle", 0)))
    state = snap / f"{golden.STATE}.part"
    t1 = time.monotonic()
    created = time.time()
    vm.execute("stop")
    vm.execute("migrate-set-parameters", {"max-bandwidth": 1 << 40})  # the default throttles to 128 MiB/s
    fd = os.open(state, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    try:
        vm.execute("getfd", {"fdname": "vmstate"}, fds=[fd])
        vm.execute("migrate", {"uri": "fd:vmstate"})
        deadline = time.monotonic() + SAVE_TIMEOUT
        while True:
            status = vm.execute("query-migrate")
            if status.get("status") == "completed":
                break
            if status.get("status") in ("failed", "cancelled") or time.monotonic() > deadline:
                raise vm.failure(f"saving the memory state: {status.get('status')} "
                                 f"({status.get('error-desc', 'out of time')})")
            time.sleep(0.05)
        os.fsync(fd)
    finally:
        os.close(fd)
    saved = time.monotonic() - t1
    try:
        golden.check_stream(state)
    except ConfigError as exc:
        raise vm.failure(f"the saved state is incomplete: {exc}") from None
    vm.execute("quit")
    try:
        vm.proc.wait(timeout=60)
    except subprocess.TimeoutExpired:
        raise vm.failure("QEMU did not quit after saving the state") from None
    os.replace(state, snap / golden.STATE)
    os.sync()
    for path in snap.iterdir():
        path.chmod(0o444)
    files = {rel: golden.file_stamp(GOLDEN / rel) for rel in golden.recorded_files(GOLDEN, profile)}
    size = (snap / golden.STATE).stat().st_size
    record = golden.Record(profile=profile, qemu=version, source=spec.get("source", {}), state_bytes=size,
                           state_sha256=golden.sha256_of(snap / golden.STATE), files=files, created=created,
                           outputs=outputs, timings={"boot_to_ready": round(booted, 3), "save": round(saved, 3)})
    golden.write_record(GOLDEN, record)
    emit("prepared", state_bytes=size, boot_to_ready=round(booted, 3), save=round(saved, 3))


def restore(profile: Profile, spec: dict[str, Any]) -> Vm:
    started = time.time()
    t0 = time.monotonic()
    golden.check(GOLDEN, profile, qemu_version())
    snap = golden.snapshot_dir(GOLDEN)
    TASK.mkdir(parents=True, exist_ok=True)
    disk, vars_copy = own_disk(profile, str(snap / golden.DISK), "qcow2", snap, TASK)
    t_overlay = time.monotonic()
    vm = Vm(command_for(profile, disk, vars_copy, str(uuid.uuid4()), incoming=True))
    t_qemu = time.monotonic()
    fd = os.open(snap / golden.STATE, os.O_RDONLY)
    try:
        vm.execute("getfd", {"fdname": "vmstate"}, fds=[fd])
    finally:
        os.close(fd)
    vm.execute("migrate-incoming", {"uri": "fd:vmstate"})
    deadline = time.monotonic() + LOAD_TIMEOUT
    while (status := vm.execute("query-status")["status"]) == "inmigrate":
        if time.monotonic() > deadline or not vm.alive():
            raise vm.failure("loading the memory state did not finish")
        time.sleep(0.01)
    if status != "paused":
        raise vm.failure(f"after loading the memory state the VM is {status!r}, not paused")
    t_loaded = time.monotonic()
    vm.execute("cont")
    wait_guest(vm, profile, float(spec.get("ready_timeout", GUEST_TIMEOUT)))
    t_answered = time.monotonic()
    guest_run(vm, profile, profile.clock_command.format(epoch=time.time()), timeout=30)
    t_clock = time.monotonic()
    for command in profile.after_restore:  # e.g. Windows maps its drive letter: the golden could not reach it
        guest_run(vm, profile, command, timeout=AFTER_RESTORE_TIMEOUT)
    t_after = time.monotonic()
    vm.relay = subprocess.Popen(relay_command(profile), stdin=subprocess.DEVNULL)
    emit("ready", started=started, epoch=time.time(), seconds=round(time.monotonic() - t0, 3),
         phases={"check_and_overlay": round(t_overlay - t0, 3), "qemu_start": round(t_qemu - t_overlay, 3),
                 "load": round(t_loaded - t_qemu, 3), "resume_to_answer": round(t_answered - t_loaded, 3),
                 "clock": round(t_clock - t_answered, 3), "after_restore": round(t_after - t_clock, 3)})
    return vm


def serve(vm: Vm) -> int:
    """Reap every child (slirp's forwarders end up ours) until QEMU or the relay ends; SIGTERM ends QEMU."""
    def stop(signum: int, frame: Any) -> None:
        if vm.alive():
            vm.proc.terminate()

    signal.signal(signal.SIGTERM, stop)
    while True:
        try:
            pid, status = os.wait()
        except ChildProcessError:
            return 0
        if pid == vm.proc.pid:
            code = os.waitstatus_to_exitcode(status)
            emit("exited", code=code, console=tail(vm.console, 10))
            return 0 if code in (0, -signal.SIGTERM) else EXIT_FAILED
        if vm.relay is not None and pid == vm.relay.pid:
            emit("error", kind="vm", message=f"the control port's relay ended ({os.waitstatus_to_exitcode(status)})")
            vm.proc.kill()
            return EXIT_FAILED


def main(argv: list[str]) -> int:
    if len(argv) != 2 or argv[1] not in ("prepare", "restore"):
        print("usage: python3 -m jarvis_pytest.devices.vm.runner prepare|restore  (spec in $JARVIS_VM)")
        return EXIT_CONFIG
    try:
        spec = json.loads(os.environ.get(SPEC_ENV, ""))
    except ValueError as exc:
        emit("error", kind="config", message=f"${SPEC_ENV} is not JSON: {exc}")
        return EXIT_CONFIG
    try:
        if not isinstance(spec, dict):
            raise ConfigError("the spec must be a JSON object", path=f"${SPEC_ENV}")
        profile = Profile.from_dict(spec.get("profile"), where=f"${SPEC_ENV}")
        if argv[1] == "prepare":
            prepare(profile, spec)
            return 0
        return serve(restore(profile, spec))
    except ConfigError as exc:
        emit("error", kind="config", message=str(exc), path=exc.path, field=exc.field, fix=exc.fix)
        return EXIT_CONFIG
    except (Failure, QmpError, OSError, subprocess.CalledProcessError) as exc:
        detail = getattr(exc, "stderr", None)
        emit("error", kind="vm", message=f"{exc}" + (f": {detail.decode(errors='replace')}" if detail else ""))
        return EXIT_FAILED


if __name__ == "__main__":
    sys.exit(main(sys.argv))
