"""pytest picks its rootdir and ini file before plugin options are known, so in `pytest --results-dir /tmp/x`
it takes `/tmp/x` for a test path: the project's `pyproject.toml` is then not read — no `testpaths` (the
project's own tests run as benchmark cases), no registered markers (a warning per marker), in the xdist workers
too. Once our options are known (`pytest_load_initial_conftests`) the choice is made again without the values
of options, and kept when it differs."""

from __future__ import annotations

import copy
import inspect

import pytest


def redetermine(config: pytest.Config, args: list[str]) -> None:
    """Recompute rootdir and ini file with every plugin option known; a UsageError if pytest's internals do not
    allow it (then `--option=value` avoids the problem)."""
    try:
        from _pytest.config import findpaths

        ns = config._parser.parse_known_args(list(args), namespace=copy.copy(config.option))
        kwargs = dict(inifile=ns.inifilename, args=ns.file_or_dir, rootdir_cmd_arg=ns.rootdir or None,
                      invocation_dir=config.invocation_params.dir)
        if "override_ini" in inspect.signature(findpaths.determine_setup).parameters:
            kwargs["override_ini"] = ns.override_ini
        rootpath, inipath, inicfg = findpaths.determine_setup(**kwargs)[:3]
        if rootpath == config.rootpath and inipath == config.inipath:
            return
        config._rootpath, config._inipath = rootpath, inipath
        if hasattr(config, "_inicfg"):
            config._inicfg = inicfg
        else:  # older pytest
            config.inicfg = inicfg
        config._inicache.clear()
        config._parser.extra_info["rootdir"] = str(rootpath)
        config._parser.extra_info["inifile"] = str(inipath)
        if getattr(ns, "confcutdir", None) is None:
            config.known_args_namespace.confcutdir = str(inipath.parent if inipath else rootpath)
    except Exception as exc:  # pytest's internals changed: say how to avoid the problem instead
        raise pytest.UsageError(
            f"could not re-read pytest's configuration ({exc.__class__.__name__}: {exc}); write path options "
            "with `=` (e.g. --results-dir=reports/x, --resume=reports/x) so pytest does not take their values "
            "for test paths") from None
