"""The atomic task library: template files under `<library>/<platform>/`, loaded and validated.

Layout: ``<library>/types.json`` (optional; default: the repository's ``tasks/types.json``) and
``<library>/{android,windows,ubuntu}/**/*.json``. A template file holds one template object or a list of them;
each template's ``platform`` must match its folder. Nothing else under the library is read, so dataset files and
test modules may live beside it. Every problem (bad JSON, an unknown field or slot type, a placeholder naming no
slot, a duplicate id, ...) is one ConfigError naming the file, the task, the field and the fix.
"""

from __future__ import annotations

import hashlib
import json
import random
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Collection, Iterable, Mapping

from pydantic import ValidationError

from jarvis_pytest.devices.actions import PLATFORMS
from jarvis_pytest.errors import ConfigError
from jarvis_pytest.paths import FIXTURE_FILES
from jarvis_pytest.tasks.evaluator_args import check_evaluator_args, slot_samples
from jarvis_pytest.tasks.instances import check_pattern, materialise, sample_inputs
from jarvis_pytest.tasks.model import InputSlot, TaskTemplate
from jarvis_pytest.tasks.templating import Where, find_placeholders, walk_strings
from jarvis_pytest.tasks.transfer import is_transfer
from jarvis_pytest.tasks.types import TypeSystem, load_types


@dataclass(frozen=True)
class Library:
    """Validated templates sorted by id, the type system they use and the file each came from."""

    types: TypeSystem
    templates: tuple[TaskTemplate, ...]
    sources: dict[str, Path] = field(default_factory=dict)
    root: Path | None = None

    @classmethod
    def from_templates(cls, templates: Iterable[TaskTemplate], types: TypeSystem, *,
                       sources: dict[str, Path] | None = None, root: Path | None = None,
                       evaluators: Collection[str] | None = None) -> "Library":
        """Validate `templates` against `types` and build a library (ids must be unique)."""
        sources = dict(sources or {})
        seen: dict[str, TaskTemplate] = {}
        for tpl in templates:
            path = sources.get(tpl.id)
            if tpl.id in seen:
                raise ConfigError(f"duplicate template id {tpl.id!r}", path=path, field="id",
                                  fix="give every template its own id")
            validate_template(tpl, types, path=path, evaluators=evaluators)
            seen[tpl.id] = tpl
        ordered = tuple(seen[k] for k in sorted(seen))
        return cls(types=types, templates=ordered, sources=sources, root=root)

    def get(self, template_id: str) -> TaskTemplate:
        for tpl in self.templates:
            if tpl.id == template_id:
                return tpl
        raise KeyError(template_id)

    def by_platform(self, platform: str) -> list[TaskTemplate]:
        return [t for t in self.templates if t.platform == platform]

    def digest(self) -> str:
        """A short content hash of the templates and the type system (for dataset provenance)."""
        blob = json.dumps({"types": self.types.to_json(),
                           "templates": [_digested(t) for t in self.templates]}, sort_keys=True)
        return hashlib.sha256(blob.encode()).hexdigest()[:16]


def _digested(tpl: TaskTemplate) -> dict[str, Any]:
    """What a template's digest covers: all of it, less GUI solution fields it leaves empty (so adding the fields
    changed no library's digest)."""
    data = tpl.model_dump(mode="json", by_alias=True)
    for key in ("gui_solution", "gui_values", "gui_infeasible"):
        if not data[key]:
            del data[key]
    return data


# -- reading files -------------------------------------------------------------------------------------------
def template_files(root: Path) -> list[Path]:
    """The template files of a library, sorted: `<root>/<platform>/**/*.json`."""
    return sorted(p for platform in PLATFORMS for p in (root / platform).rglob("*.json") if p.is_file())


def _loc(loc: tuple[Any, ...]) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def pydantic_error(exc: ValidationError, *, path: object, task: str | None, prefix: str = "") -> ConfigError:
    """The first error of a pydantic validation as a ConfigError with the field's dotted path."""
    err = exc.errors()[0]
    where = prefix + _loc(tuple(err["loc"]))
    head = f"task {task!r}: " if task else ""
    kind = err["type"]
    if kind == "extra_forbidden":
        return ConfigError(f"{head}unknown field", path=path, field=where,
                           fix="remove it or fix its spelling (see `jarvis schema`)")
    if kind == "missing":
        return ConfigError(f"{head}required field is missing", path=path, field=where, fix="add it (see `jarvis schema`)")
    message = str(err["msg"]).removeprefix("Value error, ")
    cause = (err.get("ctx") or {}).get("error")
    return ConfigError(f"{head}{message}", path=path, field=where or None,
                       fix=getattr(cause, "fix", None) or "see `jarvis schema` for the template format")


