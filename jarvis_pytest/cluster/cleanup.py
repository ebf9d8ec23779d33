"""Removing what runs left on every node of a Ray cluster: `infra/cleanup.cleanup` run on each live jarvis node,
on that node's own engine (a Ray task pinned to the node). A node that is down now is cleaned when it is back:
run `jarvis cleanup --ray ADDRESS` (with `--run`) again then."""

from __future__ import annotations

from typing import Any

from jarvis_pytest.cluster.connect import connect, jarvis_nodes
from jarvis_pytest.errors import InfrastructureError

CLEANUP_TIMEOUT = 600.0


def cleanup_nodes(address: str, field: str = "--ray", **selection: Any) -> dict[str, int]:
    """`cleanup(**selection)` on every live jarvis node of the cluster: the counts summed; InfrastructureError naming
    each node that could not be cleaned (after all were tried)."""
    from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

    from jarvis_pytest.cluster.node import cleanup_here

    ray = connect(address, field)
    remote = ray.remote(cleanup_here)
    nodes = jarvis_nodes(ray)
    refs = [remote.options(num_cpus=0, max_retries=0,
                           scheduling_strategy=NodeAffinitySchedulingStrategy(n.node_id, soft=False)).remote(selection)
            for n in nodes]
    total = {"containers": 0, "networks": 0, "volumes": 0}
    problems = []
    for node, ref in zip(nodes, refs):
        try:
            answer = ray.get(ref, timeout=CLEANUP_TIMEOUT)
        except Exception as exc:
            problems.append(f"node {node.address} {node.short}: {exc.__class__.__name__}")
            continue
        for kind, count in answer["counts"].items():
            total[kind] = total.get(kind, 0) + count
        if answer["error"]:
            problems.append(f"node {answer['hostname']} {node.short} ({answer['engine']}): {answer['error']}")
    if problems:
        raise InfrastructureError("; ".join(problems))
    return total


def cleanup_everywhere(hosts: tuple[str, ...] | list[str], ray: str | None, field: str = "--ray",
                       **selection: Any) -> dict[str, int]:
    """`infra/engines.cleanup_everywhere(hosts, ...)` (this machine's engines), and with `ray` also every live node
    of that cluster: the counts summed."""
    from jarvis_pytest.infra import engines

    counts = engines.cleanup_everywhere(tuple(hosts), **selection)
    if ray:
        for kind, n in cleanup_nodes(ray, field, **selection).items():
            counts[kind] = counts.get(kind, 0) + n
    return counts
