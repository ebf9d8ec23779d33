"""Several Docker engines (`--docker-host`, `infra/engines.py`): the URLs and `[tool.jarvis] docker_hosts` are
checked at start-up; a run of 4 real tasks under -n 2 with the local engine and a second, real `dockerd` of this
machine (its own socket and data root: `jarvis engine extra 2`, shared by the xdist workers) puts each worker's
tasks on its own engine, copies the images there first, and leaves nothing on either; a task network on the
second engine carries a device's traffic to its drive and nothing else; the second engine is also used through
its tcp:// and ssh:// URLs (an sshd of this machine on 127.0.0.1, the real `ssh` client and `docker system
dial-stdio`)."""

from __future__ import annotations

import contextlib
import fcntl
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import within_rules

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.infra import engines
from jarvis_pytest.results.run_state import resource_id

REPO = Path(__file__).resolve().parents[1]
LOCAL_URL = "unix:///var/run/docker.sock"
TCP_PORT = 23752  # the second engine also answers on tcp://127.0.0.1:23752: the same engine through a tcp:// URL
TCP_URL = f"tcp://127.0.0.1:{TCP_PORT}"
SSH_PORT = 23722  # an sshd of the test's own, on 127.0.0.1 only
TASKS = ["-k", "(mousepad-write_note or thunar-rename_file or terminal-count_matches or terminal-zip_folder) and seed0",
         "--instances", "1"]


