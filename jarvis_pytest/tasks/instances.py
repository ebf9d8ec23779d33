"""Instantiation: sample input values from their domains (seeded) and materialise (O, D, Φ) ← M(v_I).

Every random choice goes through a `random.Random` passed in by the caller, and slots are visited in sorted
order, so equal seeds give equal instances. An atomic instance of template `t` with seed `n` has the id
``t[seed<n>]`` and draws from ``Random("t#seed<n>")``: adding or removing other templates does not change it.
"""

from __future__ import annotations

import random
import re
from typing import TYPE_CHECKING, Any, Mapping

from pydantic import TypeAdapter

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.tasks.model import (BoundSlot, EvaluatorSpec, GuiStep, InputSlot, Negative, Scalar, SetupStep,
                                       SolutionStep, Subtask, Task, TaskTemplate)
from jarvis_pytest.tasks.templating import Where, render_data, render_text

if TYPE_CHECKING:
    from jarvis_pytest.tasks.library import Library

PATTERN_TOKEN = re.compile(r"\{(?:int:(-?\d+)-(-?\d+)|word)\}")
WORDS = ("alpha", "amber", "atlas", "birch", "bravo", "cedar", "comet", "coral", "delta", "ember", "falcon", "fern",
         "garnet", "harbor", "hazel", "indigo", "jasper", "juniper", "kestrel", "lotus", "maple", "meadow", "nova",
         "onyx", "orchid", "pebble", "quartz", "raven", "river", "saffron", "sierra", "summit", "tango", "topaz",
         "umber", "velvet", "willow", "zephyr")
_STEP = TypeAdapter(SetupStep)


def check_pattern(pattern: str) -> None:
    """Raise ValueError unless `pattern` uses only `{int:LO-HI}` and `{word}` tokens."""
    rest = PATTERN_TOKEN.sub("", pattern)
    if "{" in rest or "}" in rest:
        raise ValueError(f"pattern {pattern!r} has a brace that is not a token {{int:LO-HI}} or {{word}}")
    for m in PATTERN_TOKEN.finditer(pattern):
        if m.group(1) is not None and int(m.group(1)) > int(m.group(2)):
            raise ValueError(f"pattern token {m.group(0)} is an empty range")


def sample_value(slot: InputSlot, rng: random.Random) -> Scalar:
    """One value from the slot's domain."""
    if slot.choices is not None:
        return rng.choice(slot.choices)
    if slot.range is not None:
        return rng.randint(slot.range[0], slot.range[1])
    if slot.pattern is not None:
        def token(m: re.Match[str]) -> str:
            if m.group(1) is not None:
                return str(rng.randint(int(m.group(1)), int(m.group(2))))
            return rng.choice(WORDS)
        return PATTERN_TOKEN.sub(token, slot.pattern)
    raise ValueError("slot has no sampling domain")


def sample_inputs(template: TaskTemplate, rng: random.Random) -> dict[str, Scalar]:
    """A value for every input slot that has a domain, in sorted slot order."""
    return {name: sample_value(template.inputs[name], rng) for name in sorted(template.inputs)
            if template.inputs[name].has_domain}


def _render_steps(steps: list, model: type | TypeAdapter, values: Mapping[str, Scalar], where: Where) -> list:
    out = []
    for i, step in enumerate(steps):
        data = render_data(step.model_dump(mode="json"), values, Where(where.path, where.task, f"{where.field}[{i}]"),
                           keep_types=model is not GuiStep)  # a GUI step's `{{number}}` is text to type
        data.pop("provides", None)
        out.append(model.validate_python(data) if isinstance(model, TypeAdapter) else model.model_validate(data))
    return out


