"""Evaluator arguments checked at load against each evaluator's Python signature.

Every `evaluate` entry of a template (at library load) and of a dataset's subtask (at dataset load) names a
registered evaluator, called at evaluation as ``func(state, **args)``. Its `args` must fit the function: no
argument the function does not take (a misspelling would otherwise be a failed check at run time), every
argument without a default given, and each value of the annotated type (``list``, ``int``, ``bool``, ``str``,
``dict``, with their parameters; ``X | None`` also takes None, ``Any`` anything, a ``float`` also an int). The
first parameter (the final state) is not an argument; an evaluator with ``**kwargs`` takes any name.

The signature is read from the registry when the check runs, so whatever evaluators are registered then are
checked. In a template, an argument that is exactly one placeholder (``"{{count}}"``) takes the type of the slot's
value at render time: every value type the input slot's domain can draw (its choices, an int for a range, text
for a pattern), text for an output slot; any other string renders as text. A dataset's arguments are rendered.
"""

from __future__ import annotations

import builtins
import collections.abc
import difflib
import inspect
import types
import typing
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Callable, Mapping

from jarvis_pytest.tasks.templating import PLACEHOLDER, Where

_ANY = object()  # an annotation that cannot be read: not type-checked


@dataclass(frozen=True)
class Param:
    name: str
    required: bool
    annotation: Any  # a typing object, or _ANY


@dataclass(frozen=True)
class Signature:
    params: tuple[Param, ...]
    state: str | None       # the name of the first parameter (the final state), not an argument
    any_name: bool          # the function takes **kwargs

    @property
    def names(self) -> list[str]:
        return [p.name for p in self.params]


@dataclass(frozen=True)
class SlotValue:
    """A template argument that is one whole placeholder: at render time one of `samples` (one per value type)."""

    slot: str
    samples: tuple[Any, ...]


def _resolve(annotation: Any, func: Callable) -> Any:
    if annotation is inspect.Parameter.empty:
        return _ANY
    if not isinstance(annotation, str):
        return annotation
    namespace = {**vars(typing), **vars(builtins), **getattr(func, "__globals__", {})}
    try:
        return eval(annotation, namespace, {})  # noqa: S307 - an annotation of our own evaluator module
    except Exception:  # a name imported for type checking only: not checked
        return _ANY


@lru_cache(maxsize=None)
def signature_of(func: Callable) -> Signature:
    """The arguments `func(state, **args)` takes, with their annotations resolved (cached per function)."""
    sig = inspect.signature(func)
    params = list(sig.parameters.values())
    state = None
    if params and params[0].kind in (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD):
        state = params[0].name
        params = params[1:]
    out, any_name = [], False
    for p in params:
        if p.kind is inspect.Parameter.VAR_KEYWORD:
            any_name = True
        elif p.kind in (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY):
            out.append(Param(p.name, p.default is inspect.Parameter.empty, _resolve(p.annotation, func)))
    return Signature(tuple(out), state, any_name)


def type_text(annotation: Any) -> str:
    """An annotation as it is written (`list[str] | None`)."""
    if annotation is _ANY or annotation is Any:
        return "any value"
    if annotation is type(None) or annotation is None:
        return "None"
    if isinstance(annotation, type) and not typing.get_args(annotation):
        return annotation.__name__
    text = repr(annotation).replace("typing.", "")
    return text


def _json_type(value: Any) -> str:
    if value is None:
        return "null"
    return {bool: "bool", int: "int", float: "float", str: "str", list: "list", dict: "dict"}.get(
        type(value), type(value).__name__)


def _fits(annotation: Any, value: Any) -> bool:
    """Whether the JSON `value` is of the annotated type (unknown kinds of annotation accept anything)."""
    if annotation is _ANY or annotation is Any or annotation is object:
        return True
    if isinstance(value, SlotValue):  # a placeholder: every value type it can render to must fit
        return all(_fits(annotation, sample) for sample in value.samples)
    if isinstance(annotation, typing.TypeVar):
        return True
    if annotation is None or annotation is type(None):
        return value is None
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if origin is typing.Union or origin is types.UnionType:
        return any(_fits(a, value) for a in args)
    if origin is typing.Literal:
        return value in args
    if origin is typing.Annotated:
        return _fits(args[0], value)
    if annotation is bool:
        return isinstance(value, bool)
    if annotation is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if annotation is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if annotation is str:
        return isinstance(value, str)
    kind = origin or annotation
    if kind in (list, tuple, set, frozenset, collections.abc.Sequence, collections.abc.Iterable,
                collections.abc.Collection):
        if not isinstance(value, list):
            return False
        if not args:
            return True
        if kind is tuple and not (len(args) == 2 and args[1] is Ellipsis):
            return len(value) == len(args) and all(_fits(a, v) for a, v in zip(args, value))
        return all(_fits(args[0], v) for v in value)
    if kind in (dict, collections.abc.Mapping):
        if not isinstance(value, dict):
            return False
        if len(args) != 2:
            return True
        return all(_fits(args[0], k) and _fits(args[1], v) for k, v in value.items())
    return True  # a class of its own (a path, a model, ...): not judged from JSON