def test_paramiko_is_imported_only_for_an_ssh_engine():
    """`import docker` would import paramiko (0.19 CPU-s a process); the harness has it imported on first use."""
    code = ("import sys, jarvis_pytest.infra.engine, docker; import paramiko; before = type(paramiko).__name__; "
            "paramiko.SSHClient; print(before, type(sys.modules['paramiko']).__name__, 'paramiko.transport' in "
            "sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.stdout.split() == ["_OnFirstUse", "module", "True"], out.stderr[-2000:]


@pytest.mark.parametrize("url", ["", "docker.sock", "/var/run/docker.sock", "tcp://", "http//x"])
def test_a_bad_engine_url_is_one_clear_error(url):
    with pytest.raises(ConfigError) as err:
        engines.check_urls([url], "--docker-host")
    assert "--docker-host" in str(err.value) and "unix:///path/to/docker.sock" in str(err.value)


def test_engines_come_from_the_command_line_else_pyproject(tmp_path):
    assert engines.configured(None, tmp_path) == ()
    (tmp_path / "pyproject.toml").write_text('[tool.jarvis]\ndocker_hosts = ["unix:///a.sock", "tcp://127.0.0.1:2375", '
                                             '"unix:///a.sock"]\n')
    assert engines.configured(None, tmp_path) == ("unix:///a.sock", "tcp://127.0.0.1:2375")
    assert engines.configured(["ssh://me@127.0.0.1"], tmp_path) == ("ssh://me@127.0.0.1",)
    (tmp_path / "pyproject.toml").write_text('[tool.jarvis]\ndocker_hosts = "unix:///a.sock"\n')
    with pytest.raises(ConfigError, match="tool.jarvis.docker_hosts.*is not a list"):
        engines.configured(None, tmp_path)


def test_workers_are_spread_over_the_engines():
    hosts = ("unix:///a", "unix:///b")
    assert [engines.for_worker(hosts, w) for w in ("gw0", "gw1", "gw2", "gw3", "main")] == \
        ["unix:///a", "unix:///b", "unix:///a", "unix:///b", "unix:///a"]
    assert engines.for_worker((), "gw5") is None


def test_a_bad_engine_option_stops_the_run_before_anything_boots(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", str(REPO / "tasks"),
                           "--agent", "noop", "--results-dir", str(tmp_path), "--docker-host", "docker.sock"],
                          cwd=REPO, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 4 and "--docker-host" in proc.stderr and "Traceback" not in proc.stderr, proc.stderr


@pytest.fixture(scope="module")
def second_engine(device_images, tmp_path_factory):
    """The second engine, shared by every xdist worker that runs tests of this module: the first to need it
    starts it (unless it runs already), the last to be done with it stops it (if this session started it).
    A user holds a shared lock on a file while it uses the engine: the one that can then lock it alone is last."""
    from filelock import FileLock

    from jarvis_pytest.infra.engine import _ping, extra_engine_url, start_extra_engine, stop_extra_engine
    from jarvis_pytest.infra.images import image_tag

    shared = tmp_path_factory.getbasetemp().parent  # the session's folder under xdist
    started_here = shared / "engine-2.started-here"
    bridges = {p.name for p in Path("/sys/class/net").iterdir()} & {"docker0"}  # the first engine's own bridge
    with FileLock(str(shared / "engine-2.lock")):
        running = _ping(extra_engine_url(2))
        if running and not _ping(TCP_URL):  # started before without its TCP listener: started again with it
            stop_extra_engine(2)
            running = False
        url = start_extra_engine(2, tcp_port=TCP_PORT)  # fails loudly when it cannot start: never skipped
        if not running:
            started_here.touch()
        assert _ping(TCP_URL)
        gone = bridges - {p.name for p in Path("/sys/class/net").iterdir()}
        assert not gone, f"starting the second engine removed {gone} (the first engine's default bridge is docker0)"
        engines.copy_images([url], [image_tag("ubuntu"), image_tag("transfer")])
        using = open(shared / "engine-2.users", "a")
        fcntl.flock(using, fcntl.LOCK_SH)
    yield url
    with FileLock(str(shared / "engine-2.lock")):
        using.close()  # this worker's shared lock goes with it
        with open(shared / "engine-2.users", "a") as probe:
            try:
                fcntl.flock(probe, fcntl.LOCK_EX | fcntl.LOCK_NB)
                last = True
            except OSError:
                last = False  # another worker still uses the engine
        if last and started_here.exists():  # its images stay in its data root for the next time
            stop_extra_engine(2)
            started_here.unlink()
    gone = bridges - {p.name for p in Path("/sys/class/net").iterdir()}
    assert not gone, f"the second engine removed {gone} (the first engine's default bridge is docker0)"


def _leftovers(url: str | None, run_id: str) -> list[str]:
    from jarvis_pytest.infra.engine import client

    api = client(host=url).api
    label = {"label": f"org.jarvis.run={run_id}"}
    return ([c["Names"][0] for c in api.containers(all=True, filters=label)]
            + [n["Name"] for n in api.networks(filters=label)]
            + [v["Name"] for v in (api.volumes(filters=label) or {}).get("Volumes") or []])


@contextlib.contextmanager
def device_on(url: str, second_engine: str):
    """An Ubuntu task environment booted through `url` (found to run on this machine), whose device is on the
    second engine; afterwards closed and cleaned up through `url`, with nothing of it left on the second engine."""
    import uuid

    from jarvis_pytest.infra.cleanup import cleanup
    from jarvis_pytest.infra.engine import client
    from jarvis_pytest.environments.lifecycle import Lifecycle

    run_id = f"test-engine2-{uuid.uuid4().hex[:8]}"
    engines.check_on_this_machine(url)
    env = Lifecycle(run_id, "test", docker_host=url).boot(("ubuntu",))
    try:
        assert env.engine == url
        assert env.containers["ubuntu"].id in {c.id for c in client(host=second_engine).containers.list()}
        yield env
    finally:
        env.close()
    cleanup(run_id, host=url)
    assert _leftovers(second_engine, run_id) == [] and _leftovers(url, run_id) == []


@pytest.mark.containers
def test_a_run_of_four_tasks_uses_both_engines_and_leaves_nothing(second_engine, tmp_path):
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", str(REPO / "tasks"), "--agent", "oracle",
           "-n", "2", "--results-dir", str(tmp_path), "--docker-host", LOCAL_URL, "--docker-host", second_engine,
           *TASKS]
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=1200)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    results = [json.loads(p.read_text()) for p in tmp_path.glob("tasks/*/result.json")]
    assert len(results) == 4 and all(r["status"] == "passed" for r in results), [r["error"] for r in results]
    assert {r["engine"] for r in results} == {LOCAL_URL, second_engine}
    assert json.loads((tmp_path / "run.json").read_text())["engines"] == [LOCAL_URL, second_engine]
    run_id = resource_id(tmp_path)
    assert _leftovers(None, run_id) == [] and _leftovers(second_engine, run_id) == []
    rules = subprocess.run(["iptables", "-S", "DOCKER-USER"], capture_output=True, text=True).stdout
    assert all(Path(f"/sys/class/net/{line.split()[3]}").exists()
               for line in rules.splitlines() if line.startswith("-A DOCKER-USER -i jv-") and " -o jv-" in line)


