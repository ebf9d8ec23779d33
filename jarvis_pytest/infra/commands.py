"""`jarvis engine`, `jarvis images`, `jarvis cleanup` and `jarvis bench devices` subcommands."""

from __future__ import annotations

import argparse

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.infra import engine, images


def _images_build(args) -> int:
    if args.base is not None:  # gone: say so rather than argparse's "unrecognized arguments"
        raise ConfigError(f"{args.base!r}: --base is gone (no other base was ever built or tested)", field="--base",
                          fix=f"drop it: every image builds on the offline {images.BASE_DESCRIPTION} base, and the "
                          "ubuntu platform's device is Debian 12 with XFCE")
    from jarvis_pytest.devices.backend import OPTION_FLAG, backend_option_pairs, check_backend_options

    given = backend_option_pairs([(OPTION_FLAG, item) for item in args.backend_option or []])
    takers = {platform: name for name, (_, platform, _) in images.PREPARED.items() if platform}
    for platform in given:  # each is for an image named with --only, and a key and value a run would take
        if takers.get(platform) not in (args.only or []):
            key = next(iter(given[platform]))
            raise ConfigError(f"no image named with --only takes {platform} options", field=f"{OPTION_FLAG} "
                              f"{platform}.{key}", fix="give them with the image that uses them: "
                              + ", ".join(f"--only {n} for {p}.KEY=VALUE" for p, n in takers.items()))
    check_backend_options({}, given)
    engine.ensure_engine()
    built = images.build_all(args.only or None, force=args.force, options=given)
    for name, tag in built.items():
        print(f"{name}\t{tag}")
    return 0


def _images_list(args) -> int:
    c = engine.client()
    for name in images.discover():
        tag = images.image_tag(name)
        try:
            img = c.images.get(tag)
            print(f"{name}\t{tag}\t{img.short_id}\t{img.attrs['Size'] / 1e6:.0f} MB")
        except Exception:
            print(f"{name}\t{tag}\t(not built)")
    return 0


def _cleanup(args) -> int:
    from pathlib import Path

    from jarvis_pytest.infra import engines
    from jarvis_pytest.infra.images import REPO_ROOT
    from jarvis_pytest.results import run_lock
    from jarvis_pytest.results.run_state import read_json, resource_id

    from jarvis_pytest.cluster.connect import configured as cluster_address

    hosts = list(engines.configured(args.docker_host, REPO_ROOT))
    ray = cluster_address(args.ray, REPO_ROOT)
    run = args.run
    if run:  # a run folder (its name under reports/, or a path) stands for its resources, on the engines it used
        folder = next((f for f in (Path(run), REPO_ROOT / "reports" / run) if (f / "run.json").is_file()), None)
        if folder is not None:
            run = resource_id(folder)
            meta = read_json(folder / "run.json") or {}
            recorded = meta.get("engines") or []
            hosts += [h for h in engines.check_urls(recorded, f"{folder / 'run.json'}: engines") if h not in hosts]
            ray = ray or (meta.get("ray") or {}).get("address")  # and on the Ray nodes it ran on
    if args.list:
        _print_kept(hosts, removed=False)
        return 0
    kept_before = set(run_lock.kept_runs())
    from jarvis_pytest.cluster.cleanup import cleanup_everywhere

    # this machine's engines, and every live node of the cluster (each on its own engine)
    counts = cleanup_everywhere(hosts, ray, run_id=run, everything=args.all, kept=args.kept)
    for gone in (kept_before if args.kept or args.all else [run] if run else []):
        run_lock.forget(gone)  # removed on every engine: no longer kept (a live run's record stays)
    what = (f"run {args.run}" if args.run else "every run" if args.all else
            "devices kept with --keep-devices by ended runs" if args.kept else "orphans: runs whose processes are gone")
    where = f" on {len(hosts)} engines" if len(hosts) > 1 else ""
    where += f" and the live nodes of the Ray cluster at {ray}" if ray else ""
    print(", ".join(f"{v} {k}" for k, v in counts.items()) + f" removed ({what}){where}")
    if not (args.run or args.all or args.kept):
        run_lock.prune()  # the lock files killed runs left
        _print_kept(hosts, removed=True)
    return 0


def _print_kept(hosts: list[str], removed: bool) -> None:
    """The devices ended runs kept with --keep-devices (left alone by every sweep), and how to remove them."""
    from jarvis_pytest.infra.cleanup import kept_devices

    lines = []
    for host in hosts or [None]:
        for run, kept in kept_devices(host).items():
            if kept["containers"] or kept["networks"]:
                where = f" on {host}" if host else ""
                lines.append(f"  {run}{where} ({kept['run_dir'] or 'folder unknown'}; ended {kept['ended'] or '?'}): "
                             f"{', '.join(kept['containers'] + kept['networks'])}")
    if not lines:
        if not removed:
            print("no devices kept with --keep-devices")
        return
    print(("kept with --keep-devices, not removed:" if removed else "kept with --keep-devices:"))
    print("\n".join(lines))
    print("remove them with `jarvis cleanup --kept` (all of them) or `jarvis cleanup --run RUN` (one run)")