def read_template_file(path: Path) -> list[TaskTemplate]:
    """Parse one template file (an object or a list of objects) into templates, without type checks."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ConfigError(f"not valid JSON: {exc.msg} at line {exc.lineno} column {exc.colno}", path=path,
                          fix="fix the JSON syntax") from None
    except UnicodeDecodeError:
        raise ConfigError("not UTF-8 text", path=path, fix="save the file as UTF-8 JSON") from None
    items = data if isinstance(data, list) else [data]
    out = []
    for i, item in enumerate(items):
        prefix = f"[{i}]." if isinstance(data, list) else ""
        if not isinstance(item, dict):
            raise ConfigError("a template must be a JSON object", path=path, field=prefix.rstrip(".") or None,
                              fix="write one template object, or a list of them")
        task = item.get("id") if isinstance(item.get("id"), str) else None
        try:
            out.append(TaskTemplate.model_validate(item))
        except ValidationError as exc:
            raise pydantic_error(exc, path=path, task=task, prefix=prefix) from None
    return out


def load_library(root: Path | str | None = None, *, types: TypeSystem | None = None,
                 types_path: Path | str | None = None, evaluators: Collection[str] | None = None) -> Library:
    """Load and validate every template under `root` (default: ./tasks).

    `types` (or `types_path`) overrides the type system; by default `<root>/types.json` if present, else the
    repository's `tasks/types.json`. `evaluators`, when given, is the set of known evaluator names.
    """
    root = Path(root) if root is not None else Path("tasks")
    if not root.is_dir():
        raise ConfigError("no such library folder", path=root, fix="pass --library DIR with <platform>/*.json templates")
    types = types or load_types(types_path, library=root)
    templates, sources = [], {}
    for path in template_files(root):
        platform = path.relative_to(root).parts[0]
        for tpl in read_template_file(path):
            if tpl.platform != platform:
                raise ConfigError(f"task {tpl.id!r}: platform {tpl.platform!r} in the {platform}/ folder",
                                  path=path, field="platform", fix=f"move the file to {tpl.platform}/ or fix the platform")
            if tpl.id in sources:
                raise ConfigError(f"duplicate template id {tpl.id!r} (first in {sources[tpl.id]})", path=path,
                                  field="id", fix="give every template its own id")
            templates.append(tpl)
            sources[tpl.id] = path
    return Library.from_templates(templates, types, sources=sources, root=root, evaluators=evaluators)


# -- validation ------------------------------------------------------------------------------------------------
def validate_template(tpl: TaskTemplate, types: TypeSystem, *, path: object = None,
                      evaluators: Collection[str] | None = None) -> None:
    """Check a library template beyond its schema; raises the first problem as a ConfigError."""
    where = Where(path, tpl.id)

    def fail(field: str, message: str, fix: str) -> ConfigError:
        return where.at(field).error(message, fix)

    if is_transfer(tpl.id) or tpl.source_platform is not None:
        raise fail("id", "ids `transfer-*-to-*` and `source_platform` are reserved for the built-in transfer task",
                   "rename the template and drop source_platform")
    for kind, slots in (("inputs", tpl.inputs), ("outputs", tpl.outputs)):
        for name, slot in slots.items():
            types.require(slot.type, path=path, field=f"{kind}.{name}.type", task=tpl.id)
    both = sorted(set(tpl.inputs) & set(tpl.outputs))
    if both:
        raise fail(f"outputs.{both[0]}", f"slot {both[0]!r} is both an input and an output", "rename one of them")
    for name, slot in tpl.inputs.items():
        field = f"inputs.{name}"
        if not slot.has_domain:
            raise fail(field, f"input slot {name!r} has no sampling domain", "add `choices`, `range` or `pattern`")
        if slot.pattern is not None:
            try:
                check_pattern(slot.pattern)
            except ValueError as exc:
                raise fail(f"{field}.pattern", str(exc), "use tokens {int:LO-HI} and {word} only") from None
        if types.is_file(slot.type) and slot.choices is not None and not all(isinstance(c, str) for c in slot.choices):
            raise fail(f"{field}.choices", f"file slot {name!r} has a non-path choice", "write paths as strings")
        if slot.range is not None and types.is_file(slot.type):
            raise fail(f"{field}.range", f"file slot {name!r} cannot take a number range", "use choices or a pattern")
        for choice in slot.choices or []:
            if isinstance(choice, str) and ("{{" in choice or "}}" in choice):
                raise fail(f"{field}.choices", f"choice {choice!r} contains braces", "remove {{ }} from values")
    for name, out in tpl.outputs.items():
        field = f"outputs.{name}"
        if out.same_type_as is not None:
            if out.same_type_as not in tpl.inputs:
                raise fail(f"{field}.same_type_as", f"same_type_as names no input slot ({out.same_type_as!r})",
                           f"use one of {sorted(tpl.inputs)}")
            source_type = tpl.inputs[out.same_type_as].type
            if not types.is_subtype(source_type, out.type):
                raise fail(f"{field}.type", f"output type {out.type!r} is not a supertype of input "
                           f"{out.same_type_as!r} ({source_type!r})", f"declare the output as {source_type!r} or wider")
        _check_placeholders(out.value, tpl.inputs, types, tpl, where.at(f"{field}.value"),
                            "output values may use input slots only")
    slots = {**tpl.inputs, **tpl.outputs}
    _check_placeholders(tpl.instruction, slots, types, tpl, where.at("instruction"))
    gui_slots = {**slots, **_check_gui_values(tpl, slots, where)}
    for section in ("config", "evaluate", "solution", "negatives", "gui_solution"):
        data = [item.model_dump(mode="json", exclude_none=True) for item in getattr(tpl, section)]
        for text, loc in walk_strings(data, where.at(section)):
            _check_placeholders(text, gui_slots if section == "gui_solution" else slots, types, tpl, loc)
    _check_gui_infeasible(tpl, slots, types, where)
    for i, text in enumerate(tpl.baseline):
        _check_placeholders(text, slots, types, tpl, where.at(f"baseline[{i}]"))
    if tpl.window:
        _check_placeholders(tpl.window, slots, types, tpl, where.at("window"))
    for i, step in enumerate(tpl.config):
        if step.provides is not None and step.provides not in tpl.inputs:
            raise fail(f"config[{i}].provides", f"provides names no input slot ({step.provides!r})",
                       f"use one of {sorted(tpl.inputs)}")
    _check_fills_of_fed_folders(tpl, types, fail)
    for name in tpl.consumes:
        if name not in tpl.inputs:
            raise fail(f"consumes.{name}", f"consumes names no input slot ({name!r})", f"use one of {sorted(tpl.inputs)}")
        if not types.is_file(tpl.inputs[name].type):
            raise fail(f"consumes.{name}", f"only file inputs can be consumed ({name!r} is {tpl.inputs[name].type!r})",
                       "remove it from consumes")
    check_names(tpl.evaluate, tpl.config, where, evaluators, samples=slot_samples(tpl))
    if tpl.backends:
        from jarvis_pytest.devices.backend import ALIASES, BUILTIN

        known = set(BUILTIN.get(tpl.platform, {}))
        for i, name in enumerate(tpl.backends):
            if ALIASES.get((tpl.platform, name), name) not in known:
                raise fail(f"backends[{i}]", f"no {tpl.platform} backend {name!r}",
                           f"use some of {sorted(known) or 'none (the platform has no backend yet)'}")
    for i, step in enumerate(tpl.config):
        if step.type == "upload_file" and step.fixture is not None:
            problem = fixture_problem(step.fixture)
            if problem:
                raise fail(f"config[{i}].fixture", problem, "put the file under fixtures/files/ and name it "
                           "relative to that folder")
    materialise(tpl, sample_inputs(tpl, random.Random(0)), source=path, gui=True)


def _check_gui_values(tpl: TaskTemplate, slots: dict[str, Any], where: Where) -> dict[str, InputSlot]:
    """`gui_values` name new names, each a text for every choice of an input slot that has choices; returned as
    text slots, the names a GUI solution's placeholders may use besides the template's slots."""
    out = {}
    for name, value in tpl.gui_values.items():
        at = where.at(f"gui_values.{name}")
        if name in slots:
            raise at.error(f"gui_values names a slot of the template ({name!r})", "give the value a name of its own")
        slot = tpl.inputs.get(value.slot)
        if slot is None or slot.choices is None:
            raise at.error(f"slot {value.slot!r} is not an input slot with choices",
                           f"use one of {sorted(n for n, s in tpl.inputs.items() if s.choices is not None) or 'none'}")
        if slot.feedable:
            raise at.error(f"slot {value.slot!r} may be fed from an upstream subtask, whose value is none of its choices",
                           f"mark {value.slot!r} `\"feedable\": false`")
        choices = {str(c) for c in slot.choices}
        if set(value.text) != choices:
            raise at.error(f"text gives {sorted(value.text)} for the choices {sorted(choices)} of {value.slot!r}",
                           "give a text for each choice, and for no other value")
        out[name] = InputSlot(type="text")
    return out


def _check_gui_infeasible(tpl: TaskTemplate, slots: dict[str, Any], types: TypeSystem, where: Where) -> None:
    """`gui_infeasible` names backends of the template's platform, each with a reason."""
    from jarvis_pytest.devices.backend import ALIASES, BUILTIN

    known = set(BUILTIN.get(tpl.platform, {}))
    for name, reason in tpl.gui_infeasible.items():
        at = where.at(f"gui_infeasible.{name}")
        if ALIASES.get((tpl.platform, name), name) not in known:
            raise at.error(f"no {tpl.platform} backend {name!r}",
                           f"use some of {sorted(known) or 'none (the platform has no backend yet)'}")
        if not reason.strip():
            raise at.error("gui_infeasible gives no reason", "say why the GUI cannot solve the task on that backend")
        _check_placeholders(reason, slots, types, tpl, at)


