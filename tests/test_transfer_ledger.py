"""The transfer drive's ledger on real containers: a Windows (Wine) device that writes and reads the drive through
its shared storage (`S:`) and an Ubuntu device that uses HTTP are both recorded; the ledger's own reads are not;
marks bound the agent's turn; a renewed drive starts an empty ledger; nothing a device does reaches the ledger."""

from __future__ import annotations

import hashlib
import json
import uuid

import pytest

from jarvis_pytest.evaluators.ledger import DriveLedger
from jarvis_pytest.infra import drive_ledger
from jarvis_pytest.environments.lifecycle import TRANSFER_ROLE, Lifecycle
from jarvis_pytest.infra.transfer_server import drive_said

pytestmark = pytest.mark.containers
DRIVE = "http://transfer:5244"
PUT = "curl -fsS -H 'PW: agentPassword' -T {src} " + DRIVE + "/data/{name}"
GET = "curl -fsS -H 'PW: agentPassword' -o {dst} " + DRIVE + "/data/{name}"


def sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


@pytest.fixture(scope="module")
def env(device_images):
    from jarvis_pytest.infra.cleanup import cleanup

    lc = Lifecycle(f"test-ledger-{uuid.uuid4().hex[:6]}", "test")
    env = lc.boot(("ubuntu", "windows"))
    yield env
    env.close()
    lc.close()
    cleanup(lc.run_id)


def ledger(env, start: int | None, end: int | None) -> DriveLedger:
    text, read_object = env.drive_ledger()
    return DriveLedger.parse(text, read_object).between(start, end)


def run_ok(device, command: str):
    res = device.run(command, timeout=60)
    assert res.returncode == 0, (command, res)
    return res


def test_uploads_downloads_and_the_shared_storage_are_recorded_and_the_ledgers_own_reads_are_not(env):
    ubuntu, windows = env.devices["ubuntu"], env.devices["windows"]
    start = env.mark_drive()
    run_ok(ubuntu, "printf 'made on ubuntu' > /tmp/u.txt && " + PUT.format(src="/tmp/u.txt", name="u.txt"))
    run_ok(windows, r'copy /y S:\data\u.txt C:\Users\user\u.txt')                  # Wine reads the shared storage
    run_ok(windows, r'echo made on windows> S:\data\w.txt')                   # and writes it
    run_ok(ubuntu, GET.format(dst="/tmp/w.txt", name="w.txt"))
    run_ok(ubuntu, "printf 'never fetched' > /tmp/n.txt && " + PUT.format(src="/tmp/n.txt", name="n.txt"))
    end = env.mark_drive()
    assert end == start + 1
    turn = ledger(env, start, end)
    by_name = {v.name: v for v in turn.versions}
    assert sorted(by_name) == ["n.txt", "u.txt", "w.txt"]
    assert by_name["u.txt"].sha256 == sha(b"made on ubuntu") and by_name["u.txt"].served == 1
    assert windows.download(r"C:\Users\user\u.txt") == b"made on ubuntu"
    made_on_windows = ubuntu.run("cat /tmp/w.txt").stdout.encode()
    assert by_name["w.txt"].sha256 == sha(made_on_windows) and by_name["w.txt"].served == 1
    assert by_name["n.txt"].served == 0  # hashed and kept by the ledger, which is not a download
    assert turn.content(by_name["u.txt"].sha256) == b"made on ubuntu"
    # what happens after the end mark is not part of the turn
    run_ok(ubuntu, GET.format(dst="/tmp/n2.txt", name="n.txt"))
    assert ledger(env, start, end).named("n.txt")[0].served == 0
    assert ledger(env, end, env.mark_drive()).named("n.txt") == []  # nothing new arrived after the turn


def test_a_version_replaced_on_the_drive_keeps_its_own_reads(env):
    ubuntu = env.devices["ubuntu"]
    start = env.mark_drive()
    run_ok(ubuntu, "printf one > /tmp/r.txt && " + PUT.format(src="/tmp/r.txt", name="r.txt"))
    run_ok(ubuntu, GET.format(dst="/tmp/r1.txt", name="r.txt"))
    run_ok(ubuntu, "printf two > /tmp/r.txt && " + PUT.format(src="/tmp/r.txt", name="r.txt"))
    versions = ledger(env, start, env.mark_drive()).named("r.txt")
    assert [(v.sha256, v.served) for v in versions][-2:] == [(sha(b"one"), 1), (sha(b"two"), 0)]


