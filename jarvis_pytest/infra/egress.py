"""Devices have no way out: a task network reaches only its own devices and its drive.

How (no traffic is ever sent to find out — the closure is read back from configuration and routes):

- A task network is a Docker bridge named `jv-<id>` (`com.docker.network.bridge.name`) with masquerading off
  (`enable_ip_masquerade=false`): nothing leaving it is translated to the host's address.
- Two host firewall rules match every such bridge by name (`jv+`): in `DOCKER-USER`, traffic from a task bridge
  to any other interface is dropped (the internet, the local network, link-local addresses such as a cloud
  machine's metadata service, other Docker networks); in `INPUT`, new connections from a task bridge to the
  host itself are dropped (the gateway address and every other address of the host). Replies to the harness's
  own connections through the ports published on 127.0.0.1 are still accepted.
- Traffic within one task bridge is accepted by a rule of that bridge alone (`DOCKER-USER -i jv-X -o jv-X`,
  added with the network and removed with it): an engine that leaves the firewall to others (a second `dockerd`
  with `--iptables=false`, `infra/engines.py`) gets no rules of its own, and the host's FORWARD policy would
  otherwise drop its devices' traffic to their drive. Traffic between two task bridges stays dropped.
- Each device's default route is deleted inside its network namespace (`nsenter`, from the host): `ip route`
  in a device shows only its task network. A device has no `NET_ADMIN` capability, so not even root inside it
  can put a route back.

With `--allow-egress` a task network is an ordinary Docker bridge (`jo-<id>`, masquerading on, no rule, routes
kept) and every result records `egress: true`. The rules need root: `jarvis engine ensure` (run by `make`)
installs them; a run that is not root and finds them missing stops with that fix.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path
from typing import Any

from jarvis_pytest.errors import InfrastructureError

CLOSED_PREFIX = "jv"   # bridge names of task networks without egress: jv-<12 hex>
OPEN_PREFIX = "jo"     # bridge names of task networks with --allow-egress
MARKER = Path("/run/jarvis-egress-rules")  # written once the rules are in place (gone at reboot, as the rules)
RULES: tuple[tuple[str, ...], ...] = (
    ("DOCKER-USER", "-i", f"{CLOSED_PREFIX}+", "!", "-o", f"{CLOSED_PREFIX}+", "-j", "DROP"),
    ("INPUT", "-i", f"{CLOSED_PREFIX}+", "-m", "conntrack", "!", "--ctstate", "ESTABLISHED,RELATED", "-j", "DROP"),
)


def bridge_name(network_name: str, egress: bool) -> str:
    """The host interface name of a task network's bridge (at most 15 characters)."""
    import hashlib

    digest = hashlib.sha256(network_name.encode()).hexdigest()[:12]
    return f"{OPEN_PREFIX if egress else CLOSED_PREFIX}-{digest}"


def network_options(network_name: str, egress: bool) -> dict[str, str]:
    """Docker driver options of a task network."""
    opts = {"com.docker.network.bridge.name": bridge_name(network_name, egress)}
    if not egress:
        opts["com.docker.network.bridge.enable_ip_masquerade"] = "false"
    return opts


def _iptables(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["iptables", "-w", "10", *args], capture_output=True, text=True)


def rules_present() -> bool:
    """Whether both rules are in the host's firewall (root), or the marker says so (not root)."""
    if os.geteuid() != 0:
        return MARKER.exists()
    return shutil.which("iptables") is not None and all(_iptables("-C", *rule).returncode == 0 for rule in RULES)


def ensure_rules() -> None:
    """Install the rules when missing (root); otherwise raise with the fix."""
    if rules_present():
        return
    if os.geteuid() != 0 or shutil.which("iptables") is None:
        raise InfrastructureError(
            "devices could reach the host and the network: the firewall rules that close task networks are not "
            "installed; run `sudo jarvis engine ensure` once (it installs them until the next reboot), or pass "
            "--allow-egress to run with devices open to the network (recorded in every result)")
    if _iptables("-L", "DOCKER-USER", "-n").returncode != 0:
        _iptables("-N", "DOCKER-USER")  # Docker makes it when it starts; make sure either way
    for rule in RULES:
        _insert_rule(rule)
    try:
        MARKER.write_text("jarvis-pytest task networks are closed by iptables rules on jv+ bridges\n")
    except OSError:
        pass


def _insert_rule(rule: tuple[str, ...]) -> None:
    """Put `rule` (chain first) at the top of its chain unless it is there already."""
    if _iptables("-C", *rule).returncode != 0:
        proc = _iptables("-I", rule[0], "1", *rule[1:])
        if proc.returncode != 0:
            raise InfrastructureError(f"cannot install firewall rule `iptables -I {' '.join(rule)}`: "
                                      f"{proc.stderr.strip()}")


def _within(bridge: str) -> tuple[str, ...]:
    return ("DOCKER-USER", "-i", bridge, "-o", bridge, "-j", "ACCEPT")


def open_within(network_name: str) -> None:
    """Accept traffic inside the closed task network `network_name` (root; otherwise the engine's own rules must)."""
    if os.geteuid() != 0 or shutil.which("iptables") is None:
        return
    _insert_rule(_within(bridge_name(network_name, egress=False)))


def close_within(network_name: str) -> None:
    """Remove the rule of `open_within` (idempotent)."""
    if os.geteuid() == 0 and shutil.which("iptables") is not None:
        _iptables("-D", *_within(bridge_name(network_name, egress=False)))


def remove_stale_within_rules() -> int:
    """Remove the `open_within` rules whose bridge is gone (a run killed before it removed them); their count."""
    if os.geteuid() != 0 or shutil.which("iptables") is None:
        return 0
    removed = 0
    for line in _iptables("-S", "DOCKER-USER").stdout.splitlines():
        parts = line.split()
        if len(parts) == 8 and parts[2] == "-i" and parts[4] == "-o" and parts[3] == parts[5] \
                and parts[3].startswith(f"{CLOSED_PREFIX}-") and not Path(f"/sys/class/net/{parts[3]}").exists():
            removed += _iptables("-D", *_within(parts[3])).returncode == 0
    return removed


def cut_default_route(container: Any) -> None:
    """Delete the device's default route inside its network namespace (from the host; needs root)."""
    if os.geteuid() != 0 or shutil.which("nsenter") is None:
        return  # the firewall rules alone close the network
    container.reload()
    pid = (container.attrs.get("State") or {}).get("Pid")
    if not pid:
        return  # the device already exited: nothing can leave it, and the boot reports its exit and logs
    proc = subprocess.run(["nsenter", "-t", str(pid), "-n", "ip", "route", "del", "default"],
                          capture_output=True, text=True)
    if proc.returncode != 0 and "No such process" not in proc.stderr and "No such file" not in proc.stderr:
        container.reload()
        if not (container.attrs.get("State") or {}).get("Running"):
            return  # it exited while the route was being cut; the boot reports why
        raise InfrastructureError(f"cannot remove the default route of {container.name}: {proc.stderr.strip()}")


def device_routes(container: Any) -> list[str]:
    """The device's routing table as `ip route` prints it, read from the host (for tests and reports)."""
    container.reload()
    pid = container.attrs["State"]["Pid"]
    proc = subprocess.run(["nsenter", "-t", str(pid), "-n", "ip", "route"], capture_output=True, text=True,
                          check=True)
    return [line for line in proc.stdout.splitlines() if line.strip()]