def _check_fills_of_fed_folders(tpl: TaskTemplate, types: Any, fail: Any) -> None:
    """Set-up must not write into a folder an upstream subtask may feed: in a composed task that folder is the
    upstream's work, and files set-up put there would spoil it. A step that makes such a folder's content must
    `provide` the slot (it is dropped when the slot is fed), or the slot must be `feedable: false`."""
    import re

    for i, step in enumerate(tpl.config):
        text = step.path if step.type == "upload_file" else step.command if step.type == "command" else None
        for name in re.findall(r"\{\{(\w+)\}\}[\\/]", text or ""):
            slot = tpl.inputs.get(name)
            if slot is not None and slot.feedable and step.provides != name and types.is_subtype(slot.type, "directory"):
                raise fail(f"config[{i}]", f"set-up writes into folder {name!r}, which an upstream subtask may feed",
                           f"mark the step \"provides\": \"{name}\", or set inputs.{name}.feedable to false")


def fixture_problem(name: str, root: Path = FIXTURE_FILES, *, must_exist: bool = False) -> str | None:
    """Why a set-up fixture cannot be used (None when it can): it must be inside `fixtures/files/`, reached
    without leaving it (no absolute path, no `..`, no symlink out of it); at set-up it must also exist."""
    if Path(name).is_absolute() or ".." in Path(name).parts:
        return f"fixture {name!r} must be a path relative to fixtures/files/ without `..`"
    target = (root / name).resolve()
    if not target.is_relative_to(root.resolve()):
        return f"fixture {name!r} leads out of fixtures/files/ (to {target})"
    if must_exist and not target.is_file():
        return f"fixture {name!r} is not a file under fixtures/files/"
    return None


