"""The Docker engines of a run: `--docker-host URL` (repeatable) or `docker_hosts = [...]` under `[tool.jarvis]`
in the project's pyproject.toml; neither means the local engine ($DOCKER_HOST or its socket).

- Worker `gw<n>` of pytest-xdist uses engine n mod count (a run without xdist uses the first): a task's devices,
  drive and network are all on its worker's engine, so nothing crosses engines.
- Images are built on the local engine (`jarvis images build`) and copied to every other engine before the
  workers start (`docker save` streamed into `docker load`, only where the image id differs).
- Removing what runs leave (at the start and the end of a run, `jarvis cleanup`) covers every engine.
- Every engine must run on this machine (its own socket, data root and bridges, e.g. a second `dockerd`; any
  transport the Docker SDK takes: unix://, tcp://127.0.0.1:..., ssh://...@127.0.0.1): the harness reaches
  devices only through ports published on 127.0.0.1, and closes their networks with this machine's firewall
  and routes. Several machines run one harness each (README, "Several engines and clusters").
"""

from __future__ import annotations

import socket
import sys
from pathlib import Path
from typing import Any, Iterable, Sequence

from jarvis_pytest.errors import ConfigError, InfrastructureError

SCHEMES = ("unix://", "tcp://", "ssh://", "http://", "https://")
LOCAL = "local"  # how results name the engine of the environment


def check_urls(values: Iterable[str], field: str) -> tuple[str, ...]:
    """The engine URLs, each checked; duplicates dropped. One ConfigError naming the bad value otherwise."""
    out: list[str] = []
    for raw in values:
        url = str(raw).strip()
        if not url.startswith(SCHEMES) or len(url) <= len(url.split("://", 1)[0]) + 3:
            raise ConfigError(f"{raw!r} is not a Docker engine URL", field=field,
                              fix="give unix:///path/to/docker.sock, tcp://127.0.0.1:PORT or ssh://user@host")
        if url not in out:
            out.append(url)
    return tuple(out)


def configured(cli: Sequence[str] | None, rootdir: Path) -> tuple[str, ...]:
    """The engines asked for: the command line's, else `[tool.jarvis] docker_hosts` of rootdir/pyproject.toml."""
    from jarvis_pytest.project_settings import tool_table

    if cli:
        return check_urls(cli, "--docker-host")
    pyproject, table = tool_table(rootdir)
    hosts = table.get("docker_hosts", [])
    if isinstance(hosts, str) or not isinstance(hosts, list):
        raise ConfigError(f"{hosts!r} is not a list", path=pyproject, field="tool.jarvis.docker_hosts",
                          fix='write docker_hosts = ["unix:///var/run/docker.sock", "tcp://127.0.0.1:2375"]')
    return check_urls(hosts, f"{pyproject}: tool.jarvis.docker_hosts")


def for_worker(hosts: Sequence[str], worker: str) -> str | None:
    """The engine of a worker (`gw3`, or `main` without xdist); None is the local engine."""
    if not hosts:
        return None
    index = int(worker[2:]) if worker.startswith("gw") and worker[2:].isdigit() else 0
    return hosts[index % len(hosts)]


def name(host: str | None) -> str:
    """How results and messages name an engine."""
    return host or LOCAL


def check_on_this_machine(host: str | None) -> None:
    """Raise when the engine runs on another machine (its devices' ports and network closure would be there)."""
    from jarvis_pytest.infra.engine import client

    if host is None:
        return
    info = client(timeout=30, host=host).info()
    if info.get("Name") != socket.gethostname():
        raise InfrastructureError(
            f"the Docker engine at {host} runs on {info.get('Name')!r}, not on this machine "
            f"({socket.gethostname()!r}): the harness reaches devices only through ports published on this "
            "machine's 127.0.0.1 and closes their networks with this machine's firewall; run the harness on that "
            "machine (one harness per machine, see the README), or give engines of this machine")


def copy_images(hosts: Sequence[str], tags: Iterable[str], progress=None) -> dict[str, list[str]]:
    """Copy each image (by tag) from the local engine to every engine in `hosts` that lacks the same image id;
    returns engine → tags copied. An image the local engine lacks is an error naming the build command."""
    from jarvis_pytest.infra.engine import client

    say = progress or (lambda msg: print(f"[engines] {msg}", file=sys.stderr, flush=True))
    source = client(timeout=1800)
    wanted: dict[str, Any] = {}
    for tag in dict.fromkeys(tags):
        try:
            wanted[tag] = source.images.get(tag)
        except Exception:
            raise InfrastructureError(f"image {tag} is not on the local engine, so it cannot be copied to the other "
                                      "engines: run `jarvis images build` first") from None
    copied: dict[str, list[str]] = {}
    for host in hosts:
        target = client(timeout=1800, host=host)
        if _identity(target) == _identity(source):
            continue  # the local engine itself, by another URL
        for tag, image in wanted.items():
            try:
                if target.images.get(tag).id == image.id:
                    continue
            except Exception:
                pass
            say(f"copying {tag} to {host}")
            for chunk in target.api.load_image(source.api.get_image(tag)):
                if isinstance(chunk, dict) and chunk.get("error"):
                    raise InfrastructureError(f"copying {tag} to the engine at {host} failed: {chunk['error']}")
            if target.images.get(tag).id != image.id:
                raise InfrastructureError(f"copying {tag} to {host} gave another image id")
            copied.setdefault(host, []).append(tag)
    return copied


def _identity(docker: Any) -> tuple[str, str]:
    """What tells two engines apart: engines of one machine share their `ID` (the key in /etc/docker), not
    their data root."""
    info = docker.info()
    return info.get("Name", ""), info.get("DockerRootDir", "")


def cleanup_everywhere(hosts: Sequence[str], **selection: Any) -> dict[str, int]:
    """`cleanup.cleanup(**selection)` on every engine (the local one when `hosts` is empty); counts summed, then
    the machine's firewall rules of task networks now gone. Every engine is cleaned even when one fails; the
    failures are raised together after."""
    from jarvis_pytest.infra.cleanup import cleanup
    from jarvis_pytest.infra.egress import remove_stale_within_rules

    total = {"containers": 0, "networks": 0, "volumes": 0}
    problems = []
    for host in hosts or (None,):
        try:
            for kind, count in cleanup(host=host, **selection).items():
                total[kind] = total.get(kind, 0) + count
        except InfrastructureError as exc:
            problems.append(f"{name(host)}: {exc}")
    remove_stale_within_rules()  # one firewall for every engine of this machine
    if problems:
        raise InfrastructureError("; ".join(problems))
    return total
