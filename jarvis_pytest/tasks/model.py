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

from jarvis_pytest.devices.actions import ACTION_TYPES, Platform, parse_action

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


class FixedValueError(ValueError):
    """A validation error that knows its fix (`tasks.library.pydantic_error` puts it in the ConfigError)."""

    def __init__(self, message: str, fix: str):
        super().__init__(message)
        self.fix = fix


class GuiControl(_Strict):
    """A control as a person sees it, found in the accessibility tree (Ubuntu: AT-SPI; Windows: the window-handle
    tree): by its `role` ("push button", "text", "menu item", ...) or window `class` (Windows: "Edit", "Button"),
    and its `name` (a button's label, a menu item's text) or `text` (what an edit field holds). Names and texts
    match case-insensitively, whole (`Save` is not `Save As…`), or as a pattern where they hold `*` (any text)."""

    model_config = ConfigDict(extra="forbid", populate_by_name=True)

    role: str | None = Field(default=None, min_length=1)
    class_: str | None = Field(default=None, alias="class", min_length=1)
    name: str | None = None
    text: str | None = None

    @model_validator(mode="after")
    def _something(self) -> "GuiControl":
        if self.role is None and self.class_ is None and self.name is None and self.text is None:
            raise FixedValueError("a control names nothing to find it by",
                                  "give its `role` or `class`, and its `name` or `text`")
        return self


class GuiTarget(_Strict):
    """Where a GUI step acts, named by what a person sees, resolved to the centre of its box at run time: a
    `control` (in the `window` whose title shows that pattern, if given), a node that shows `text` (its name or its
    text), or a whole `window`. `index`: the n-th match (0: the first, in the tree's order)."""

    window: str | None = Field(default=None, min_length=1, description="the window's title: a case-insensitive "
                               "substring, or with `*` (any text) a pattern of the whole title, as the template's "
                               "`window`")
    control: GuiControl | None = None
    text: str | None = Field(default=None, min_length=1, description="text shown on screen: a node's name or text, "
                             "whole (case-insensitive), or a pattern with `*`")
    screen_text: str | None = Field(default=None, min_length=1, description="text read off the screen image (OCR) "
                                    "where no accessibility tree shows it (a title the window manager draws, "
                                    "Chromium's GTK file dialog): words on one line, matched as `text` is")
    index: int = Field(default=0, ge=0, le=100)

    @model_validator(mode="after")
    def _one_thing(self) -> "GuiTarget":
        if self.control is not None and self.text is not None:
            raise FixedValueError("a target names both a `control` and a `text`", "keep one of them")
        if self.screen_text is not None and (self.control is not None or self.text is not None
                                             or self.window is not None):
            raise FixedValueError("a target names `screen_text` and something of the accessibility tree",
                                  "keep `screen_text` alone: it is read off the screen image, not the tree")
        if self.control is None and self.text is None and self.window is None and self.screen_text is None:
            raise FixedValueError("a target names nothing", "give a `control` or a `text`, or a `window`")
        return self


#: Actions that a target may place (their x and y come from the target's box).
GUI_POINTED = frozenset({"MOVE_TO", "CLICK", "RIGHT_CLICK", "DOUBLE_CLICK", "DRAG_TO", "SCROLL", "SWIPE",
                         "LONG_PRESS"})
#: Action types a GUI solution may not use: a script can run anything (a shell command, a file write); the GUI
#: oracle ends the task itself.
GUI_REFUSED_ACTIONS = {"PYAUTOGUI": "a PYAUTOGUI script can run any Python (a shell command, a file write)",
                       "DONE": "the GUI oracle says DONE itself after the last step",
                       "FAIL": "a solution does not give up"}
#: Keys that make a step something other than an action: each is refused with what it is.
GUI_REFUSED_KEYS = {"command": "runs a shell command", "run": "runs a shell command", "shell": "runs a shell command",
                    "user": "runs a command as a user", "upload": "writes a file behind the application's back",
                    "upload_file": "writes a file behind the application's back",
                    "content": "writes a file behind the application's back",
                    "fixture": "writes a file behind the application's back",
                    "generator": "writes a file behind the application's back",
                    "path": "names a file (a GUI step acts on what the screen shows)",
                    "action": "wraps an action (write the action's fields in the step itself)"}
#: Set-up step types, refused as GUI steps with what they do.
GUI_SETUP_KINDS = {"upload_file": "writes a file behind the application's back", "command": "runs a shell command",
                   "launch": "starts a program from outside the GUI", "open": "opens a file from outside the GUI",
                   "sleep": "is a set-up step (use WAIT)"}
GUI_FIX = ("use only actions of the agent's action space (`jarvis_pytest/devices/actions.py`) and WAIT_FOR, with "
           "`target` for what the step acts on; where the GUI cannot do it, state `gui_infeasible` for the backend "
           "with the reason")
GUI_STEP_FIELDS = ("type", "target", "timeout", "gone", "note")


