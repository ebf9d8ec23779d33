"""The transfer drive on real containers: files move between devices through `http://transfer:5244` on the task's
network and between the host and the drive through its 127.0.0.1 port; a password is required, never banned."""

from __future__ import annotations

import json
import shlex
import uuid

import httpx
import pytest

from jarvis_pytest.environments.lifecycle import Lifecycle
from jarvis_pytest.infra.transfer import CopypartyClient, TransferClient

pytestmark = pytest.mark.containers
DRIVE = "http://transfer:5244"


@pytest.fixture(scope="module")
def two_devices(standin_platforms, device_images):
    """One task with two stand-in devices and a drive."""
    from jarvis_pytest.infra.cleanup import cleanup

    lc = Lifecycle(f"test-drive-{uuid.uuid4().hex[:6]}", "test")
    env = lc.boot(standin_platforms)
    yield env
    env.close()
    cleanup(lc.run_id)


def sh(env, platform: str, command: str) -> tuple[int, str]:
    """Run a shell command inside a device's container (docker exec, not the network)."""
    code, out = env.containers[platform].exec_run(["sh", "-c", command])
    return code, out.decode()


def test_files_move_between_two_devices_and_the_host(two_devices):
    env = two_devices
    a, b = sorted(env.devices)
    assert isinstance(env.transfer, TransferClient)
    assert env.transfer.list("/") == (["data"], [])
    # device a uploads with PUT; device b downloads it
    assert sh(env, a, f"printf 'made on a' > /tmp/a.txt && curl -s -o /dev/null -w '%{{http_code}}' -T /tmp/a.txt "
                      f"-H 'PW: agentPassword' {DRIVE}/data/a.txt") == (0, "201")
    assert sh(env, b, f"curl -fsS -H 'PW: agentPassword' {DRIVE}/data/a.txt") == (0, "made on a")
    # a plain PUT onto an existing name replaces it (copyparty's default would keep both under a new name)
    assert sh(env, a, f"printf 'made on a, again' > /tmp/a.txt && curl -s -o /dev/null -w '%{{http_code}}' "
                      f"-T /tmp/a.txt -H 'PW: agentPassword' {DRIVE}/data/a.txt") == (0, "201")
    assert sh(env, b, f"curl -fsS -H 'PW: agentPassword' {DRIVE}/data/a.txt") == (0, "made on a, again")
    assert env.transfer.list("/data") == ([], ["a.txt"])
    # device b uploads with a multipart form (what a browser does); the host downloads it
    code, _ = sh(env, b, f"printf 'made on b' > /tmp/b.txt && curl -fsS -H 'PW: agentPassword' -F f=@/tmp/b.txt "
                         f"{DRIVE}/data/")
    assert code == 0
    assert env.transfer.download("/data/b.txt") == b"made on b"
    # the host uploads; device a downloads with basic auth
    env.transfer.upload("/data/from host/c.txt", b"made on the host")
    assert sh(env, a, f"curl -fsS -u agent:agentPassword '{DRIVE}/data/from%20host/c.txt'") == (0, "made on the host")
    assert env.transfer.walk() == ["/data/a.txt", "/data/b.txt", "/data/from host/c.txt"]


def test_the_real_ubuntu_device_uses_the_drive(ubuntu_env):
    device = ubuntu_env.devices["ubuntu"]
    put = device.run("printf 'made on ubuntu' > /tmp/u.txt && curl -s -o /dev/null -w '%{http_code}' -T /tmp/u.txt "
                     f"-H 'PW: agentPassword' {DRIVE}/data/u.txt")
    assert put.stdout == "201", put
    assert ubuntu_env.transfer.download("/data/u.txt") == b"made on ubuntu"
    ubuntu_env.transfer.upload("/data/h.txt", b"made on the host")
    got = device.run(f"curl -fsS -H 'PW: agentPassword' {DRIVE}/data/h.txt")
    assert got.stdout == "made on the host", got


def test_a_browser_on_the_device_needs_to_log_in_and_then_sees_the_drive(ubuntu_env):
    device = ubuntu_env.devices["ubuntu"]
    chromium = "timeout 60 chromium --headless=new --no-sandbox --disable-gpu --dump-dom"
    anonymous = device.run(f"{chromium} {DRIVE}/ 2>/dev/null", timeout=90, user="user").stdout
    assert 'name="cppwd"' in anonymous and "data/" not in anonymous  # a password form, no files
    logged_in = device.run(f"{chromium} '{DRIVE}/?pw=agentPassword' 2>/dev/null", timeout=90, user="user").stdout
    assert 'href="data/"' in logged_in or "data/" in logged_in, logged_in[-500:]


def test_the_login_form_sets_a_session_cookie(two_devices):
    env = two_devices
    a = sorted(env.devices)[0]
    login = (f"curl -s -o /dev/null -c /tmp/jar -F act=login -F cppwd=agentPassword {DRIVE}/ && "
             f"curl -s -b /tmp/jar '{DRIVE}/?ls'")
    code, out = sh(env, a, login)
    assert code == 0 and json.loads(out)["acct"] == "agent", out[:300]


def test_the_password_is_required_and_mistakes_are_never_banned(two_devices):
    env = two_devices
    url = env.urls["transfer"]
    env.transfer.upload("/data/secret.txt", b"s")
    assert httpx.put(f"{url}/data/x.txt", content=b"x", headers={"PW": "wrong"}).status_code == 403
    assert httpx.put(f"{url}/data/x.txt", content=b"x").status_code in (401, 403)
    assert httpx.get(f"{url}/data/secret.txt").status_code in (401, 403, 404)
    assert httpx.get(f"{url}/?ls").json()["dirs"] == []  # anonymous visitors see nothing
    a = sorted(env.devices)[0]
    assert sh(env, a, f"curl -s -o /dev/null -w '%{{http_code}}' -H 'PW: nope' {DRIVE}/data/secret.txt") == (0, "403")
    # copyparty's default bans an address after 9 *different* wrong passwords within an hour: not here
    for i in range(15):
        httpx.get(f"{url}/data/?ls", headers={"PW": f"wrong-{i}"})
    wrongs = " ; ".join(f"curl -s -o /dev/null -H {shlex.quote(f'PW: bad-{i}')} {DRIVE}/data/" for i in range(15))
    sh(env, a, wrongs)
    assert httpx.get(f"{url}/data/?ls", headers={"PW": "agentPassword"}).status_code == 200
    assert sh(env, a, f"curl -fsS -H 'PW: agentPassword' {DRIVE}/data/secret.txt") == (0, "s")
    assert httpx.URL(url).host == "127.0.0.1"


def test_client_operations(two_devices):
    drive: CopypartyClient = two_devices.transfer
    drive.upload("/data/deep/ér te/x.txt", b"one")
    drive.upload("/data/deep/ér te/x.txt", b"two, overwritten")
    assert drive.list("/data/deep/ér te") == ([], ["x.txt"])
    assert drive.download("data/deep//ér te/x.txt") == b"two, overwritten"
    drive.mkdir("/data/empty")
    assert "empty" in drive.list("/data")[0]
    with pytest.raises(FileNotFoundError):
        drive.download("/data/missing.txt")
    with pytest.raises(FileNotFoundError):
        drive.list("/no/such/folder")
    assert drive.walk("/no/such/folder") == []
    drive.delete("/data/deep/ér te/x.txt")
    assert "/data/deep/ér te/x.txt" not in drive.walk()
    with pytest.raises(FileNotFoundError):
        drive.delete("/data/deep/ér te/x.txt")
