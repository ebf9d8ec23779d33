"""`jarvis engine ...` and `jarvis images ...` subcommands."""

from __future__ import annotations

from jarvis_pytest.infra import engine, images


def _images_build(args) -> int:
    engine.ensure_engine()
    built = images.build_all(args.only or None, base=args.base, force=args.force)
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


def register(sub) -> None:
    p = sub.add_parser("engine", help="the Docker engine")
    esub = p.add_subparsers(dest="engine_command", required=True)
    e = esub.add_parser("ensure", help="install (Debian, root) and start the Docker engine if needed")
    e.set_defaults(func=engine.main_ensure)

    p = sub.add_parser("images", help="device images")
    isub = p.add_subparsers(dest="images_command", required=True)
    b = isub.add_parser("build", help="build the base and device images (only what changed)")
    b.add_argument("--base", help="a registry base image to build on (e.g. ubuntu:24.04) instead of debootstrap")
    b.add_argument("--only", action="append", metavar="NAME", help="build only this image (repeatable)")
    b.add_argument("--force", action="store_true", help="rebuild even when up to date")
    b.set_defaults(func=_images_build)
    ls = isub.add_parser("list", help="list device images and whether they are built")
    ls.set_defaults(func=_images_list)
