"""The package's layers, bottom up, and the rule that holds them: no module imports from a layer above its own
(at the top of a module, inside a function, or for type checking alike). The task engine (`harness/`) runs
without pytest."""

from __future__ import annotations

import ast
from pathlib import Path

from jarvis_pytest.cli import COMMAND_MODULES

PACKAGE = Path(__file__).resolve().parents[1] / "jarvis_pytest"

# Bottom up: a module may import from its own layer and those below. A prefix names a package or a module; the
# longest prefix that matches a module decides its layer. The command line (`cli`, the modules it registers
# subcommands from, `__main__`s) is the top: it wires everything together.
LAYERS: list[tuple[str, tuple[str, ...]]] = [
    ("foundations", ("errors", "naming", "paths", "project_settings", "http_client", "http_server")),
    ("results", ("results",)),                  # result files and run state: data, no devices
    ("llm", ("llm",)),                          # the OpenAI-compatible client
    ("infra", ("infra",)),                      # Docker engines, containers, networks, images, the drive
    ("devices", ("devices",)),                  # the device API, platforms' facts and backends
    ("generators", ("generators",)),
    ("evaluators", ("evaluators",)),
    ("tasks", ("tasks",)),                      # templates, instances, composition
    ("environments", ("environments",)),        # a task's devices, drive and network; the worker's pool
    ("agents", ("agents", "player")),           # the agent protocol, the built-in agents, the person's player
    ("harness", ("harness",)),                  # the task engine: one task end to end, without pytest
    ("cluster", ("cluster",)),                  # task environments on Ray nodes (imports Ray only with --ray)
    ("report", ("report",)),                    # the rollup, the run card, reproduce and diff
    ("plugin", ("plugin",)),                    # the pytest glue
    ("apps", ("dashboard", "bench")),
    ("commands", ("cli", *(m.removeprefix("jarvis_pytest.") for m in COMMAND_MODULES))),
]


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def layer(module: str) -> int:
    if module.endswith("__main__"):
        return len(LAYERS) - 1
    if module == "":
        return 0
    best = None
    for index, (_, prefixes) in enumerate(LAYERS):
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + ".")) and (best is None or len(prefix) > best[1]):
                best = (index, len(prefix))
    assert best is not None, f"jarvis_pytest.{module} is in no layer: add it to LAYERS"
    return best[0]


def imports(path: Path) -> list[tuple[int, str]]:
    """(line, module of the package) of every import in `path`, wherever it stands."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, a.name) for a in node.names if a.name.startswith("jarvis_pytest.")]
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("jarvis_pytest"):
            base = node.module.removeprefix("jarvis_pytest").lstrip(".")
            for alias in node.names:  # `from jarvis_pytest.x import y`: y may be a module of x
                sub = f"{base}.{alias.name}" if base else alias.name
                is_module = (PACKAGE / sub.replace(".", "/")).with_suffix(".py").is_file() or \
                    (PACKAGE / sub.replace(".", "/") / "__init__.py").is_file()
                found.append((node.lineno, "jarvis_pytest." + (sub if is_module else base)))
    return [(line, name.removeprefix("jarvis_pytest.").removeprefix("jarvis_pytest")) for line, name in found]


def test_no_module_imports_from_a_layer_above_its_own():
    upward = []
    for path in sorted(PACKAGE.rglob("*.py")):
        own = module_name(path)
        for line, target in imports(path):
            if layer(target) > layer(own):
                upward.append(f"{path.relative_to(PACKAGE.parent)}:{line}: {own} ({LAYERS[layer(own)][0]}) imports "
                              f"{target} ({LAYERS[layer(target)][0]})")
    assert not upward, "imports pointing up a layer:\n" + "\n".join(upward)


def test_the_layering_rule_sees_an_upward_import(tmp_path):
    """The check can fail: a device module importing the plugin is caught, wherever the import stands."""
    source = tmp_path / "probe.py"
    source.write_text("def f():\n    from jarvis_pytest.plugin import session\n")
    ((line, target),) = imports(source)
    assert (line, target) == (2, "plugin.session") and layer(target) > layer("devices.base")


def test_the_task_engine_runs_without_pytest():
    for path in sorted((PACKAGE / "harness").rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        names = [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
        names += [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
        assert not [n for n in names if n == "pytest" or n.startswith(("pytest.", "_pytest", "xdist"))], path