def test_a_link_a_device_makes_in_the_storage_does_not_reach_the_ledger(env):
    """Under Wine the drive's storage is a volume the device mounts: a symbolic link from it to the ledger is a
    cheap attack. copyparty never follows it out of the drive (`--xvol`), nor does the ledger's watcher."""
    windows = env.containers["windows"]
    code, out = windows.exec_run(["sh", "-c", "ln -s /run/jarvis-ledger/events /mnt/drive/data/evil.txt"],
                                 user="root")
    assert code == 0, out
    start = env.mark_drive()
    before = drive_ledger.read_events(env.containers[TRANSFER_ROLE])
    env.devices["ubuntu"].run("printf '{\"ev\":\"write\"}' > /tmp/e.txt && "
                              + PUT.format(src="/tmp/e.txt", name="evil.txt"))
    end = env.mark_drive()
    after = drive_ledger.read_events(env.containers[TRANSFER_ROLE])
    assert after.startswith(before)
    added = [json.loads(line) for line in after[len(before):].splitlines()]
    assert all({"seq", "ev", "t"} <= set(r) for r in added), added  # only the watcher's records
    assert [r["n"] for r in added if r["ev"] == "mark"] == [end]
    assert all(v.name != "evil.txt" or v.sha256 != sha(b'{"ev":"write"}') or v.path == "/data/evil.txt"
               for v in ledger(env, start, end).versions)


def test_a_renewed_drive_starts_an_empty_ledger(env):
    drive = env.containers[TRANSFER_ROLE]
    generation, _ = drive_said(drive)
    drive.kill(signal="SIGUSR1")
    import time

    deadline = time.monotonic() + 10
    while drive_said(drive)[0] <= generation:
        assert time.monotonic() < deadline
        time.sleep(0.05)
    env.transfer.wait_ready(30)
    fresh = DriveLedger.parse(drive_ledger.read_events(drive))
    assert fresh.versions == []  # an empty drive, an empty ledger
    assert env.mark_drive() == 1


def test_a_link_into_the_drive_at_the_destination_is_not_a_transfer(env):
    """Under Wine the drive is the device's `S:`: a link from the transfer folder to the drive's copy reads the same
    bytes, and reading it through the link is even a read off the drive; nothing was placed on the device."""
    from jarvis_pytest.evaluators.state import FinalState
    from jarvis_pytest.evaluators.transfer import decide

    ubuntu, windows = env.devices["ubuntu"], env.devices["windows"]
    folder, dest = r"C:\Users\user\Downloads\transfer", r"C:\Users\user\Downloads\transfer\linked.txt"
    start = env.mark_drive()
    run_ok(ubuntu, "printf 'carried' > /tmp/linked.txt && " + PUT.format(src="/tmp/linked.txt", name="linked.txt"))
    run_ok(windows, f'if not exist "{folder}" mkdir "{folder}"')
    code, out = env.containers["windows"].exec_run(
        ["sh", "-c", 'ln -s /mnt/drive/data/linked.txt "$WINEPREFIX/drive_c/users/user/Downloads/transfer/linked.txt"'],
        user="root")
    assert code == 0, out
    assert windows.download(dest) == b"carried"  # the link reads the drive's copy (one read off the drive)
    state = FinalState(platform="windows", devices=env.devices, ledger=ledger(env, start, env.mark_drive()))
    verdict = decide(state, "/tmp/linked.txt", "ubuntu", dest).verdict
    assert not verdict.passed and "the drive's own copy" in verdict.reason, verdict.reason
    env.containers["windows"].exec_run(  # (Wine's `del` would delete the link's target on the drive)
        ["sh", "-c", 'rm "$WINEPREFIX/drive_c/users/user/Downloads/transfer/linked.txt"'], user="root")
    run_ok(windows, f'copy /y S:\\data\\linked.txt "{dest}"')  # a real copy passes
    state = FinalState(platform="windows", devices=env.devices, ledger=ledger(env, start, env.mark_drive()))
    assert decide(state, "/tmp/linked.txt", "ubuntu", dest).verdict.passed
