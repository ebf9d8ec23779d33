"""A person's input in the player page, as actions of the unified action space (`devices/actions.py`).

The page sends what the browser saw, in the page's own terms (`event`): a click at a point of the screen as it is
displayed (and the displayed size), a drag, the wheel, a key with its modifiers, text. Everything is turned into
an action here, on the host, so that what a person did is decided in one place that the tests read:

- **Points**: a displayed point (x, y) of an image shown w × h maps to the device pixel (⌊x·W/w⌋, ⌊y·H/h⌋) of its
  W × H screen, clamped to the screen (`to_device`).
- **Keys**: a key with Ctrl, Alt or the OS key held, or a key that types nothing (Enter, Tab, Escape, Backspace,
  Delete, the arrows, Home/End, Page Up/Down, Insert, F1–F24, the menu key), becomes a HOTKEY of the device's key
  names (`ctrl`, `alt`, `shift`, `super`, `enter`, `f5`, ...): ["ctrl", "shift", "s"]. Shift alone with a
  character is that character. A letter or digit under modifiers is named by its physical key (`KeyS` → `s`), so
  Ctrl+Shift+S is ["ctrl", "shift", "s"] whatever the layout prints. Modifiers alone, dead keys and IME keys send
  nothing (`key_action` gives None).
- **Text** arrives as the text the browser typed (layouts, dead keys, IMEs and non-ASCII included), and becomes
  TYPING; text typed in a row is one TYPING (`merge`) until another input comes or the person pauses
  (`TEXT_IDLE`). The wheel's turns in one place are one SCROLL (`SCROLL_IDLE`; `PIXELS_PER_NOTCH` pixels of a
  pixel-mode wheel event are one notch). A second click in the same place within `CLICK_IDLE` makes a CLICK with
  clicks=2 (then 3), as the browser counts them (`detail`).
- **Touch screens** (`PlatformSpec.touch`: Android): a press held `LONG_PRESS_MS` or longer is a LONG_PRESS of that
  length, a drag is a SWIPE at the drag's own speed, and the page's system buttons (back, home, ...) are
  SYSTEM_BUTTON. **A pointer at rest** (the page sends `hover` once the mouse rested a second at a new place) is a
  MOVE_TO on a desktop (menus and tooltips that open under the pointer); a touch screen has no pointer, so nothing.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, replace
from typing import Any

from pydantic import ValidationError

from jarvis_pytest.devices.actions import (Action, Click, Done, DragTo, Fail, Hotkey, LongPress, MoveTo, RightClick,
                                           Scroll, Swipe, Typing, parse_action)
from jarvis_pytest.devices.platforms import PLATFORMS
from jarvis_pytest.devices.validate import MAX_SCROLL, MAX_TEXT

TEXT_IDLE = 0.8  # seconds of no typing after which the text typed so far is sent as one TYPING
SCROLL_IDLE = 0.4  # seconds of no wheel turns after which they are sent as one SCROLL
CLICK_IDLE = 0.35  # seconds a click waits for a second one in the same place (a double click)
NEAR = 8  # device pixels: clicks or wheel turns this close are in the same place
PIXELS_PER_NOTCH = 100.0  # a pixel-mode wheel event of this many pixels is one notch (Chromium's step)
LINES_PER_NOTCH = 3.0  # a line-mode wheel event of this many lines is one notch
PAGE_NOTCHES = 10  # a page-mode wheel event is this many notches
LONG_PRESS_MS = 600  # a press held this long on a touch screen is a LONG_PRESS
GESTURE_MS = (50, 10_000)  # the shortest and longest swipe or long press the player sends (milliseconds)

#: Browser key names (`KeyboardEvent.key`) of keys that type nothing → the device's key names.
NAMED_KEYS = {"Enter": "enter", "Tab": "tab", "Backspace": "backspace", "Delete": "delete", "Escape": "esc",
              "ArrowUp": "up", "ArrowDown": "down", "ArrowLeft": "left", "ArrowRight": "right", "Home": "home",
              "End": "end", "PageUp": "pageup", "PageDown": "pagedown", "Insert": "insert", "ContextMenu": "menu",
              **{f"F{n}": f"f{n}" for n in range(1, 25)}}
#: Keys that send nothing by themselves: modifiers, locks, dead keys (their character comes as text), IME keys.
SILENT_KEYS = frozenset({"Control", "Shift", "Alt", "Meta", "AltGraph", "OS", "Super", "Hyper", "Fn", "FnLock",
                         "CapsLock", "NumLock", "ScrollLock", "Dead", "Process", "Unidentified", "Compose"})
MODIFIER_ORDER = (("ctrl", "ctrl"), ("alt", "alt"), ("shift", "shift"), ("meta", "super"))
BUTTONS = ("left", "middle", "right")


class InputRefused(ValueError):
    """What the page sent is not an input the player takes (answered 400 with the reason)."""


@dataclass(frozen=True)
class Input:
    """One input of a person, made into an action for `platform`. `at`: when it was complete (monotonic seconds);
    `raw`: what the page sent (its last event, for the trajectory); `merges`: "text", "scroll" or "click" while
    later events may still extend it, for `idle` seconds after `at`."""

    platform: str
    action: Action
    at: float
    raw: dict[str, Any] = field(default_factory=dict)
    merges: str | None = None
    idle: float = 0.0
    events: int = 1
    wheel: tuple[float, float] = (0.0, 0.0)  # a SCROLL's turns so far, in notches (fractions kept)

    def open_until(self) -> float:
        return self.at + self.idle


def to_device(x: float, y: float, shown_w: float, shown_h: float, width: int, height: int) -> tuple[int, int]:
    """The device pixel under the displayed point (x, y) of a screen displayed shown_w × shown_h, whose device
    screen is width × height: scaled, floored and clamped to the screen."""
    for name, v in (("x", x), ("y", y), ("shown_w", shown_w), ("shown_h", shown_h)):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise InputRefused(f"{name} must be a finite number, not {v!r}")
    if shown_w <= 0 or shown_h <= 0:
        raise InputRefused(f"the displayed screen has no size ({shown_w}x{shown_h})")
    if width <= 0 or height <= 0:
        raise InputRefused(f"the device's screen has no size ({width}x{height})")
    dx = math.floor(x * width / shown_w)
    dy = math.floor(y * height / shown_h)
    return min(max(dx, 0), width - 1), min(max(dy, 0), height - 1)


def _physical(key: str, code: str) -> str:
    """The key under modifiers by its physical place where it is a letter or a digit (`KeyS` → `s`), else the
    character the layout gave, lower case."""
    m = re.fullmatch(r"Key([A-Z])|Digit([0-9])", code or "")
    if m:
        return (m.group(1) or m.group(2)).lower()
    return key.lower()


def key_action(event: dict[str, Any]) -> Hotkey | None:
    """The HOTKEY a key press makes (see the module's docstring), or None when it types text or sends nothing."""
    key = event.get("key")
    if not isinstance(key, str) or not key:
        raise InputRefused("a key event needs `key` (KeyboardEvent.key)")
    if key in SILENT_KEYS or event.get("altgraph"):  # AltGr's characters come as text
        return None
    held = [name for flag, name in MODIFIER_ORDER if event.get(flag)]
    if key in NAMED_KEYS:
        return Hotkey(keys=[*held, NAMED_KEYS[key]])
    if len(key) == 1 or (len(key) == 2 and key.isprintable()):  # one character (a surrogate pair counts as one)
        if key == " " and held:
            return Hotkey(keys=[*held, "space"])
        chord = [k for k in held if k != "shift"]
        if not chord:  # plain or shifted: a character, typed as text
            return None
        return Hotkey(keys=[*held, _physical(key, str(event.get("code") or ""))])
    raise InputRefused(f"unknown key {key!r}")


def _number(event: dict[str, Any], name: str, default: float | None = None) -> float:
    v = event.get(name, default)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise InputRefused(f"`{name}` must be a finite number, not {v!r}")
    return float(v)


def _point(event: dict[str, Any], size: tuple[int, int], prefix: str = "") -> tuple[int, int]:
    return to_device(_number(event, prefix + "x"), _number(event, prefix + "y"), _number(event, "w"),
                     _number(event, "h"), *size)


def _notches(amount: float, mode: int) -> float:
    if mode == 1:
        return amount / LINES_PER_NOTCH
    if mode == 2:
        return amount * PAGE_NOTCHES
    return amount / PIXELS_PER_NOTCH


def _whole(notches: float) -> int:
    """Whole notches of a wheel turn: rounded, at least one where it turned at all, within ±MAX_SCROLL."""
    n = round(notches)
    if n == 0 and notches != 0:
        n = 1 if notches > 0 else -1
    return max(-MAX_SCROLL, min(MAX_SCROLL, n))


def translate(event: dict[str, Any], size: tuple[int, int] | None, now: float) -> Input | None:
    """The input one event of the page makes for its platform, whose screen is `size` (W, H); None for a key that
    sends nothing. Raises InputRefused with the reason for anything else the player does not take."""
    platform = event.get("platform")
    if not isinstance(platform, str) or not platform:
        raise InputRefused("the event names no platform")
    kind = event.get("kind")
    raw = {k: v for k, v in event.items() if k not in ("seq", "platform")}
    if kind in ("done", "fail"):
        return Input(platform, Done() if kind == "done" else Fail(), now, raw)
    if kind == "key":
        action = key_action(event)
        return None if action is None else Input(platform, action, now, raw)
    if kind == "keys":  # a combination written out, for keys the browser keeps for itself (Ctrl+W, Ctrl+T)
        combo = event.get("combo")
        names = [k.strip() for k in combo.split("+")] if isinstance(combo, str) else []
        if not names or not all(names):
            raise InputRefused(f"`combo` must name keys joined by +, e.g. ctrl+w, not {combo!r}")
        return Input(platform, _checked({"type": "HOTKEY", "keys": [n.lower() for n in names]}), now, raw)
    if kind == "text":
        text = event.get("text")
        if not isinstance(text, str):
            raise InputRefused("a text event needs `text`")
        text = text.replace("\r\n", "\n").replace("\r", "\n")
        if not text:
            return None
        return Input(platform, _checked({"type": "TYPING", "text": text}), now, raw, "text", TEXT_IDLE)
    touch = is_touch(platform)
    if kind == "button":
        if not touch:
            raise InputRefused(f"{platform} has no system buttons (only a touch screen's device has)")
        return Input(platform, _checked({"type": "SYSTEM_BUTTON", "button": event.get("button")}), now, raw)
    if size is None:
        raise InputRefused(f"no screen of {platform} has been shown yet")
    if kind == "hover":
        return None if touch else Input(platform, MoveTo(**dict(zip("xy", _point(event, size)))), now, raw)
    if kind == "click":
        button = event.get("button", "left")
        if button not in BUTTONS:
            raise InputRefused(f"`button` must be one of {', '.join(BUTTONS)}, not {button!r}")
        x, y = _point(event, size)
        held = _number(event, "held_ms", 0)
        if touch and button == "left" and held >= LONG_PRESS_MS:
            return Input(platform, LongPress(x=x, y=y, duration=_gesture(held)), now, raw)
        if button == "right":
            return Input(platform, RightClick(x=x, y=y), now, raw)
        return Input(platform, Click(x=x, y=y, button=button), now, raw, "click", CLICK_IDLE)
    if kind == "drag":
        x0, y0 = _point(event, size, "start_")
        x, y = _point(event, size)
        if touch:
            return Input(platform, Swipe(x=x0, y=y0, dx=x - x0, dy=y - y0,
                                         duration=_gesture(_number(event, "held_ms", 300))), now, raw)
        return Input(platform, DragTo(start_x=x0, start_y=y0, x=x, y=y), now, raw)
    if kind == "scroll":
        x, y = _point(event, size)
        mode = int(_number(event, "mode", 0))
        wheel = (_notches(_number(event, "dx", 0), mode), _notches(_number(event, "dy", 0), mode))
        if wheel == (0.0, 0.0):
            return None
        return Input(platform, Scroll(dx=_whole(wheel[0]), dy=_whole(wheel[1]), x=x, y=y), now, raw, "scroll",
                     SCROLL_IDLE, wheel=wheel)
    raise InputRefused(f"unknown input kind {kind!r}")


def is_touch(platform: str) -> bool:
    """Whether `platform`'s screen is a touch screen (`PlatformSpec.touch`)."""
    facts = PLATFORMS.get(platform)
    return facts is not None and facts.touch


def _gesture(ms: float) -> int:
    return int(max(GESTURE_MS[0], min(GESTURE_MS[1], round(ms))))


def _checked(fields: dict[str, Any]) -> Action:
    try:
        return parse_action(fields)
    except ValidationError as exc:
        first = exc.errors()[0]
        raise InputRefused(f"not a valid {fields['type']} ({'.'.join(map(str, first['loc'][1:]))}: "
                           f"{first['msg']})") from None


def _near(a: Action, b: Action) -> bool:
    return abs((a.x or 0) - (b.x or 0)) <= NEAR and abs((a.y or 0) - (b.y or 0)) <= NEAR


def merge(pending: Input, new: Input) -> Input | None:
    """`pending` extended by `new` when they make one action (text typed in a row; wheel turns in one place; the
    browser's second and third click in one place), else None. `new` must come while `pending` is open."""
    if pending.merges is None or pending.merges != new.merges or pending.platform != new.platform \
            or new.at > pending.open_until():
        return None
    a, b = pending.action, new.action
    if pending.merges == "text":
        text = a.text + b.text
        if len(text) > MAX_TEXT:
            return None
        return replace(pending, action=Typing(text=text), at=new.at, raw=new.raw, events=pending.events + 1)
    if pending.merges == "scroll":
        if not _near(a, b):
            return None
        wheel = (pending.wheel[0] + new.wheel[0], pending.wheel[1] + new.wheel[1])
        return replace(pending, action=Scroll(dx=_whole(wheel[0]), dy=_whole(wheel[1]), x=a.x, y=a.y), at=new.at,
                       raw=new.raw, events=pending.events + 1, wheel=wheel)
    # clicks: the browser counts a double click in `detail`; a click that is not its next count is a new click
    if a.button != b.button or not _near(a, b) or a.clicks >= 3 or new.raw.get("detail") != a.clicks + 1:
        return None
    return replace(pending, action=Click(x=a.x, y=a.y, button=a.button, clicks=a.clicks + 1), at=new.at,
                   raw=new.raw, events=pending.events + 1)


def describe(action: Action) -> str:
    """An action in a few words, for the page and the trajectory's reasoning."""
    data = action.model_dump(exclude_none=True, exclude_defaults=True)
    data.pop("type", None)
    args = ", ".join(f"{k}={v!r}" for k, v in data.items())
    return f"{action.type}({args})"