def check_names(evaluate: list, config: list, where: Where, evaluators: Collection[str] | None = None,
                samples: Mapping[str, tuple[Any, ...]] | None = None) -> None:
    """Every evaluator and file generator named by a template or subtask exists (default: the registries), and
    every evaluator's arguments fit its signature (`evaluator_args`; `samples`: a template's slot values)."""
    from jarvis_pytest.evaluators import EVALUATORS

    if evaluators is None:
        evaluators = EVALUATORS
    from jarvis_pytest.generators import GENERATORS

    for i, spec in enumerate(evaluate):
        if spec.func not in evaluators:
            raise where.at(f"evaluate[{i}].func").error(
                f"unknown evaluator {spec.func!r}", f"use one of {sorted(evaluators)} or register it in "
                "jarvis_pytest/evaluators/")
    for i, step in enumerate(config):
        if step.type == "upload_file" and step.generator is not None and step.generator not in GENERATORS:
            raise where.at(f"config[{i}].generator").error(
                f"unknown file generator {step.generator!r}", f"use one of {sorted(GENERATORS)} or register it in "
                "jarvis_pytest/generators/")
    # the functions as registered now (a bare set of names: those of them the registry has)
    functions = evaluators if isinstance(evaluators, Mapping) else \
        {name: EVALUATORS[name] for name in evaluators if name in EVALUATORS}
    check_evaluator_args(evaluate, where, functions, samples)


def negative_problems(tpl: TaskTemplate) -> list[str]:
    """What the template's `negatives` lack (empty when it has an `artefact` and a wrong/partial/damage state)."""
    kinds = {n.kind for n in tpl.negatives}
    problems = []
    if "artefact" not in kinds:
        problems.append("no `artefact` negative (the output where asked, its substance wrong or missing)")
    if not kinds - {"artefact"}:
        problems.append("no `wrong`, `partial` or `damage` negative (a wrong or partial operation, or damage to "
                        "what the instruction did not touch)")
    return problems


def _check_placeholders(text: str, slots: dict[str, Any], types: TypeSystem, tpl: TaskTemplate, where: Where,
                        hint: str = "") -> None:
    for ph in find_placeholders(text, where):
        if ph.name not in slots:
            known = ", ".join(sorted(slots)) or "none"
            raise where.error(f"placeholder {ph.text} names no slot (slots: {known})",
                              f"declare a slot {ph.name!r} or fix the spelling" + (f"; {hint}" if hint else ""))
        if ph.attr is not None:
            slot_type = slots[ph.name].type
            if not (types.is_file(slot_type) or slot_type == "directory"):
                raise where.error(f"placeholder {ph.text} takes a path part of {ph.name!r}, which is a "
                                  f"{slot_type!r}, not a file", f"use {{{{{ph.name}}}}}")
