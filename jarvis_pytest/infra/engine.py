"""Make sure a Docker engine answers: install Debian's docker.io and start dockerd when we are root.

`jarvis engine ensure` is what `make` calls. Anything it cannot do itself it explains: which command to run.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import docker

from jarvis_pytest.errors import InfrastructureError

DOCKERD_LOG = Path("/var/log/jarvis-dockerd.log")
DOCKERD_PIDFILES = (Path("/var/run/docker.pid"), Path("/var/run/docker/containerd/containerd.pid"))


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
        return True
    except ProcessLookupError:
        return False
    except PermissionError:
        return True


def _clear_stale_pidfiles(wait_seconds: float = 30.0) -> None:
    """A daemon killed without cleanup leaves its pid file, and a new dockerd then refuses to start: remove
    files whose process is gone; wait (bounded) for a daemon that is still shutting down."""
    for pidfile in DOCKERD_PIDFILES:
        try:
            pid = int(pidfile.read_text().strip() or 0)
        except (OSError, ValueError):
            continue
        deadline = time.monotonic() + wait_seconds
        while pid and _alive(pid) and time.monotonic() < deadline:
            time.sleep(0.2)
        if not pid or not _alive(pid):
            pidfile.unlink(missing_ok=True)


def client(timeout: int = 120, host: str | None = None) -> docker.DockerClient:
    """A Docker client for `host` (a URL as the Docker SDK takes it: unix://, tcp://, ssh://) or, without one, for
    the local engine ($DOCKER_HOST or its socket); raises InfrastructureError with the fix when none answers."""
    try:
        if host:
            c = docker.DockerClient(base_url=host, timeout=timeout, use_ssh_client=host.startswith("ssh://"))
        else:
            c = docker.from_env(timeout=timeout)
        c.ping()
        return c
    except Exception as exc:  # docker raises several unrelated types here
        if host:
            raise InfrastructureError(
                f"the Docker engine at {host} does not answer ({exc.__class__.__name__}: {exc}); start it, or drop "
                "it from --docker-host / [tool.jarvis] docker_hosts") from exc
        raise InfrastructureError(
            f"no Docker engine answers ({exc.__class__.__name__}: {exc}); run `make engine` "
            "(as root it installs Debian's docker.io and starts dockerd)"
        ) from exc


def _ping(url: str | None = None) -> bool:
    """Whether the engine at `url` (default: the local one) answers within 5 s."""
    try:
        (docker.DockerClient(base_url=url, timeout=5) if url else docker.from_env(timeout=5)).ping()
        return True
    except Exception:
        return False


APT_LOCK_WAIT = 600  # seconds apt waits for another apt or dpkg (unattended upgrades, another install) to finish


POLICY_RC_D = Path("/usr/sbin/policy-rc.d")  # Debian's switch: exit 101 and packages start no service


def _apt_install(*packages: str, start_services: bool = True) -> None:
    """apt-get install, waiting (with a message) while another apt or dpkg holds the lock; one clear error.
    `start_services=False`: what the packages would start (e.g. an sshd on every address) stays stopped."""
    if not start_services and not POLICY_RC_D.exists():
        POLICY_RC_D.write_text("#!/bin/sh\n# jarvis-pytest: no service starts while it installs packages\nexit 101\n")
        POLICY_RC_D.chmod(0o755)
        try:
            return _apt_install(*packages)
        finally:
            POLICY_RC_D.unlink(missing_ok=True)
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    lock = ["-o", f"DPkg::Lock::Timeout={APT_LOCK_WAIT}"]
    print(f"[engine] apt-get install {' '.join(packages)} (waits up to {APT_LOCK_WAIT // 60} min if another apt or "
          "dpkg runs)", flush=True)
    for argv in (["apt-get", *lock, "update", "-q"], ["apt-get", *lock, "install", "-y", "-q", *packages]):
        proc = subprocess.run(argv, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        if proc.returncode != 0:
            tail = proc.stderr.strip().splitlines()[-3:]
            held = any("lock" in line.lower() for line in tail)
            raise InfrastructureError(
                f"`{' '.join(argv)}` failed ({proc.returncode}): {' | '.join(tail) or 'no message'}"
                + ("; another apt or dpkg still holds the lock: wait for it (e.g. unattended-upgrades) and run "
                   "the command again" if held else "; check the network and the Debian mirror"))


def ensure_debian_packages(*packages_by_command: tuple[str, str], start_services: bool = True) -> None:
    """Install (command, package) pairs whose command is missing, when root; otherwise explain.
    `start_services=False`: the packages' services are not started (Debian's policy-rc.d)."""
    missing = [pkg for cmd, pkg in packages_by_command if shutil.which(cmd) is None]
    if not missing:
        return
    if os.geteuid() != 0 or shutil.which("apt-get") is None:
        raise InfrastructureError(f"missing Debian packages {missing}; run: sudo apt-get install -y {' '.join(missing)}")
    _apt_install(*missing, start_services=start_services)


def ensure_engine(wait_seconds: float = 60.0) -> None:
    """Return once a Docker engine answers; install and start one if we can, else raise with the fix."""
    if _ping():
        return
    is_root = os.geteuid() == 0
    if shutil.which("dockerd") is None:
        if not is_root or shutil.which("apt-get") is None:
            raise InfrastructureError(
                "no Docker engine: install one (Debian: `sudo apt-get install -y docker.io`), start it "
                "(`sudo systemctl start docker` or `sudo dockerd &`), and let your user reach it "
                "(`sudo usermod -aG docker $USER`, then log in again)"
            )
        ensure_debian_packages(("dockerd", "docker.io"), ("iptables", "iptables"))
    if not is_root:
        raise InfrastructureError(
            "the Docker engine is installed but not answering: start it (`sudo systemctl start docker` "
            "or `sudo dockerd &`) and check that your user is in the `docker` group"
        )
    if Path("/run/systemd/system").is_dir() and shutil.which("systemctl"):
        subprocess.run(["systemctl", "start", "docker"], check=False)
    daemon = None
    if not _ping():
        _clear_stale_pidfiles()
        print(f"[engine] starting dockerd (log: {DOCKERD_LOG})", flush=True)
        log = open(DOCKERD_LOG, "ab")
        daemon = subprocess.Popen(["dockerd"], stdout=log, stderr=log, stdin=subprocess.DEVNULL,
                                  start_new_session=True)
    deadline = time.monotonic() + wait_seconds
    while time.monotonic() < deadline:
        if _ping():
            print("[engine] Docker engine is up", flush=True)
            return
        if daemon is not None and daemon.poll() is not None:
            break  # dockerd exited: no point in waiting
        time.sleep(0.5)
    tail = DOCKERD_LOG.read_text(errors="replace")[-2000:] if DOCKERD_LOG.exists() else ""
    raise InfrastructureError(f"dockerd did not start (see {DOCKERD_LOG}); last log lines:\n{tail}")


def extra_engine_url(index: int) -> str:
    """The socket URL of extra engine `index` (2, 3, ...) of this machine (`start_extra_engine`)."""
    return f"unix:///run/jarvis-engine-{index}/docker.sock"


def start_extra_engine(index: int, wait_seconds: float = 60.0, tcp_port: int | None = None) -> str:
    """Start (or find running) extra Docker engine `index` (2..50) of this machine and return its URL: a
    `dockerd` of its own (socket and state under /run/jarvis-engine-<index>, images under
    /var/lib/jarvis-engine-<index>, which stay for the next start), its default bridge a bridge of its own
    (`jarvisbr<index>`, 10.250.<index>.1/24: with `--bridge none` dockerd deletes `docker0`, the first
    engine's), its networks in 10.<200+index>.0.0/16 so they never overlap the first engine's, and the firewall
    left to the first engine and the harness (`--iptables=false`; task networks get their rules from
    `infra/egress.py`). With `tcp_port` it also listens on tcp://127.0.0.1:<tcp_port> (no TLS: loopback only,
    and whoever can reach it is root on this machine, as with the socket). Root only."""
    if not 2 <= index <= 50:
        raise InfrastructureError(f"extra engine {index}: give an index from 2 to 50 (1 is the local engine)")
    url = extra_engine_url(index)
    tcp = [] if tcp_port is None else ["--host", f"tcp://127.0.0.1:{int(tcp_port)}"]
    if _ping(url):
        if tcp and not _ping(tcp[1]):
            raise InfrastructureError(f"extra engine {index} runs without {tcp[1]}: stop it (kill the pid in "
                                      f"/run/jarvis-engine-{index}/docker.pid) and start it again with the port")
        return url
    if os.geteuid() != 0 or shutil.which("dockerd") is None:
        raise InfrastructureError("starting another Docker engine needs root and dockerd (`make engine` first)")
    run, data = Path(f"/run/jarvis-engine-{index}"), Path(f"/var/lib/jarvis-engine-{index}")
    run.mkdir(parents=True, exist_ok=True)
    data.mkdir(parents=True, exist_ok=True)
    # Its network store goes: restarted with networks in its store, dockerd 20.10 deleted `docker0`, the first
    # engine's bridge (seen here; a fresh store keeps it). Task networks never outlive a run anyway.
    shutil.rmtree(data / "network", ignore_errors=True)
    bridge = f"jarvisbr{index}"
    if not Path(f"/sys/class/net/{bridge}").exists():
        for cmd in (["ip", "link", "add", "name", bridge, "type", "bridge"],
                    ["ip", "addr", "add", f"10.250.{index}.1/24", "dev", bridge], ["ip", "link", "set", bridge, "up"]):
            proc = subprocess.run(cmd, capture_output=True, text=True)
            if proc.returncode != 0:
                raise InfrastructureError(f"extra engine {index}: `{' '.join(cmd)}` failed: {proc.stderr.strip()}")
    log_path = run / "dockerd.log"
    log = open(log_path, "ab")
    daemon = subprocess.Popen(
        ["dockerd", "--host", url, *tcp, "--data-root", str(data), "--exec-root", str(run / "exec"),
         "--pidfile", str(run / "docker.pid"), "--bridge", bridge, "--iptables=false", "--ip-masq=false",
         "--default-address-pool", f"base=10.{200 + index}.0.0/16,size=24"],
        stdout=log, stderr=log, stdin=subprocess.DEVNULL, start_new_session=True)
    deadline = time.monotonic() + wait_seconds
    while time.monotonic() < deadline:
        if _ping(url):
            return url
        if daemon.poll() is not None:
            break
        time.sleep(0.3)
    tail = log_path.read_text(errors="replace")[-2000:]
    raise InfrastructureError(f"extra engine {index} did not start (see {log_path}); last log lines:\n{tail}")


def stop_extra_engine(index: int, wait_seconds: float = 30.0) -> None:
    """Stop extra engine `index` (its containers stop with it; its images stay in its data root)."""
    pidfile = Path(f"/run/jarvis-engine-{index}/docker.pid")
    try:
        pid = int(pidfile.read_text().strip())
        os.kill(pid, 15)
    except (OSError, ValueError):
        return
    deadline = time.monotonic() + wait_seconds
    while _alive(pid) and time.monotonic() < deadline:
        try:
            if os.waitpid(pid, os.WNOHANG)[0] == pid:  # our own child: reaped, not a zombie
                return
        except ChildProcessError:
            pass
        time.sleep(0.2)


def main_extra(args) -> int:
    """`jarvis engine extra N`: start extra engine N of this machine and print its URL (for --docker-host)."""
    try:
        print(start_extra_engine(args.index, tcp_port=args.tcp))
        if args.tcp:
            print(f"tcp://127.0.0.1:{args.tcp}")
    except InfrastructureError as exc:
        print(f"jarvis engine: error: {exc}", file=sys.stderr)
        return 1
    return 0


def main_ensure(_args=None) -> int:
    """`jarvis engine ensure`: a Docker engine answers, and (as root) the rules that close task networks are in."""
    from jarvis_pytest.infra import egress

    try:
        ensure_engine()
        if os.geteuid() == 0:
            egress.ensure_rules()
    except InfrastructureError as exc:
        print(f"jarvis engine: error: {exc}", file=sys.stderr)
        return 1
    return 0
