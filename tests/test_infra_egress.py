"""Devices have no way out by default (`infra/egress.py`). Shown from the network's configuration, the host's
firewall and the device's routes — and, for the one address a test may use, a server this host runs reached
through the task network's gateway address: closed by default, open with the opt-in. No traffic goes anywhere
but this machine."""

from __future__ import annotations

import http.server
import socket
import subprocess
import threading
import uuid

import pytest

from jarvis_pytest.infra import egress
from jarvis_pytest.infra.cleanup import cleanup
from jarvis_pytest.environments.lifecycle import Lifecycle

pytestmark = pytest.mark.containers


@pytest.fixture
def host_server():
    """An HTTP server of the host on every address (the gateway address of task networks included)."""
    server = http.server.ThreadingHTTPServer(("0.0.0.0", 0), http.server.SimpleHTTPRequestHandler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield server.server_address[1]
    server.shutdown()
    server.server_close()


def _env(egress_open: bool):
    run_id = f"test-egress-{uuid.uuid4().hex[:6]}"
    env = Lifecycle(run_id, "test", egress=egress_open).boot(("ubuntu",))
    return run_id, env


def _gateway(env) -> str:
    env.network.reload()
    return env.network.attrs["IPAM"]["Config"][0]["Gateway"]


def _host_reachable(env, port: int) -> subprocess.CompletedProcess:
    return env.devices["ubuntu"].run(f"curl -sS -m 4 -o /dev/null -w '%{{http_code}}' http://{_gateway(env)}:{port}/",
                                     timeout=30)


def test_closed_by_default(device_images, host_server):
    run_id, env = _env(egress_open=False)
    try:
        device = env.devices["ubuntu"]
        container = env.containers["ubuntu"]
        # configuration: the bridge is one the host's rules close, with no address translation out
        env.network.reload()
        options = env.network.attrs["Options"]
        assert options["com.docker.network.bridge.name"].startswith("jv-")
        assert options["com.docker.network.bridge.enable_ip_masquerade"] == "false"
        assert egress.rules_present()
        rules = subprocess.run(["iptables", "-S"], capture_output=True, text=True, check=True).stdout
        rules += subprocess.run(["iptables", "-S", "DOCKER-USER"], capture_output=True, text=True, check=True).stdout
        assert "-A DOCKER-USER -i jv+ ! -o jv+ -j DROP" in rules
        assert "-A INPUT -i jv+ -m conntrack ! --ctstate RELATED,ESTABLISHED -j DROP" in rules
        # routes: only the task network, no default route (and no NET_ADMIN to add one back)
        routes = egress.device_routes(container)
        assert routes and not any(r.startswith("default") for r in routes), routes
        denied = device.run("sudo ip route add default via " + _gateway(env), timeout=30)
        assert denied.returncode != 0, denied.stdout + denied.stderr
        # the one address a test may use: a server of this host, through the gateway address: refused
        probe = _host_reachable(env, host_server)
        assert probe.returncode != 0 and probe.stdout.strip() in ("", "000"), probe.stdout + probe.stderr
        # ... while the harness still drives the device and the device still reaches its drive
        assert device.observe().width == 1920
        drive = device.run("curl -sS -m 5 -o /dev/null -w '%{http_code}' -H 'PW: agentPassword' "
                           "'http://transfer:5244/data/?ls'", timeout=30)
        assert drive.stdout.strip() == "200", drive.stdout + drive.stderr
        env.transfer.upload("/data/from_host.txt", b"hello")
        assert device.run("curl -sS -m 5 -H 'PW: agentPassword' http://transfer:5244/data/from_host.txt",
                          timeout=30).stdout == "hello"
    finally:
        env.close()
        cleanup(run_id)


def test_allow_egress_opens_it_and_results_say_so(device_images, host_server):
    run_id, env = _env(egress_open=True)
    try:
        env.network.reload()
        assert env.network.attrs["Options"]["com.docker.network.bridge.name"].startswith("jo-")
        routes = egress.device_routes(env.containers["ubuntu"])
        assert any(r.startswith("default") for r in routes), routes
        probe = _host_reachable(env, host_server)
        assert probe.stdout.strip() == "200", probe.stdout + probe.stderr
        assert env.egress is True
    finally:
        env.close()
        cleanup(run_id)


def test_a_result_records_whether_egress_was_open(device_images, tmp_path):
    import json
    import sys
    from pathlib import Path

    repo = Path(__file__).resolve().parents[1]
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist", str(repo / "tasks"),
           "--results-dir", str(tmp_path), "--instances", "1", "-k", "thunar-rename_file", "--agent", "noop",
           "--allow-egress"]
    subprocess.run(cmd, cwd=repo, capture_output=True, text=True, timeout=300)
    (task,) = (tmp_path / "tasks").iterdir()
    assert json.loads((task / "result.json").read_text())["egress"] is True
    assert json.loads((tmp_path / "run.json").read_text())["egress"] is True


def test_bridge_names_fit_the_kernel_limit():
    name = egress.bridge_name("jarvis-" + "x" * 80, egress=False)
    assert len(name) <= 15 and name.startswith("jv-")
    assert socket.gethostname()  # (the host's own name is what orphan cleanup compares)
