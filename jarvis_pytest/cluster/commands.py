"""`jarvis cluster start|stop|status`: a Ray cluster on this machine for trying `--ray` (`cluster/local.py`)."""

from __future__ import annotations


def _start(args) -> int:
    from jarvis_pytest.cluster import local

    running = local.LocalCluster.load()
    if running is not None and local.alive(running):
        print(f"a local cluster runs already: --ray {running.address} (`jarvis cluster stop` ends it)")
        return 1
    cluster = local.start(nodes=args.nodes, slots=args.slots, port=args.port)
    cluster.save()
    for node, engine in cluster.nodes.items():
        print(f"node {node[:12]}: engine {engine}")
    print(f"--ray {cluster.address}")
    return 0


def _stop(args) -> int:
    from jarvis_pytest.cluster import local

    cluster = local.LocalCluster.load()
    if cluster is None:
        print("no local cluster was started here")
        return 0
    local.stop(cluster)
    local.STATE.unlink(missing_ok=True)
    print(f"stopped the cluster at {cluster.address} (its engines run on; `jarvis cleanup --all` empties them)")
    return 0


def _status(args) -> int:
    from jarvis_pytest.cluster.connect import configured, connect, jarvis_nodes
    from jarvis_pytest.cluster import local
    from jarvis_pytest.paths import REPO_ROOT

    address = configured(args.ray, REPO_ROOT) or getattr(local.LocalCluster.load(), "address", None)
    if address is None:
        print("no cluster: give --ray ADDRESS (or start one here: jarvis cluster start)")
        return 1
    nodes = jarvis_nodes(connect(address))
    print(f"Ray cluster at {address}: {len(nodes)} node(s) offering devices")
    for n in nodes:
        print(f"  {n.short} {n.address}: {n.slots:g} device slots, {n.memory_mb / 1024:.1f} GiB memory"
              f"{', kvm' if n.kvm else ''}")
    return 0


def register(sub) -> None:
    p = sub.add_parser("cluster", help="a Ray cluster for --ray: start one on this machine, see its nodes")
    csub = p.add_subparsers(dest="cluster_command", required=True)
    s = csub.add_parser("start", help="start a head and N nodes here, node i on its own Docker engine (extra engine "
                        "i+1); prints the --ray address")
    s.add_argument("--nodes", type=int, default=2, help="nodes that offer devices (default 2)")
    s.add_argument("--slots", type=int, default=4, help="devices each node runs at once (default 4)")
    s.add_argument("--port", type=int, default=26379, help="the head's port (default 26379)")
    s.set_defaults(func=_start)
    t = csub.add_parser("stop", help="stop the cluster `jarvis cluster start` started")
    t.set_defaults(func=_stop)
    st = csub.add_parser("status", help="the nodes of a cluster that offer devices")
    st.add_argument("--ray", default=None, metavar="ADDRESS", help="the cluster (default: [tool.jarvis] ray, else the "
                    "one `jarvis cluster start` started)")
    st.set_defaults(func=_status)
