"""The unified action space (paper, table "Action Space"), shared by agents, the harness and the control server.

Every action is a pydantic model with a literal ``type``; ``Action`` is their discriminated union, so
``parse_action({"type": "CLICK", "x": 10, "y": 20})`` validates one action and rejects unknown ones with a
message that names the field. Coordinates are in the device's own screen pixels.

Every number is bounded and every text encodable (the bounds are `validate.py`'s, which the device servers check
too): a NaN, an infinity, a boolean for a number, a coordinate past ±32767, a SCROLL past ±100 notches, a TYPING
past 10,000 characters, a script past 20,000, a HOTKEY of more than 16 keys or a lone surrogate in any text is
refused here, and the loop feeds the refusal back to the agent as its step's error.
"""

from __future__ import annotations

from typing import Annotated, Literal, Union

from pydantic import AfterValidator, BaseModel, BeforeValidator, ConfigDict, Field, TypeAdapter

from jarvis_pytest.devices.platforms import PLATFORM_NAMES
from jarvis_pytest.devices.validate import (MAX_COORD, MAX_KEY_NAME, MAX_KEYS, MAX_SCRIPT, MAX_SCROLL, MAX_TEXT,
                                            problem_of_text)

Button = Literal["left", "middle", "right"]
Platform = Literal[PLATFORM_NAMES]  # type: ignore[valid-type]
PLATFORMS: tuple[str, ...] = PLATFORM_NAMES


def _not_bool(value: object) -> object:
    if isinstance(value, bool):
        raise ValueError("must be a number, not a boolean")
    return value


def _encodable(most: int):
    def check(text: str) -> str:
        problem = problem_of_text(text, most)
        if problem:
            raise ValueError(problem)
        return text
    return AfterValidator(check)


Coord = Annotated[int, BeforeValidator(_not_bool), Field(ge=-MAX_COORD, le=MAX_COORD)]
Notches = Annotated[int, BeforeValidator(_not_bool), Field(ge=-MAX_SCROLL, le=MAX_SCROLL)]
Millis = Annotated[int, BeforeValidator(_not_bool), Field(ge=0, le=10_000)]
KeyName = Annotated[str, Field(min_length=1), _encodable(MAX_KEY_NAME)]


class _Action(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class MoveTo(_Action):
    """Move the cursor to (x, y)."""

    type: Literal["MOVE_TO"] = "MOVE_TO"
    x: Coord
    y: Coord


class Click(_Action):
    """Click at (x, y), or at the current position when x and y are omitted."""

    type: Literal["CLICK"] = "CLICK"
    x: Coord | None = None
    y: Coord | None = None
    button: Button = "left"
    clicks: Annotated[int, BeforeValidator(_not_bool)] = Field(default=1, ge=1, le=3)


class MouseDown(_Action):
    type: Literal["MOUSE_DOWN"] = "MOUSE_DOWN"
    button: Button = "left"


class MouseUp(_Action):
    type: Literal["MOUSE_UP"] = "MOUSE_UP"
    button: Button = "left"


class RightClick(_Action):
    type: Literal["RIGHT_CLICK"] = "RIGHT_CLICK"
    x: Coord | None = None
    y: Coord | None = None


class DoubleClick(_Action):
    type: Literal["DOUBLE_CLICK"] = "DOUBLE_CLICK"
    x: Coord | None = None
    y: Coord | None = None


class DragTo(_Action):
    """Drag with the left button from (start_x, start_y) (default: the cursor) to (x, y)."""

    type: Literal["DRAG_TO"] = "DRAG_TO"
    x: Coord
    y: Coord
    start_x: Coord | None = None
    start_y: Coord | None = None


class Scroll(_Action):
    """Scroll the wheel by (dx, dy) notches (positive dy scrolls down), optionally at (x, y) first."""

    type: Literal["SCROLL"] = "SCROLL"
    dx: Notches = 0
    dy: Notches = 0
    x: Coord | None = None
    y: Coord | None = None


class Swipe(_Action):
    """Touch swipe from (x, y) by offset (dx, dy) in pixels over `duration` ms (mobile; a drag on desktops)."""

    type: Literal["SWIPE"] = "SWIPE"
    x: Coord
    y: Coord
    dx: Coord
    dy: Coord
    duration: Millis = 300


class LongPress(_Action):
    """Press at (x, y) for `duration` ms."""

    type: Literal["LONG_PRESS"] = "LONG_PRESS"
    x: Coord
    y: Coord
    duration: Millis = 800


class Typing(_Action):
    """Type `text` exactly (any Unicode, including <>{})."""

    type: Literal["TYPING"] = "TYPING"
    text: Annotated[str, _encodable(MAX_TEXT)]


class KeyDown(_Action):
    type: Literal["KEY_DOWN"] = "KEY_DOWN"
    key: KeyName


class KeyUp(_Action):
    type: Literal["KEY_UP"] = "KEY_UP"
    key: KeyName


class Hotkey(_Action):
    """Press a key combination, e.g. ["ctrl", "s"]; a single key is a one-element list."""

    type: Literal["HOTKEY"] = "HOTKEY"
    keys: list[KeyName] = Field(min_length=1, max_length=MAX_KEYS)


class SystemButton(_Action):
    """Android system button: home, back, menu, enter, volume_up, volume_down."""

    type: Literal["SYSTEM_BUTTON"] = "SYSTEM_BUTTON"
    button: Literal["home", "back", "menu", "enter", "volume_up", "volume_down", "power"]


class Wait(_Action):
    type: Literal["WAIT"] = "WAIT"
    seconds: Annotated[float, BeforeValidator(_not_bool)] = Field(default=1.0, ge=0, le=60)


class Done(_Action):
    """End the task, claiming success."""

    type: Literal["DONE"] = "DONE"


class Fail(_Action):
    """End the task, giving up."""

    type: Literal["FAIL"] = "FAIL"


class Pyautogui(_Action):
    """Run a raw pyautogui script on a desktop device."""

    type: Literal["PYAUTOGUI"] = "PYAUTOGUI"
    script: Annotated[str, _encodable(MAX_SCRIPT)]


Action = Annotated[
    Union[
        MoveTo, Click, MouseDown, MouseUp, RightClick, DoubleClick, DragTo, Scroll, Swipe, LongPress,
        Typing, KeyDown, KeyUp, Hotkey, SystemButton, Wait, Done, Fail, Pyautogui,
    ],
    Field(discriminator="type"),
]

ACTION_ADAPTER: TypeAdapter[Action] = TypeAdapter(Action)
ACTION_TYPES: tuple[str, ...] = tuple(
    cls.model_fields["type"].default
    for cls in (MoveTo, Click, MouseDown, MouseUp, RightClick, DoubleClick, DragTo, Scroll, Swipe, LongPress,
                Typing, KeyDown, KeyUp, Hotkey, SystemButton, Wait, Done, Fail, Pyautogui)
)
TERMINAL_TYPES = frozenset({"DONE", "FAIL"})


def parse_action(data: object) -> Action:
    """Validate a dict (or JSON string) as one action; raises pydantic.ValidationError naming the bad field."""
    if isinstance(data, (str, bytes)):
        return ACTION_ADAPTER.validate_json(data)
    return ACTION_ADAPTER.validate_python(data)