def _first_misfit(annotation: Any, value: Any) -> tuple[Any, str | None] | None:
    """None when `value` fits; else (the value that does not: a slot's sample for a whole placeholder, the slot
    it comes from) or (the value, None)."""
    if isinstance(value, SlotValue):
        for sample in value.samples:
            if not _fits(annotation, sample):
                return sample, value.slot
        return None
    return None if _fits(annotation, value) else (value, None)


def template_arg_values(args: Mapping[str, Any], samples: Mapping[str, tuple[Any, ...]]) -> dict[str, Any]:
    """A template's raw arguments with each string that is one whole placeholder (at any depth, in lists and
    dicts) made a SlotValue of its slot's samples; other strings stay text, which they render to."""
    def one(value: Any) -> Any:
        if isinstance(value, str):
            whole = PLACEHOLDER.fullmatch(value)
            if whole and whole.group(2) is None:
                return SlotValue(whole.group(1), tuple(samples.get(whole.group(1), ())))
            return value
        if isinstance(value, list):
            return [one(v) for v in value]
        if isinstance(value, dict):
            return {k: one(v) for k, v in value.items()}
        return value

    return {name: one(value) for name, value in args.items()}


def slot_samples(template: Any) -> dict[str, tuple[Any, ...]]:
    """For each slot of a template, a value of each type its rendered value can have (see the module's doc)."""
    out: dict[str, tuple[Any, ...]] = {}
    for name, slot in template.inputs.items():
        if slot.choices is not None:
            by_type: dict[type, Any] = {}
            for choice in slot.choices:
                by_type.setdefault(type(choice), choice)
            out[name] = tuple(by_type.values())
        elif slot.range is not None:
            out[name] = (slot.range[0],)
        elif slot.pattern is not None:
            out[name] = (slot.pattern,)
    for name, slot in template.outputs.items():
        out[name] = (slot.value,)
    return out


def check_evaluator_args(evaluate: list, where: Where, evaluators: Mapping[str, Callable],
                         samples: Mapping[str, tuple[Any, ...]] | None = None) -> None:
    """Raise the first argument problem of `evaluate` (unknown, missing or mistyped) as one ConfigError naming the
    field `evaluate[i].args.<name>` and the fix. `samples` (templates only): see `template_arg_values`."""
    for i, spec in enumerate(evaluate):
        func = evaluators.get(spec.func)
        if func is None or not callable(func):
            continue
        sig = signature_of(func)
        takes = ", ".join(sig.names) or "no arguments"
        here = where.at(f"evaluate[{i}]")
        for name in spec.args:
            if name in sig.names or (sig.any_name and name != sig.state):
                continue
            close = difflib.get_close_matches(name, sig.names, n=1, cutoff=0.6)
            hint = f"did you mean `{close[0]}`? " if close else "remove it or fix its spelling; "
            what = ("is the final state the harness passes, not an argument" if name == sig.state
                    else "has no such argument")
            raise here.at(f"args.{name}").error(f"evaluator {spec.func!r} {what} ({name!r})",
                                                f"{hint}the evaluator takes: {takes}")
        for param in sig.params:
            if param.required and param.name not in spec.args:
                raise here.at(f"args.{param.name}").error(
                    f"evaluator {spec.func!r} needs the argument {param.name!r}, which is missing",
                    f"add `{param.name}` ({type_text(param.annotation)}) to args; the evaluator takes: {takes}")
        values = template_arg_values(spec.args, samples) if samples is not None else spec.args
        for param in sig.params:
            if param.name not in values or param.annotation is _ANY:
                continue
            misfit = _first_misfit(param.annotation, values[param.name])
            if misfit is None:
                continue
            value, slot = misfit
            if slot is None and samples is not None:
                value = spec.args[param.name]  # as written in the template
            want = type_text(param.annotation)
            shown = repr(value) if len(repr(value)) <= 60 else repr(value)[:57] + "..."
            origin = f" from slot {slot!r}" if slot else ""
            fix = (f"make slot {slot!r} give {want} values, or pass another value" if slot
                   else f"write a value of type {want}")
            raise here.at(f"args.{param.name}").error(
                f"argument {param.name!r} of evaluator {spec.func!r} takes {want}, not {_json_type(value)} "
                f"{shown}{origin}", fix)
