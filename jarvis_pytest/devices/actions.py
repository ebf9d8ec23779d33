"""The unified action space (paper, table "Action Space"), shared by agents, the harness and the control server.

Every action is a pydantic model with a literal ``type``; ``Action`` is their discriminated union, so
``parse_action({"type": "CLICK", "x": 10, "y": 20})`` validates one action and rejects unknown ones with a
message that names the field. Coordinates are in the device's own screen pixels.
"""

from __future__ import annotations

from typing import Annotated, Literal, Union

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter

from jarvis_pytest.devices.platforms import PLATFORM_NAMES

Button = Literal["left", "middle", "right"]
Platform = Literal[PLATFORM_NAMES]  # type: ignore[valid-type]
PLATFORMS: tuple[str, ...] = PLATFORM_NAMES


class _Action(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class MoveTo(_Action):
    """Move the cursor to (x, y)."""

    type: Literal["MOVE_TO"] = "MOVE_TO"
    x: int
    y: int


class Click(_Action):
    """Click at (x, y), or at the current position when x and y are omitted."""

    type: Literal["CLICK"] = "CLICK"
    x: int | None = None
    y: int | None = None
    button: Button = "left"
    clicks: int = Field(default=1, ge=1, le=3)


class MouseDown(_Action):
    type: Literal["MOUSE_DOWN"] = "MOUSE_DOWN"
    button: Button = "left"


class MouseUp(_Action):
    type: Literal["MOUSE_UP"] = "MOUSE_UP"
    button: Button = "left"


class RightClick(_Action):
    type: Literal["RIGHT_CLICK"] = "RIGHT_CLICK"
    x: int | None = None
    y: int | None = None


class DoubleClick(_Action):
    type: Literal["DOUBLE_CLICK"] = "DOUBLE_CLICK"
    x: int | None = None
    y: int | None = None


class DragTo(_Action):
    """Drag with the left button from (start_x, start_y) (default: the cursor) to (x, y)."""

    type: Literal["DRAG_TO"] = "DRAG_TO"
    x: int
    y: int
    start_x: int | None = None
    start_y: int | None = None


class Scroll(_Action):
    """Scroll the wheel by (dx, dy) notches (positive dy scrolls down), optionally at (x, y) first."""

    type: Literal["SCROLL"] = "SCROLL"
    dx: int = 0
    dy: int = 0
    x: int | None = None
    y: int | None = None


class Swipe(_Action):
    """Touch swipe from (x, y) by offset (dx, dy) in pixels over `duration` ms (mobile; a drag on desktops)."""

    type: Literal["SWIPE"] = "SWIPE"
    x: int
    y: int
    dx: int
    dy: int
    duration: int = Field(default=300, ge=0, le=10_000)


class LongPress(_Action):
    """Press at (x, y) for `duration` ms."""

    type: Literal["LONG_PRESS"] = "LONG_PRESS"
    x: int
    y: int
    duration: int = Field(default=800, ge=0, le=10_000)


class Typing(_Action):
    """Type `text` exactly (any Unicode, including <>{})."""

    type: Literal["TYPING"] = "TYPING"
    text: str


class KeyDown(_Action):
    type: Literal["KEY_DOWN"] = "KEY_DOWN"
    key: str


class KeyUp(_Action):
    type: Literal["KEY_UP"] = "KEY_UP"
    key: str


class Hotkey(_Action):
    """Press a key combination, e.g. ["ctrl", "s"]; a single key is a one-element list."""

    type: Literal["HOTKEY"] = "HOTKEY"
    keys: list[str] = Field(min_length=1)


class SystemButton(_Action):
    """Android system button: home, back, menu, enter, volume_up, volume_down."""

    type: Literal["SYSTEM_BUTTON"] = "SYSTEM_BUTTON"
    button: Literal["home", "back", "menu", "enter", "volume_up", "volume_down", "power"]


class Wait(_Action):
    type: Literal["WAIT"] = "WAIT"
    seconds: float = Field(default=1.0, ge=0, le=60)


class Done(_Action):
    """End the task, claiming success."""

    type: Literal["DONE"] = "DONE"


class Fail(_Action):
    """End the task, giving up."""

    type: Literal["FAIL"] = "FAIL"


class Pyautogui(_Action):
    """Run a raw pyautogui script on a desktop device."""

    type: Literal["PYAUTOGUI"] = "PYAUTOGUI"
    script: str


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
