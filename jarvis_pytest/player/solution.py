"""A run recorded in the player (or any agent's run) saved as its template's `gui_solution`.

The GUI solution is the trajectory's plain actions in order (`jarvis gui-solution <run>/tasks/<task>`), as the
schema takes them (`tasks.model.GuiStep`): pointer actions keep the device pixels the person clicked (a GUI
solution may name targets instead; a recording cannot know them), DONE and FAIL are left out (the GUI oracle ends
the task itself), and so is a step the device refused (it did nothing). Two things make it a solution of the
template rather than of the one instance played:

- **Placeholders**: where typed text holds a slot's value of the instance (or the name or stem of a path value),
  that part becomes the slot's placeholder (`{{new_word}}`, `{{renamed_file.name}}`), kept only where rendering it
  back gives exactly the text typed; so another instance types its own values.
- **Pace**: before each action but the first, and before the DONE that ends the recording (the person saw their
  last action, a save, take effect), a `WAIT` of as long as the device had between the previous action
  and this one in the recording (its observation and the person's decision), and never under `SETTLE` seconds:
  a person waits for a dialog to open, while the GUI oracle acts at once, and on a loaded machine the dialog a
  person saw open in 0.3 s may take a second (`max_wait` seconds at most, default 5). Pixel steps replayed at a
  pace stay weaker than steps that name their targets, which wait for exactly what they need.

A step the schema refuses is refused here with the file, the step and the fix (a PYAUTOGUI script, say): the
template with its new GUI solution is checked as the library checks templates, before anything is written.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any, Mapping

from pydantic import ValidationError

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.results.model import StepRecord, TaskResult
from jarvis_pytest.tasks.instances import atomic_task
from jarvis_pytest.tasks.library import Library, load_library, pydantic_error, validate_template
from jarvis_pytest.tasks.model import TaskTemplate
from jarvis_pytest.tasks.templating import path_part, render_text

MAX_WAIT = 5.0  # seconds of one WAIT for the recorded pace, at most
SETTLE = 1.0  # seconds between two recorded actions, at least (a shortcut's dialog opening on a loaded machine)
MIN_VALUE = 3  # characters a slot value needs to be taken for a placeholder (shorter ones occur by chance)
ENDS = ("DONE", "FAIL")


def placeholder_candidates(values: Mapping[str, Any]) -> list[tuple[str, str]]:
    """(text, placeholder) pairs for the instance's text values: each value, and the name and stem of a path
    value; longest text first, one placeholder per text (the first slot in sorted order)."""
    found: dict[str, str] = {}
    pairs: list[tuple[str, str]] = []
    for name in sorted(values):
        value = values[name]
        if not isinstance(value, str):
            continue
        pairs.append((value, f"{{{{{name}}}}}"))
        if "/" in value or "\\" in value:
            pairs += [(path_part(value, attr), f"{{{{{name}.{attr}}}}}") for attr in ("name", "stem")]
    for text, ph in pairs:
        if len(text.strip()) >= MIN_VALUE and text not in found:
            found[text] = ph
    return sorted(found.items(), key=lambda kv: (-len(kv[0]), kv[1]))


def with_placeholders(text: str, values: Mapping[str, Any]) -> str:
    """`text` with the instance's values in it written as their placeholders (longest first, left to right); the
    text itself when that would not render back to exactly `text`, or when it holds `{{` of its own."""
    if "{{" in text or "}}" in text:
        return text
    candidates = placeholder_candidates(values)
    if not candidates:
        return text
    pattern = re.compile("|".join(re.escape(t) for t, _ in candidates))
    table = dict(candidates)
    out = pattern.sub(lambda m: table[m.group(0)], text)
    try:
        return out if render_text(out, values) == text else text
    except ConfigError:
        return text


def gui_steps(records: list[StepRecord], values: Mapping[str, Any], *,
              max_wait: float = MAX_WAIT) -> tuple[list[dict[str, Any]], list[str]]:
    """The GUI solution steps (plain dicts, not yet checked) of a trajectory, and notes on what was left out or
    changed."""
    steps: list[dict[str, Any]] = []
    notes: list[str] = []
    for rec in records:
        action = rec.action
        if not action:
            continue
        kind = action.get("type")
        if kind == "DONE" and steps:  # the person saw the last action take effect (a save) before saying done
            steps.append({"type": "WAIT", "seconds": _pace(rec, max_wait)})
        if kind in ENDS:
            continue
        if rec.error:
            notes.append(f"step {rec.index} ({kind}) left out: the device refused it ({rec.error})")
            continue
        if kind != "WAIT" and steps:
            steps.append({"type": "WAIT", "seconds": _pace(rec, max_wait)})
        step = {k: v for k, v in action.items() if v is not None}
        if kind == "TYPING":
            text = with_placeholders(step["text"], values)
            if text != step["text"]:
                notes.append(f"step {rec.index}: typed {step['text']!r} saved as {text!r}")
            step["text"] = text
        step["note"] = f"recorded: step {rec.index}"
        steps.append(step)
    return steps, notes


def _pace(rec: StepRecord, max_wait: float) -> float:
    """The WAIT before a recorded step: as long as the device had before it (its observation and the person's
    decision), between SETTLE and `max_wait` seconds."""
    return round(max(SETTLE, min((rec.observe_ms + rec.agent_ms) / 1000, max_wait)), 1)


def read_run(task_dir: Path) -> tuple[TaskResult, list[StepRecord]]:
    """A task folder's result and trajectory."""
    result_path, traj_path = task_dir / "result.json", task_dir / "traj.jsonl"
    try:
        result = TaskResult.model_validate_json(result_path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ConfigError(f"no readable result ({exc.__class__.__name__})", path=result_path,
                          fix="give a task folder of a run: reports/<run>/tasks/<task>") from None
    records = []
    try:
        lines = traj_path.read_text(encoding="utf-8").splitlines()
    except OSError as exc:
        raise ConfigError(f"no trajectory ({exc.strerror})", path=traj_path, fix="give a task folder of a run") from None
    for n, line in enumerate(lines, 1):
        if line.strip():
            try:
                records.append(StepRecord.model_validate_json(line))
            except ValueError:
                raise ConfigError(f"line {n} is not a step", path=traj_path, fix="use a traj.jsonl of a run") from None
    return result, records


def template_of(result: TaskResult, library: Library) -> tuple[TaskTemplate, dict[str, Any]]:
    """The template of an atomic task's result and the slot values of the instance that ran."""
    m = re.fullmatch(r"(.+)\[seed(\d+)\]", result.task_id)
    if result.category != "atomic" or m is None:
        raise ConfigError(f"task {result.task_id!r} is a composed task: GUI solutions belong to atomic templates",
                          fix="play an atomic task (<template id>[seedN]) and save that")
    try:
        template = library.get(m.group(1))
    except KeyError:
        raise ConfigError(f"no template {m.group(1)!r} in the library", path=library.root,
                          fix="pass the --library the run used") from None
    sub = atomic_task(template, int(m.group(2))).formatted_subtasks[0]
    values = {name: slot.value for name, slot in {**sub.input, **sub.output}.items()}
    return template, values


def _template_items(path: Path) -> tuple[Any, list[dict[str, Any]]]:
    data = json.loads(path.read_text(encoding="utf-8"))
    return data, (data if isinstance(data, list) else [data])


def save(task_dir: Path, library_root: Path, *, out: Path | None = None, write: bool = False, force: bool = False,
         max_wait: float = MAX_WAIT) -> tuple[Path | None, list[dict[str, Any]], list[str]]:
    """Make the GUI solution of the run in `task_dir` and check it as the library checks templates. With `out`,
    write the template with it to that file; with `write`, put it in the template's own file (refused where the
    template has a GUI solution, unless `force`). Returns the file written (or None), the steps and the notes."""
    library = load_library(library_root)
    result, records = read_run(task_dir)
    template, values = template_of(result, library)
    source = library.sources[template.id]
    steps, notes = gui_steps(records, values, max_wait=max_wait)
    if not steps:
        raise ConfigError("the run has no action to save", path=task_dir / "traj.jsonl",
                          fix="play the task first (jarvis play), then save its run")
    data, items = _template_items(source)
    item = next(i for i in items if i.get("id") == template.id)
    if write and item.get("gui_solution") and not force:
        raise ConfigError(f"template {template.id!r} has a gui_solution already", path=source,
                          fix="pass --force to replace it, or --out FILE to write a copy")
    item["gui_solution"] = steps
    try:
        new = TaskTemplate.model_validate(item)
    except ValidationError as exc:
        raise pydantic_error(exc, path=source, task=template.id) from None
    validate_template(new, library.types, path=source)
    target = source if write else out
    if target is not None:
        target.parent.mkdir(parents=True, exist_ok=True)
        text = json.dumps(data if write else item, indent=2, ensure_ascii=False) + "\n"
        target.write_text(text, encoding="utf-8")
    return target, steps, notes
