"""`jarvis schema`, `jarvis types`, `jarvis templates` and `jarvis compose` (with the optional LLM steps)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from pydantic import TypeAdapter

from jarvis_pytest.devices.platforms import PLATFORM_NAMES
from jarvis_pytest.tasks import llm_steps
from jarvis_pytest.tasks.compose import compose
from jarvis_pytest.tasks.dataset import write_dataset
from jarvis_pytest.tasks.library import Library, load_library
from jarvis_pytest.tasks.model import TEMPLATE_FILE_SCHEMA_TITLE, Dataset, TaskTemplate
from jarvis_pytest.tasks.types import load_types


def _print_json(data: Any) -> None:
    print(json.dumps(data, indent=2, sort_keys=True, ensure_ascii=False))


def schema(kind: str) -> dict[str, Any]:
    """The JSON Schema of a template file (`template`) or of a dataset file (`dataset`)."""
    if kind == "dataset":
        out = Dataset.model_json_schema(by_alias=True)
        out["title"] = "jarvis-pytest dataset file"
    else:
        out = TypeAdapter(TaskTemplate | list[TaskTemplate]).json_schema(by_alias=True)
        out["title"] = TEMPLATE_FILE_SCHEMA_TITLE
    out["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    return out


def _schema(args: argparse.Namespace) -> int:
    _print_json(schema(args.kind))
    return 0


def _types(args: argparse.Namespace) -> int:
    types = load_types(args.types)
    if args.json:
        _print_json(types.to_json())
    else:
        print(types.tree())
    return 0


def _templates(args: argparse.Namespace) -> int:
    lib = load_library(args.library, types_path=args.types)
    if args.json:
        _print_json([t.model_dump(mode="json", exclude_none=True) for t in lib.templates])
        return 0
    for t in lib.templates:
        ins = ", ".join(f"{k}:{v.type}" for k, v in sorted(t.inputs.items()))
        outs = ", ".join(f"{k}:{v.type}" for k, v in sorted(t.outputs.items()))
        print(f"{t.id}\t{t.platform}\t{t.app}\t({ins}) -> ({outs})")
    print(f"{len(lib.templates)} templates, all valid")
    return 0


def _compose(args: argparse.Namespace) -> int:
    lib = load_library(args.library, types_path=args.types)
    if not args.backend_specific:  # composed tasks any backend of each platform can run: comparable scores
        left_out = [t.id for t in lib.templates if t.backends]
        lib = Library.from_templates([t for t in lib.templates if not t.backends], lib.types, sources=lib.sources,
                                     root=lib.root)
        if left_out:
            print(f"left out {len(left_out)} templates written for one backend only (e.g. {left_out[0]}); "
                  "--backend-specific takes them in")
    meta = {"generator": "jarvis compose", "seed": args.seed, "count": args.count, "balanced": args.balanced,
            "category": args.category,
            "max_subtasks": args.max_subtasks, "library_digest": lib.digest(),
            "command": "jarvis compose " + " ".join(sys.argv[2:]) if sys.argv[1:2] == ["compose"] else None,
            "platforms": sorted({t.platform for t in lib.templates})}
    absent = sorted(set(PLATFORM_NAMES) - set(meta["platforms"]))
    if absent:
        print(f"no templates for {', '.join(absent)}: composing from {', '.join(meta['platforms'])}")
    chat = None
    if args.rewrite or args.judge:
        config = llm_steps.endpoint(args.composer_base_url, args.composer_model, args.composer_api_key)
        chat = llm_steps.cached_chat(config, args.llm_cache)
        meta["llm"] = {"model": config.model, "rewrite": args.rewrite, "judge": args.judge}
    try:
        finalize = llm_steps.pipeline(chat, rewrite=args.rewrite, judge=args.judge) if chat else None
        tasks = compose(lib, seed=args.seed, count=args.count, max_subtasks=args.max_subtasks,
                        balanced=args.balanced, category=args.category, finalize=finalize, max_attempts=args.max_attempts)
    finally:
        if chat is not None:
            chat.close()
    path = write_dataset(args.out, tasks, meta)
    print(f"wrote {len(tasks)} tasks to {path}")
    print(dataset_counts(tasks))
    return 0


def dataset_counts(tasks) -> str:
    """A table: tasks per category and platform set, subtasks, transfers."""
    from collections import Counter

    rows = Counter((t.category, "+".join(sorted(set(t.devices)))) for t in tasks)
    subtasks = sum(len(t.formatted_subtasks) for t in tasks)
    transfers = sum(s.source_platform is not None for t in tasks for s in t.formatted_subtasks)
    lines = ["| category | platforms | tasks |", "|---|---|---|"]
    lines += [f"| {c.upper()} | {p} | {n} |" for (c, p), n in sorted(rows.items())]
    per_cat = Counter(t.category for t in tasks)
    lines.append(f"\n{len(tasks)} tasks (" + ", ".join(f"{c.upper()} {per_cat[c]}" for c in ("sw", "mi", "md"))
                 + f"), {subtasks} subtasks, {transfers} of them file transfers")
    return "\n".join(lines)


def _datasets(args: argparse.Namespace) -> int:
    from jarvis_pytest.tasks.dataset import load_dataset

    for path in args.files or sorted(Path("tasks/composed").glob("*.json")):
        ds = load_dataset(path)
        print(f"{path}: {ds.meta.get('command') or 'composed by ' + str(ds.meta.get('generator', '?'))}, seed "
              f"{ds.meta.get('seed')}, library {ds.meta.get('library_digest')}")
        print(dataset_counts(ds.tasks))
    return 0


def _library_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--library", type=Path, default=Path("tasks"),
                   help="folder of task templates (<platform>/*.json; default: tasks)")
    p.add_argument("--types", type=Path, default=None,
                   help="types file (default: <library>/types.json if present, else the repository's tasks/types.json)")


def register(sub: Any) -> None:
    """Add the task-model subcommands to the `jarvis` parser."""
    p = sub.add_parser("schema", help="print the JSON Schema of task template files (or of dataset files)")
    p.add_argument("--kind", choices=("template", "dataset"), default="template")
    p.set_defaults(func=_schema)

    p = sub.add_parser("types", help="print the slot type hierarchy")
    p.add_argument("--json", action="store_true", help='print {"type": "parent" | null} for every declared type')
    p.add_argument("--types", type=Path, default=None, help="types file (default: tasks/types.json)")
    p.set_defaults(func=_types)

    p = sub.add_parser("templates", help="validate and list the task templates of a library")
    _library_args(p)
    p.add_argument("--json", action="store_true", help="print the templates as JSON")
    p.add_argument("--check-evaluators", action="store_true",
                   help="(always done now: every evaluator and generator name is checked when templates load)")
    p.set_defaults(func=_templates)

    p = sub.add_parser("datasets", help="the composed datasets: how they were made, tasks per category and platforms")
    p.add_argument("files", nargs="*", type=Path, help="dataset files (default tasks/composed/*.json)")
    p.set_defaults(func=_datasets)

    p = sub.add_parser("compose", help="compose cross-device tasks from the template library (paper, Algorithm 1)")
    _library_args(p)
    p.add_argument("--seed", type=int, required=True, help="random seed (same seed and inputs: same file)")
    p.add_argument("--count", type=int, required=True, help="number of tasks")
    p.add_argument("--max-subtasks", type=int, default=4,
                   help="K: most subtasks per task, transfer subtasks included (default 4)")
    p.add_argument("--balanced", action="store_true", help="equal thirds of SW, MI and MD")
    p.add_argument("--backend-specific", action="store_true", help="also draw templates written for one backend "
                   "only (e.g. Paint, which needs a real Windows); by default composed tasks use templates every "
                   "backend of their platform runs, so their scores compare across backends")
    p.add_argument("--category", choices=("sw", "mi", "md"), help="compose only tasks of this category "
                   "(e.g. sw for a library of one platform)")
    p.add_argument("--out", type=Path, required=True, help="dataset file to write")
    p.add_argument("--max-attempts", type=int, default=200,
                   help="draws per task before giving up (the judge rejects many; default 200)")
    g = p.add_argument_group("optional LLM steps (any OpenAI-compatible endpoint)")
    g.add_argument("--rewrite", action="store_true",
                   help="rewrite each merged instruction with the LLM (kept only if every slot value survives verbatim)")
    g.add_argument("--judge", action="store_true", help="keep only tasks the LLM judge rates 5/5/5 "
                   "(realism, coherence, evaluability)")
    g.add_argument("--composer-base-url", default=None, help="API root, e.g. http://127.0.0.1:8000/v1 "
                   "(env JARVIS_COMPOSER_BASE_URL)")
    g.add_argument("--composer-model", default=None, help="model name (env JARVIS_COMPOSER_MODEL)")
    g.add_argument("--composer-api-key", default=None, help="API key (env JARVIS_COMPOSER_API_KEY); never written")
    g.add_argument("--llm-cache", type=Path, default=llm_steps.DEFAULT_CACHE,
                   help=f"folder of cached LLM answers (default {llm_steps.DEFAULT_CACHE})")
    p.set_defaults(func=_compose)
