"""The task model (paper §3.1, §4.1) as pydantic models.

A task is T = (I, O, D, Φ, P). A :class:`TaskTemplate` holds the static part (input slots I with their sampling
domains, platform P) and templated dynamic parts: output values, instruction D, evaluators Φ, setup steps and
the oracle solution, all written with ``{{slot}}`` placeholders. Binding input values materialises them,
(O, D, Φ) ← M(v_I), into a :class:`Subtask` (an *instance*). A :class:`Task` is a task graph in the paper's
dataset format: its nodes are ``formatted_subtasks`` (in execution order) and its ``edges`` connect an output
slot of one subtask to an input slot of a later one. An atomic task is a graph of one subtask.

Template files are JSON, one template object or a list of them per file, under ``<library>/<platform>/``; their
JSON Schema is printed by ``jarvis schema``.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal, Union

from pydantic import (BaseModel, ConfigDict, Field, StrictFloat, StrictInt, StrictStr, ValidationError,
                      model_validator)

from jarvis_pytest.devices.actions import Platform, parse_action

Scalar = Union[StrictInt, StrictFloat, StrictStr]
SlotName = Annotated[str, Field(pattern=r"^[a-z_][a-z0-9_]*$")]
Category = Literal["atomic", "sw", "mi", "md"]
Consumption = Literal["move", "delete", "edit"]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


# -- setup steps (the subtask's `config`) -----------------------------------------------------------------
class _Step(_Strict):
    platform: Platform | None = Field(default=None, description="run on this platform (default: the subtask's)")
    provides: SlotName | None = Field(
        default=None, description="the input slot this step prepares (e.g. uploads its file); the step is dropped "
        "when that input is fed by an upstream subtask of a composed task")


class UploadFile(_Step):
    """Put a file on the device: a fixture under fixtures/files/, literal (templated) text content, or the output
    of a registered file generator (`jarvis_pytest/generators/`) called with templated `args`."""

    type: Literal["upload_file"] = "upload_file"
    path: str
    fixture: str | None = Field(default=None, description="a path under fixtures/files/")
    content: str | None = Field(default=None, description="literal file content (templated)")
    generator: str | None = Field(default=None, description="a registered file generator, e.g. odt_document")
    args: dict[str, Any] = Field(default_factory=dict, description="the generator's arguments (templated)")

    @model_validator(mode="after")
    def _one_source(self) -> "UploadFile":
        if sum(x is not None for x in (self.fixture, self.content, self.generator)) != 1:
            raise ValueError("upload_file needs exactly one of `fixture`, `content` and `generator`")
        if self.args and self.generator is None:
            raise ValueError("upload_file `args` belong to a `generator`")
        if self.fixture is not None:
            parts = self.fixture.replace("\\", "/").split("/")
            if self.fixture.startswith(("/", "\\")) or (len(self.fixture) > 1 and self.fixture[1] == ":") \
                    or ".." in parts or not self.fixture.strip():
                raise ValueError(f"fixture {self.fixture!r} must be a relative path inside fixtures/files/ "
                                 "(no absolute path, no `..`)")
        return self


class Command(_Step):
    """Run a shell command on the device."""

    type: Literal["command"] = "command"
    command: str
    user: str | None = None
    timeout: float | None = None
    allow_fail: bool = False


class Launch(_Step):
    """Start an application."""

    type: Literal["launch"] = "launch"
    app: str
    args: list[str] = Field(default_factory=list)


class Open(_Step):
    """Open a file with its default application."""

    type: Literal["open"] = "open"
    path: str


class Sleep(_Step):
    """Wait before the next step."""

    type: Literal["sleep"] = "sleep"
    seconds: float = Field(default=1.0, ge=0, le=120)


SetupStep = Annotated[Union[UploadFile, Command, Launch, Open, Sleep], Field(discriminator="type")]
SETUP_STEP_TYPES: tuple[str, ...] = ("upload_file", "command", "launch", "open", "sleep")


# -- evaluators and oracle solutions ------------------------------------------------------------------------
class EvaluatorSpec(_Strict):
    """An evaluator by registered name, with templated keyword arguments."""

    func: str = Field(min_length=1)
    args: dict[str, Any] = Field(default_factory=dict)


class SolutionStep(_Strict):
    """One oracle step: an action of the unified action space, or a command run on the device."""

    action: dict[str, Any] | None = None
    command: str | None = None
    user: str | None = None
    platform: Platform | None = None
    timeout: float | None = None
    note: str | None = None

    @model_validator(mode="after")
    def _one_kind(self) -> "SolutionStep":
        if (self.action is None) == (self.command is None):
            raise ValueError("a solution step needs exactly one of `action` and `command`")
        if self.action is not None:
            try:
                parse_action(self.action)
            except ValidationError as exc:
                first = exc.errors()[0]
                loc = ".".join(str(x) for x in first["loc"])
                raise ValueError(f"invalid action ({loc}: {first['msg']})") from None
        return self


NegativeKind = Literal["artefact", "wrong", "partial", "damage"]
NEGATIVE_KINDS: tuple[str, ...] = ("artefact", "wrong", "partial", "damage")


class Negative(_Strict):
    """A near-miss wrong final state (an adversary's cheap answer) that the task's evaluators must reject.

    `steps` run after set-up like oracle steps (commands or actions). `kind`: `artefact` — the output exists
    where asked but its substance is wrong or missing; `wrong` — a wrong value or direction; `partial` — only
    part of the work; `damage` — the work done, plus damage to what the instruction did not touch.
    """

    kind: NegativeKind
    note: str = Field(min_length=1, description="the mistake this state models")
    steps: list[SolutionStep] = Field(min_length=1)


# -- templates ---------------------------------------------------------------------------------------------
class InputSlot(_Strict):
    """An input slot (id, type) with the domain its value is sampled from: `choices`, `range` or `pattern`.

    `pattern` is text with tokens `{int:LO-HI}` (a random integer) and `{word}` (a random common word).
    """

    type: str
    description: str = ""
    choices: list[Scalar] | None = Field(default=None, min_length=1)
    range: tuple[int, int] | None = None
    pattern: str | None = None
    feedable: bool = Field(
        default=True, description="false when the task assumes the content its own setup gives this input (e.g. "
        "the word to replace is in the file): composition then never feeds it from an upstream subtask")

    @model_validator(mode="after")
    def _domain(self) -> "InputSlot":
        given = [k for k in ("choices", "range", "pattern") if getattr(self, k) is not None]
        if len(given) > 1:
            raise ValueError(f"give one sampling domain, not {' and '.join(given)}")
        if self.range is not None and self.range[0] > self.range[1]:
            raise ValueError(f"range {list(self.range)} is empty (write [low, high])")
        return self

    @property
    def has_domain(self) -> bool:
        return self.choices is not None or self.range is not None or self.pattern is not None


class OutputSlot(_Strict):
    """An output slot (id, type) whose value is materialised from the inputs by a template (the paper's M(v_I))."""

    type: str
    value: str = Field(description="template of the value, e.g. {{folder}}/{{name}}_sorted.xlsx")
    same_type_as: SlotName | None = Field(
        default=None, description="the output has the (bound) type of this input, e.g. a renamed file")
    content_checked: bool = Field(
        default=True, description="whether this task's evaluators read the output's content (not only its "
        "presence); an in-place edit by a later subtask then makes the task unevaluable")
    description: str = ""


class TaskTemplate(_Strict):
    """An atomic task template (one per annotated task of the paper)."""

    id: str = Field(pattern=r"^[a-z0-9][a-z0-9_.-]*$", description="e.g. ubuntu-calc-sort_column")
    platform: Platform
    app: str = Field(min_length=1)
    instruction: str = Field(min_length=1)
    inputs: dict[SlotName, InputSlot] = Field(default_factory=dict)
    outputs: dict[SlotName, OutputSlot] = Field(default_factory=dict)
    config: list[SetupStep] = Field(default_factory=list, description="setup steps run before the agent starts")
    evaluate: list[EvaluatorSpec] = Field(min_length=1)
    solution: list[SolutionStep] = Field(default_factory=list, description="the oracle's steps")
    negatives: list[Negative] = Field(
        default_factory=list, description="near-miss wrong final states that must fail (`jarvis qc` runs them); "
        "at least an `artefact` and one of `wrong`/`partial`/`damage`")
    baseline: list[str] = Field(
        default_factory=list, description="paths (templated) on the device whose content right after set-up "
        "evaluators compare with (`state.baseline(path)`), e.g. the original of a file the task edits; a path "
        "that an upstream subtask feeds is not captured (its baseline is then unknown)")
    consumes: dict[SlotName, Consumption] = Field(
        default_factory=dict, description="input slots whose file this task moves, deletes or edits in place")
    settings: list[str] = Field(
        default_factory=list, description="device settings this task changes (e.g. wallpaper); two subtasks on "
        "one platform must not change the same setting")
    source_platform: Platform | None = Field(default=None, description="built-in transfer tasks only")
    max_steps: int | None = Field(default=None, ge=1)
    window: str | None = Field(
        default=None, description="text the title of the application's window shows once set up (templated, "
        "e.g. {{doc.name}}; case-insensitive; with `*` a whole title, `*` any text, e.g. \"{{doc.name}} - "
        "*wordpad\" to tell WordPad from Notepad on the same file); the oracle brings that window to the front "
        "before its GUI steps in a composed task, where other subtasks' applications are open too")
    backends: list[str] = Field(
        default_factory=list, description="the device backends of its platform the template runs on (e.g. "
        "[\"kvm\"] for an application only a real Windows has); empty: every backend. Instances on another "
        "backend are skipped with the reason")
    description: str = ""


TEMPLATE_FILE_SCHEMA_TITLE = "jarvis-pytest task template file (one template or a list of templates)"


# -- instances, task graphs and the dataset file ----------------------------------------------------------------
class BoundSlot(_Strict):
    """A slot with its bound type and value."""

    type: str
    value: Scalar
    content_checked: bool | None = Field(default=None, description="written only when false (see OutputSlot)")


class Subtask(_Strict):
    """A task instance: a template with its slot values bound and O, D, Φ, setup and solution materialised."""

    template: str
    platform: Platform
    app: str
    instruction: str
    input: dict[str, BoundSlot]
    output: dict[str, BoundSlot]
    config: list[SetupStep]
    evaluate: list[EvaluatorSpec]
    solution: list[SolutionStep] = Field(default_factory=list)
    negatives: list[Negative] | None = Field(default=None, description="atomic instances only (for `jarvis qc`)")
    baseline: list[str] = Field(default_factory=list)
    consumes: dict[str, Consumption] = Field(default_factory=dict)
    settings: list[str] = Field(default_factory=list)
    source_platform: Platform | None = None
    max_steps: int | None = None
    backends: list[str] | None = Field(default=None, description="as the template's (absent: every backend)")
    window: str | None = None
    opens: list[Union[Launch, Open]] | None = Field(
        default=None, description="set-up steps held back because they open a file an upstream subtask makes or "
        "changes (at set-up it would show a missing or stale file): the instruction asks to open it, and the "
        "oracle runs these steps first")


class Edge(_Strict):
    """Output slot `from` = [subtask index, slot] feeds input slot `to` = [subtask index, slot]."""

    model_config = ConfigDict(extra="forbid", populate_by_name=True)

    from_: tuple[int, str] = Field(alias="from")
    to: tuple[int, str]


class Task(_Strict):
    """One entry of a dataset file: a task graph whose nodes are `formatted_subtasks` in execution order."""

    id: str = Field(min_length=1)
    category: Category
    devices: list[Platform]
    instruction: str
    edges: list[Edge] = Field(default_factory=list)
    formatted_subtasks: list[Subtask] = Field(min_length=1)
    template_instruction: str | None = Field(
        default=None, description="the deterministic merged instruction, kept when `instruction` was rewritten")
    judge: dict[str, int] | None = Field(default=None, description="LLM-judge scores, when the filter ran")

    def to_json(self) -> dict[str, Any]:
        """The dataset-format dict (what the harness consumes)."""
        return self.model_dump(mode="json", by_alias=True, exclude_none=True)


class Dataset(_Strict):
    """A dataset file: `tasks` (paper appendix, "Configuration File Details") and generator metadata."""

    tasks: list[Task]
    meta: dict[str, Any] = Field(default_factory=dict)