class GuiStep(BaseModel):
    """One step of a GUI solution: an action of the agent's action space with its own field names (`{"type":
    "HOTKEY", "keys": ["ctrl", "s"]}`), where a pointer action may name its `target` instead of `x`/`y` (found
    within `timeout` seconds, then clicked at its centre), or `WAIT_FOR` a target to show (`gone`: to go), which
    only observes. No command, no file write, no script: such a step is refused when the template loads."""

    model_config = ConfigDict(extra="allow", frozen=True)

    type: str
    target: GuiTarget | None = None
    timeout: float = Field(default=10.0, gt=0, le=120, description="seconds the target gets to show (or, "
                           "with `gone`, to go)")
    gone: bool = Field(default=False, description="WAIT_FOR only: wait until no such target shows")
    platform: Platform | None = Field(default=None, description="on this platform's device (default: the "
                                      "subtask's; the built-in transfer uploads on its source)")
    note: str | None = None

    @model_validator(mode="before")
    @classmethod
    def _refuse(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            raise FixedValueError("a GUI solution step must be an object (an action)", GUI_FIX)
        kind = data.get("type")
        if kind in GUI_SETUP_KINDS:
            raise FixedValueError(f"a GUI solution step cannot be a set-up step ({kind!r}): it "
                                  f"{GUI_SETUP_KINDS[kind]}", GUI_FIX)
        for key, what in GUI_REFUSED_KEYS.items():
            if key in data:
                raise FixedValueError(f"a GUI solution step cannot have `{key}`: it {what}", GUI_FIX)
        if kind in GUI_REFUSED_ACTIONS:
            raise FixedValueError(f"a GUI solution cannot use {kind}: {GUI_REFUSED_ACTIONS[kind]}", GUI_FIX)
        if kind != "WAIT_FOR" and kind not in ACTION_TYPES:
            allowed = sorted(set(ACTION_TYPES) - set(GUI_REFUSED_ACTIONS))
            raise FixedValueError(f"unknown GUI step type {kind!r}", f"use one of {allowed} or WAIT_FOR")
        return data

    @model_validator(mode="after")
    def _as_action(self) -> "GuiStep":
        extra = dict(self.__pydantic_extra__ or {})
        if self.type == "WAIT_FOR":
            if self.target is None:
                raise FixedValueError("WAIT_FOR needs a `target`", "name the window, control or text to wait for")
            if extra:
                raise FixedValueError(f"WAIT_FOR takes no {sorted(extra)[0]!r}", "give only target, timeout, gone")
            return self
        if self.gone:
            raise FixedValueError("`gone` belongs to WAIT_FOR", "remove it, or make the step a WAIT_FOR")
        if self.target is not None:
            if self.type not in GUI_POINTED:
                raise FixedValueError(f"{self.type} takes no `target` (it does not point)", "click the target in a "
                                      "step before it (CLICK with the target), then send the keys")
            given = sorted({"x", "y"} & set(extra))
            if given:
                raise FixedValueError(f"a step with a `target` cannot also give {' and '.join(given)}",
                                      "keep the target (resolved at run time) or the coordinates")
        try:
            self.action(0, 0)
        except ValidationError as exc:
            first = exc.errors()[0]
            loc = ".".join(str(x) for x in first["loc"][1:]) or first["loc"][0]
            raise FixedValueError(f"not a valid {self.type} action ({loc}: {first['msg']})",
                                  "use the action's own fields (see `jarvis_pytest/devices/actions.py`)") from None
        return self

    def action(self, x: int | None = None, y: int | None = None) -> Any:
        """The plain action this step sends; a targeted step's `x`, `y` are its target's centre."""
        fields = {"type": self.type, **(self.__pydantic_extra__ or {})}
        if self.target is not None and x is not None and y is not None:
            fields.update(x=x, y=y)
        return parse_action(fields)


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


class GuiValue(_Strict):
    """Text a GUI solution types that an input slot's choice decides: `text[choice]` for the slot's value."""

    slot: SlotName
    text: dict[str, str] = Field(min_length=1, description="the slot's choice (as text) → what to type for it")


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
    gui_solution: list[GuiStep] = Field(
        default_factory=list, description="the task solved through the GUI alone: actions of the agent's action "
        "space, targets named by what a person sees (`jarvis qc` checks the task passes after them; the "
        "`gui-oracle` agent runs them)")
    gui_values: dict[SlotName, GuiValue] = Field(
        default_factory=dict, description="text a GUI solution types that the choice of an input slot decides (the "
        "0 or 1 a registry value takes for `show` or `hide`): name → the slot and the text for each of its choices; "
        "a GUI step uses it as `{{name}}`")
    gui_infeasible: dict[str, str] = Field(
        default_factory=dict, description="backend → why the GUI cannot solve the task there (e.g. "
        "{\"wine\": \"Wine's Paint has no ...\"}); `jarvis qc` shows the reason instead of running a GUI solution")
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
    gui_solution: list[GuiStep] | None = Field(default=None, description="atomic instances only (for `jarvis qc` "
                                               "and the gui-oracle agent)")
    gui_infeasible: dict[str, str] | None = Field(default=None, description="atomic instances only: backend → why "
                                                  "the GUI cannot solve it there")
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