def _bench_devices(args) -> int:
    from jarvis_pytest.bench import devices as bench

    return bench.main(args)


def _bench_throughput(args) -> int:
    from jarvis_pytest.bench import throughput

    return throughput.main(args)


def register(sub) -> None:
    c = sub.add_parser("cleanup", help="remove containers, networks and volumes a crashed run left behind",
                       description="Without options: remove what runs whose processes are gone left behind (runs "
                                   "still going are safe; devices kept with --keep-devices are listed, not removed)."
                                   " --kept: remove the devices ended runs kept. --list: list those, remove nothing."
                                   " --run: everything of one run. --all: everything.")
    one = c.add_mutually_exclusive_group()
    one.add_argument("--run", help="a run, live or not: its folder (its name under reports/, or a path) or the id "
                   "its devices carry (label org.jarvis.run)")
    one.add_argument("--all", action="store_true", help="everything any jarvis run made, live runs included")
    one.add_argument("--kept", action="store_true", help="the devices runs started with --keep-devices kept, once "
                   "those runs ended (this host's runs)")
    one.add_argument("--list", action="store_true", help="list the devices ended runs kept with --keep-devices; "
                   "remove nothing")
    c.add_argument("--docker-host", action="append", default=None, metavar="URL",
                   help="an engine to clean (repeatable; default: [tool.jarvis] docker_hosts, else the local one; "
                   "with --run also the engines the run recorded)")
    c.add_argument("--ray", default=None, metavar="ADDRESS", help="also every live node of this Ray cluster, each "
                   "on its own engine (default: [tool.jarvis] ray; with --run also the cluster the run recorded); a "
                   "node that was down is cleaned by running this again once it is back")
    c.set_defaults(func=_cleanup)

    p = sub.add_parser("bench", help="measure the harness")
    bsub = p.add_subparsers(dest="bench_command", required=True)
    d = bsub.add_parser("devices", help="cold start, reset, screenshot, action and a11y latency; idle memory")
    d.add_argument("--platform", default="ubuntu")
    d.add_argument("--repeat", type=int, default=5, help="cold starts and pool resets to time (default 5)")
    d.add_argument("--samples", type=int, default=30, help="screenshots and actions to time (default 30)")
    d.add_argument("--json", action="store_true", help="print JSON")
    d.set_defaults(func=_bench_devices)
    t = bsub.add_parser("throughput", help="model-bound throughput: real tasks, a loopback model with a fixed "
                        "latency, once per worker count")
    t.add_argument("--workers", default="1,2,4,8", help="xdist worker counts to run, comma-separated (default 1,2,4,8)")
    t.add_argument("--latency-ms", type=int, default=2000, help="the model's answer time per call (default 2000)")
    t.add_argument("--tasks", type=int, default=None, help="tasks per run (default: 16 per worker in every run, so "
                   "that every worker does the same work and its steady state can be read)")
    t.add_argument("--results", default=None, help="where the runs' results go (default reports/)")
    t.add_argument("--ray", default=None, metavar="ADDRESS", help="also run each worker count with --ray ADDRESS, "
                   "side by side with the local run: the per-step overhead Ray adds and the head's CPU-s per task")
    t.add_argument("--json", action="store_true", help="print JSON")
    t.set_defaults(func=_bench_throughput)

    p = sub.add_parser("engine", help="the Docker engine")
    esub = p.add_subparsers(dest="engine_command", required=True)
    e = esub.add_parser("ensure", help="install (Debian, root) and start the Docker engine if needed")
    e.set_defaults(func=engine.main_ensure)
    x = esub.add_parser("extra", help="start another Docker engine on this machine (its own socket and data root) "
                        "and print its URL, for --docker-host")
    x.add_argument("index", type=int, help="2, 3, ... (1 is the local engine)")
    x.add_argument("--tcp", type=int, metavar="PORT", help="also listen on tcp://127.0.0.1:PORT (no TLS; loopback "
                   "only) and print that URL too")
    x.set_defaults(func=engine.main_extra)

    p = sub.add_parser("images", help="device images")
    isub = p.add_subparsers(dest="images_command", required=True)
    b = isub.add_parser("build", help="build the base and device images (only what changed)")
    b.add_argument("--base", help=argparse.SUPPRESS)  # removed; refused with the reason
    b.add_argument("--only", action="append", metavar="NAME", help="build only this image (repeatable)")
    b.add_argument("--force", action="store_true", help="rebuild even when up to date")
    b.add_argument("--backend-option", action="append", metavar="PLATFORM.KEY=VALUE",
                   help="a setting of a prepared image, as a run takes it (repeatable; e.g. windows.ram=6G for "
                        "--only windows-real); each else from its environment variable, else its default")
    b.set_defaults(func=_images_build)
    ls = isub.add_parser("list", help="list device images and whether they are built")
    ls.set_defaults(func=_images_list)