def _gui_fields(template: TaskTemplate, values: Mapping[str, Scalar], where: Where) -> dict[str, Any]:
    """A subtask's `gui_solution` and `gui_infeasible`, rendered from its template with `values` (None when empty);
    the GUI solution also with its `gui_values`, the text each takes for its slot's value."""
    typed = {**values, **{name: v.text[str(values[v.slot])] for name, v in template.gui_values.items()
                          if str(values.get(v.slot)) in v.text}}
    return {"gui_solution": _render_steps(template.gui_solution, GuiStep, typed, where.at("gui_solution")) or None,
            "gui_infeasible": {k: render_text(v, values, where.at(f"gui_infeasible.{k}"))
                               for k, v in sorted(template.gui_infeasible.items())} or None}


def materialise(template: TaskTemplate, values: Mapping[str, Scalar], *, fed: Mapping[str, BoundSlot] | None = None,
                source: object = None, gui: bool = False) -> Subtask:
    """Bind the inputs (sampled `values`, overridden by `fed` slots from upstream subtasks) and render the rest.

    Setup steps that `provide` a fed input are dropped: the upstream subtask produces that input; so are baseline
    paths that are a fed input's value (what an upstream subtask makes is not known at set-up). Negatives are
    rendered for atomic instances only (nothing is fed): they are the quality gate's, not a composed task's. The
    GUI solution and where it is infeasible are rendered only with `gui` (atomic instances: composed tasks have no
    GUI solutions yet).
    """
    fed = dict(fed or {})
    where = Where(source, template.id)
    inputs: dict[str, BoundSlot] = {}
    for name in sorted(template.inputs):
        if name in fed:
            inputs[name] = BoundSlot(type=fed[name].type, value=fed[name].value)
        elif name in values:
            inputs[name] = BoundSlot(type=template.inputs[name].type, value=values[name])
        else:
            raise where.at(f"inputs.{name}").error(f"input slot {name!r} has no value and no upstream subtask",
                                                   "give it a sampling domain (choices, range or pattern)")
    input_values = {name: slot.value for name, slot in inputs.items()}
    outputs: dict[str, BoundSlot] = {}
    for name in sorted(template.outputs):
        spec = template.outputs[name]
        value = render_text(spec.value, input_values, where.at(f"outputs.{name}.value"))
        bound_type = inputs[spec.same_type_as].type if spec.same_type_as else spec.type
        outputs[name] = BoundSlot(type=bound_type, value=value, content_checked=None if spec.content_checked else False)
    every = {**input_values, **{name: slot.value for name, slot in outputs.items()}}
    kept = [step for step in template.config if step.provides is None or step.provides not in fed]
    held = [step for step in kept if _opens_fed(step, fed)]
    config = _render_steps([step for step in kept if step not in held], _STEP, every, where.at("config"))
    instruction = template.instruction
    for name in sorted({name for step in held for name in fed if _mentions(step, name)}):
        instruction = re.sub(r"\{\{" + name + r"\}\} is open in ([^.]+)\.", "Open {{" + name + r"}} in \1.",
                             instruction)
    _check_upload_paths(config, template.platform, where)
    fed_values = {str(slot.value) for slot in fed.values()}
    baseline = [render_text(p, every, where.at(f"baseline[{i}]")) for i, p in enumerate(template.baseline)]
    negatives = None
    if not fed:
        negatives = [Negative(kind=n.kind, note=render_text(n.note, every, where.at(f"negatives[{i}].note")),
                              steps=_render_steps(n.steps, SolutionStep, every, where.at(f"negatives[{i}].steps")))
                     for i, n in enumerate(template.negatives)] or None
    return Subtask(
        template=template.id,
        platform=template.platform,
        app=template.app,
        instruction=render_text(instruction, every, where.at("instruction")),
        input=inputs,
        output=outputs,
        config=config,
        evaluate=_render_steps(template.evaluate, EvaluatorSpec, every, where.at("evaluate")),
        solution=_render_steps(template.solution, SolutionStep, every, where.at("solution")),
        **(_gui_fields(template, every, where) if gui else {}),
        negatives=negatives,
        baseline=[p for p in baseline if p not in fed_values],
        consumes=dict(sorted(template.consumes.items())),
        settings=sorted(template.settings),
        source_platform=template.source_platform,
        max_steps=template.max_steps,
        backends=list(template.backends) or None,
        window=render_text(template.window, every, where.at("window")) if template.window else None,
        opens=_render_steps(held, _STEP, every, where.at("config")) or None,
    )