@pytest.mark.containers
def test_a_task_network_on_the_second_engine_is_closed_but_reaches_its_drive(second_engine, tmp_path):
    """The second engine leaves the firewall alone (`--iptables=false`): the harness's own rules carry a device's
    traffic to its drive, and its default route is gone as on the first engine (read from routes, never probed
    outside). The engine is reached through its tcp:// URL here (the run above used its unix:// one)."""
    from jarvis_pytest.infra.egress import device_routes

    with device_on(TCP_URL, second_engine) as env:
        res = env.devices["ubuntu"].run("curl -s -o /dev/null -w '%{http_code}' --max-time 10 http://transfer:5244/")
        assert res.returncode == 0 and res.stdout.strip() in {"200", "401", "403"}, res
        routes = device_routes(env.containers["ubuntu"])
        assert routes and not any(r.startswith("default") for r in routes), routes
        assert all(r.split()[0].startswith("10.202.") for r in routes), routes  # its own address pool
    assert within_rules(env.network.name) == 0


@pytest.fixture(scope="module")
def ssh_engine(second_engine, tmp_path_factory):
    """`ssh://root@127.0.0.1:23722`: an sshd of this machine (Debian's openssh-server, installed without starting
    its service) on 127.0.0.1 only, with its own host key and one authorised key, whose sessions reach the second
    engine (`SetEnv DOCKER_HOST`). The Docker SDK runs the real `ssh` client; the `ssh` first on PATH adds the
    client settings (key, known host) a user keeps in ~/.ssh/config, so the machine's own are left alone."""
    import os
    import socket
    import time

    from jarvis_pytest.infra.engine import ensure_debian_packages

    ensure_debian_packages(("sshd", "openssh-server"), start_services=False)
    d = tmp_path_factory.mktemp("ssh")
    for key in ("host", "client"):
        subprocess.run(["ssh-keygen", "-q", "-t", "ed25519", "-N", "", "-f", str(d / key)], check=True)
    (d / "authorized_keys").write_text((d / "client.pub").read_text())
    (d / "sshd_config").write_text(
        f"ListenAddress 127.0.0.1\nPort {SSH_PORT}\nHostKey {d / 'host'}\nAuthorizedKeysFile {d / 'authorized_keys'}\n"
        "PermitRootLogin prohibit-password\nPasswordAuthentication no\nKbdInteractiveAuthentication no\n"
        f"UsePAM no\nStrictModes no\nPidFile none\nSetEnv DOCKER_HOST={second_engine}\n")
    host_key = " ".join((d / "host.pub").read_text().split()[:2])
    (d / "known_hosts").write_text(f"[127.0.0.1]:{SSH_PORT} {host_key}\n")
    (d / "ssh_config").write_text(
        f"Host 127.0.0.1\n  IdentityFile {d / 'client'}\n  IdentitiesOnly yes\n  UserKnownHostsFile {d / 'known_hosts'}\n"
        "  StrictHostKeyChecking yes\n  BatchMode yes\n")
    (d / "bin").mkdir()
    (d / "bin" / "ssh").write_text(f'#!/bin/sh\nexec /usr/bin/ssh -F {d / "ssh_config"} "$@"\n')
    (d / "bin" / "ssh").chmod(0o755)
    Path("/run/sshd").mkdir(exist_ok=True)  # sshd's privilege separation directory
    sshd = subprocess.Popen([shutil.which("sshd"), "-D", "-e", "-f", str(d / "sshd_config")],
                            stderr=open(d / "sshd.log", "w"))
    deadline = time.monotonic() + 20
    while True:
        try:
            socket.create_connection(("127.0.0.1", SSH_PORT), timeout=1).close()
            break
        except OSError:
            assert sshd.poll() is None and time.monotonic() < deadline, (d / "sshd.log").read_text()
            time.sleep(0.1)
    path = os.environ["PATH"]
    os.environ["PATH"] = f"{d / 'bin'}:{path}"
    try:
        yield f"ssh://root@127.0.0.1:{SSH_PORT}", d / "sshd.log"
    finally:
        os.environ["PATH"] = path
        sshd.terminate()
        sshd.wait(10)


@pytest.mark.containers
def test_a_device_on_the_second_engine_through_ssh(ssh_engine, second_engine):
    """Through ssh://: the engine is found to run on this machine, a device boots on it (the second engine, as
    its containers show), runs a command, and its task's resources are removed, with nothing left."""
    url, sshd_log = ssh_engine
    with device_on(url, second_engine) as env:
        res = env.devices["ubuntu"].run("echo through-ssh")
        assert res.returncode == 0 and res.stdout.strip() == "through-ssh", res
    assert "Accepted publickey for root from 127.0.0.1" in sshd_log.read_text()  # it went through the sshd
