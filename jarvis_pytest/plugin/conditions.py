"""The run card of a run as it starts (`report/run_card.py`): made from the options, the agent and the backends,
with the ids of the images on this machine; under `--reproduce RUN_DIR`, checked against RUN_DIR's card."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable

import pytest

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.plugin.options import JarvisOptions
from jarvis_pytest.report import run_card

if TYPE_CHECKING:
    from jarvis_pytest.devices.backend import Backends


def start_card(options: JarvisOptions, config: pytest.Config, agent_config: dict[str, Any], backends: "Backends",
               argv: list[str]) -> dict[str, Any]:
    """The card of the run about to start; with --reproduce, also what it reproduces (a ConfigError naming each
    condition it does not meet, unless --allow-differences)."""
    from jarvis_pytest.tasks.library import load_library

    o = options
    image_id = _image_ids()
    card = run_card.build(
        agent=agent_config, limits=o.limits, trials=o.trials,
        workers=int(config.getoption("numprocesses", None) or 0), instances=o.instances, library=o.library,
        templates_digest=load_library(o.library).digest(), datasets=o.datasets, devices=_device_records(backends, image_id),
        transfer=_transfer_record(o.transfer, image_id),
        environment={"egress": o.allow_egress, "device_memory": o.device_memory, "device_cpus": o.device_cpus,
                     "backend_options": o.backend_options, "docker_hosts": list(o.docker_hosts)},
        argv=argv, keyword=config.getoption("keyword", "") or "", markers=config.getoption("markexpr", "") or "")
    if o.ray:  # where the devices ran: informational (a node runs the same images, checked by their ids)
        card["machine"]["ray"] = o.ray
    return card if o.reproduce is None else _reproducing(o, card)


def _reproducing(options: JarvisOptions, card: dict[str, Any]) -> dict[str, Any]:
    source = options.reproduce
    meta, expected = run_card.read_card(source, field="--reproduce")
    found = run_card.reproduction_differences(expected, card)
    if found and not options.allow_differences:
        raise ConfigError("this run would not reproduce it:\n  " + "\n  ".join(found), path=source,
                          field="--reproduce", fix="make the conditions match (the same images, backends, harness "
                          "commit, agent settings), or pass --allow-differences to run anyway")
    return {**card, "reproduces": {"run": meta.get("run_id") or source.name, "folder": str(source),
                                   "differences": found}}


def _image_ids() -> Callable[[str], str | None]:
    """A lookup of an image's id on this machine's engine (None: not built or pulled yet, or no engine), on one
    client."""
    try:
        from jarvis_pytest.infra.engine import client

        docker = client(timeout=10)
    except Exception:
        return lambda ref: None

    def image_id(ref: str) -> str | None:
        try:
            return docker.images.get(ref).id
        except Exception:
            return None

    return image_id


def _device_records(backends: "Backends", image_id: Callable[[str], str | None]) -> dict[str, dict[str, Any]]:
    """Per platform: the backend that runs it (or why none does), its image and the device's fixed identity
    (hostname, time zone, locale)."""
    from jarvis_pytest.devices.platforms import PLATFORMS

    out: dict[str, dict[str, Any]] = {}
    for platform, facts in PLATFORMS.items():
        fixed = {"hostname": facts.hostname, "timezone": facts.timezone, "locale": facts.locale}
        if platform in backends:
            b = backends[platform]
            found = image_id(b.image_ref)
            out[platform] = {"backend": b.label, "stand_in": b.stand_in, "image": b.image_ref,
                             "image_ids": [found] if found else [], **fixed}
        else:
            out[platform] = {"backend": None, "unavailable": backends.why_missing(platform), **fixed}
    return out


def _transfer_record(flavour: str | None, image_id: Callable[[str], str | None]) -> dict[str, Any]:
    from jarvis_pytest.infra.transfer_server import transfer_server

    server = transfer_server(flavour)
    return {"flavour": server.flavour, "image": server.image, "image_id": image_id(server.image)}