def _mentions(step: Any, name: str) -> bool:
    """Whether a launch's arguments or an open's path name the slot `name` (`{{name}}`, `{{name.attr}}`)."""
    texts = step.args if step.type == "launch" else [step.path]
    return any(re.search(r"\{\{" + name + r"(\.\w+)?\}\}", text) for text in texts)


def _opens_fed(step: Any, fed: Mapping[str, BoundSlot]) -> bool:
    """A set-up step that opens a fed input in its application: held back, since at set-up the upstream subtask
    has not made or changed that file yet."""
    return step.type in ("launch", "open") and any(_mentions(step, name) for name in fed)


def _check_upload_paths(config: list, platform: str, where: Where) -> None:
    """Set-up may put files only where a task may write on its device (no absolute host paths, no `..`)."""
    from jarvis_pytest.devices.platforms import spec

    for i, step in enumerate(config):
        target = step.platform or platform
        if step.type == "upload_file" and not spec(target).may_write(step.path):
            raise where.at(f"config[{i}].path").error(
                f"upload path {step.path!r} is not where a task may write on the {target} device",
                f"put it under {' or '.join(spec(target).writable_roots)}")


def instance_id(template_id: str, seed: int) -> str:
    """The readable id of an atomic instance, e.g. `ubuntu-calc-sort_column[seed0]`."""
    return f"{template_id}[seed{seed}]"


def atomic_task(template: TaskTemplate, seed: int, *, source: object = None) -> Task:
    """The atomic task (a graph of one subtask) of `template` with input values drawn for `seed`."""
    rng = random.Random(f"{template.id}#seed{seed}")
    sub = materialise(template, sample_inputs(template, rng), source=source, gui=True)
    return Task(id=instance_id(template.id, seed), category="atomic", devices=[template.platform],
                instruction=sub.instruction, edges=[], formatted_subtasks=[sub])


def atomic_instances(library: "Library", seeds_per_template: int = 2) -> list[Task]:
    """`seeds_per_template` seeded instances of every template of `library`, sorted by id then seed."""
    if seeds_per_template < 0:
        raise ConfigError("the number of instances per template cannot be negative", field="seeds_per_template",
                          fix="pass 1 or more")
    return [atomic_task(t, n, source=library.sources.get(t.id)) for t in library.templates
            for n in range(seeds_per_template)]



def with_gui_solutions(task: Task, library: "Library") -> Task:
    """`task` with each subtask's GUI solution (and GUI infeasibility) rendered from its template in `library` (the
    built-in transfer's from code) with the subtask's own slot values. Dataset files keep the paper's format, with
    no GUI solutions: they follow the templates as those gain them. A subtask whose template is not in the library,
    or that has a GUI solution of its own, is left as it is."""
    from jarvis_pytest.tasks.transfer import is_transfer, transfer_template

    subtasks = []
    for i, sub in enumerate(task.formatted_subtasks):
        if sub.gui_solution is None and sub.gui_infeasible is None:
            try:
                template = (transfer_template(sub.source_platform, sub.platform)
                            if is_transfer(sub.template) and sub.source_platform else library.get(sub.template))
            except (KeyError, ValueError):
                template = None
            if template is not None and (template.gui_solution or template.gui_infeasible):
                values = {name: slot.value for name, slot in {**sub.input, **sub.output}.items()}
                where = Where(None, task.id, f"formatted_subtasks[{i}]")
                sub = sub.model_copy(update=_gui_fields(template, values, where))
        subtasks.append(sub)
    return task.model_copy(update={"formatted_subtasks": subtasks})
