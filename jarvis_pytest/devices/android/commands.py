"""The unified action space → the device shell commands that perform it (`input`, `am broadcast`, `ime`).

Pure functions of an action and an `InputState` (screen size, SDK level, IME, pointer): no device here, so every
mapping is testable as text and the escaping against a real POSIX shell. `AdbDevice.act` runs the lines joined by
`&&` in one `adb shell`.

Typing: ASCII goes through `input text`, whose argument AOSP's `InputShellCommand.sendText` (formerly
`cmds/input/.../Input.java`) rewrites by turning every `%s` into a space; so spaces are sent as `%s`, a literal
`%s` in the text is split between two `input text` calls (`...%` then `s...`), and the whole argument is one
single-quoted shell word (`'` as `'\\''`), which keeps `()<>|;&*\\~"$` and backticks literal for mksh.
`\\n` and `\\t` are `KEYCODE_ENTER`/`KEYCODE_TAB`. Text with any other character (non-ASCII, emoji) goes through
the ADBKeyBoard IME as base64 (`am broadcast -a ADB_INPUT_B64 --es msg <base64>`), which commits it unchanged;
`input text` cannot type it (its virtual key map has no such keys).
"""

from __future__ import annotations

import base64
import shlex
from dataclasses import dataclass, field

from jarvis_pytest.devices import actions as A

IME_PACKAGE = "com.android.adbkeyboard"
IME_ID = f"{IME_PACKAGE}/.AdbIME"
KEYCOMBINATION_SDK = 31   # `input keycombination` (Android 12+)
DRAGANDDROP_SDK = 29      # `input draganddrop` and `input motionevent` (in AOSP's Input.java of Android 10)
B64_CHUNK_BYTES = 3000    # UTF-8 bytes per broadcast (4000 base64 characters: far below the shell's limits)
SCROLL_STEP = 0.1         # screen heights per scroll notch
LONG_PRESS_MS = 800

SYSTEM_BUTTONS = {
    "home": "KEYCODE_HOME", "back": "KEYCODE_BACK", "menu": "KEYCODE_MENU", "enter": "KEYCODE_ENTER",
    "volume_up": "KEYCODE_VOLUME_UP", "volume_down": "KEYCODE_VOLUME_DOWN", "power": "KEYCODE_POWER",
    "recents": "KEYCODE_APP_SWITCH", "app_switch": "KEYCODE_APP_SWITCH",
}
# key names agents use (pyautogui/xdotool style) → KEYCODE_* names (android.view.KeyEvent)
_NAMED = {
    "enter": "ENTER", "return": "ENTER", "backspace": "DEL", "delete": "FORWARD_DEL", "del": "FORWARD_DEL",
    "tab": "TAB", "esc": "ESCAPE", "escape": "ESCAPE", "space": "SPACE", "up": "DPAD_UP", "down": "DPAD_DOWN",
    "left": "DPAD_LEFT", "right": "DPAD_RIGHT", "home": "MOVE_HOME", "end": "MOVE_END", "pageup": "PAGE_UP",
    "pagedown": "PAGE_DOWN", "pgup": "PAGE_UP", "pgdn": "PAGE_DOWN", "insert": "INSERT", "capslock": "CAPS_LOCK",
    "ctrl": "CTRL_LEFT", "control": "CTRL_LEFT", "ctrlleft": "CTRL_LEFT", "ctrlright": "CTRL_RIGHT",
    "shift": "SHIFT_LEFT", "shiftleft": "SHIFT_LEFT", "shiftright": "SHIFT_RIGHT", "alt": "ALT_LEFT",
    "altleft": "ALT_LEFT", "altright": "ALT_RIGHT", "win": "META_LEFT", "super": "META_LEFT", "meta": "META_LEFT",
    "cmd": "META_LEFT", "command": "META_LEFT", "back": "BACK", "menu": "MENU", "search": "SEARCH",
    "volumeup": "VOLUME_UP", "volumedown": "VOLUME_DOWN", "volumemute": "VOLUME_MUTE", "power": "POWER",
    "recents": "APP_SWITCH", "app_switch": "APP_SWITCH", "printscreen": "SYSRQ", "prtsc": "SYSRQ",
    ",": "COMMA", ".": "PERIOD", "/": "SLASH", ";": "SEMICOLON", "'": "APOSTROPHE", "[": "LEFT_BRACKET",
    "]": "RIGHT_BRACKET", "\\": "BACKSLASH", "-": "MINUS", "=": "EQUALS", "`": "GRAVE", "+": "PLUS", "@": "AT",
    "*": "STAR", "#": "POUND", " ": "SPACE", "\n": "ENTER", "\t": "TAB",
}
# numeric codes (android.view.KeyEvent) of the keys ADBKeyBoard's `mcode` extra may carry
_CODES = {**{f"KEYCODE_{chr(c)}": 29 + c - ord("A") for c in range(ord("A"), ord("Z") + 1)},
          **{f"KEYCODE_{d}": 7 + d for d in range(10)},
          **{f"KEYCODE_F{n}": 130 + n for n in range(1, 13)},
          "KEYCODE_ENTER": 66, "KEYCODE_DEL": 67, "KEYCODE_FORWARD_DEL": 112, "KEYCODE_TAB": 61,
          "KEYCODE_SPACE": 62, "KEYCODE_ESCAPE": 111, "KEYCODE_DPAD_UP": 19, "KEYCODE_DPAD_DOWN": 20,
          "KEYCODE_DPAD_LEFT": 21, "KEYCODE_DPAD_RIGHT": 22, "KEYCODE_MOVE_HOME": 122, "KEYCODE_MOVE_END": 123,
          "KEYCODE_PAGE_UP": 92, "KEYCODE_PAGE_DOWN": 93, "KEYCODE_COMMA": 55, "KEYCODE_PERIOD": 56,
          "KEYCODE_SLASH": 76, "KEYCODE_MINUS": 69, "KEYCODE_EQUALS": 70}
# modifier keycode → its meta state bits (android.view.KeyEvent META_*_ON | META_*_LEFT_ON)
META = {"KEYCODE_CTRL_LEFT": 0x1000 | 0x2000, "KEYCODE_CTRL_RIGHT": 0x1000 | 0x4000,
        "KEYCODE_SHIFT_LEFT": 0x1 | 0x40, "KEYCODE_SHIFT_RIGHT": 0x1 | 0x80,
        "KEYCODE_ALT_LEFT": 0x2 | 0x10, "KEYCODE_ALT_RIGHT": 0x2 | 0x20,
        "KEYCODE_META_LEFT": 0x10000 | 0x20000, "KEYCODE_META_RIGHT": 0x10000 | 0x40000}


class Unsupported(Exception):
    """The action cannot be performed on this device; the message says why (fed back to the agent)."""


@dataclass
class InputState:
    """What the mapping needs to know about the device, and the pointer/keys it tracks between actions."""

    width: int
    height: int
    sdk: int = 33
    ime_installed: bool = False
    ime_active: bool = False
    x: int | None = None
    y: int | None = None
    pressed: bool = False
    held: list[str] = field(default_factory=list)   # modifier keycodes held by KEY_DOWN


def keycode(key: str) -> str:
    """`KEYCODE_*` name of a key name (`a`, `ctrl`, `enter`, `f5`, `KEYCODE_HOME`, or a number)."""
    k = key.strip() if key.strip() else key
    if k.upper().startswith("KEYCODE_"):
        return k.upper()
    if k.isdigit() and len(k) > 1:
        return k                                    # a raw numeric keycode
    low = k.lower()
    if low in _NAMED:
        return f"KEYCODE_{_NAMED[low]}"
    if len(k) == 1 and (k.isascii() and k.isalnum()):
        return f"KEYCODE_{k.upper()}"
    if len(low) in (2, 3) and low[0] == "f" and low[1:].isdigit() and 1 <= int(low[1:]) <= 12:
        return f"KEYCODE_F{int(low[1:])}"
    raise Unsupported(f"unknown key {key!r} (use a key name such as enter, ctrl, a, f5, or KEYCODE_*)")


def is_modifier(code: str) -> bool:
    return code in META


# -- typing ------------------------------------------------------------------------------------------------------
def typable_by_input_text(text: str) -> bool:
    """Whether `input text` (plus ENTER/TAB key events) can type `text`: printable ASCII, newline, tab."""
    return all(c in "\n\t" or " " <= c <= "~" for c in text)


def input_text_segments(text: str) -> list[str]:
    """Pieces of one line of text that each contain no literal `%s` (which `input text` would turn into a
    space): `100%sure` → [`100%`, `sure`]."""
    pieces = text.split("%s")
    segs = []
    for i, p in enumerate(pieces):
        seg = ("s" if i else "") + p + ("%" if i < len(pieces) - 1 else "")
        if seg:
            segs.append(seg)
    return segs


def input_text_argument(segment: str) -> str:
    """The argument `input text` needs to type `segment` exactly (spaces as `%s`)."""
    if "%s" in segment:
        raise ValueError("a segment must not contain a literal %s (split it with input_text_segments)")
    return segment.replace(" ", "%s")


def input_text_commands(text: str) -> list[str]:
    """`input text '...'` / `input keyevent` lines typing printable-ASCII `text` exactly."""
    cmds: list[str] = []
    line = ""

    def flush() -> None:
        nonlocal line
        for seg in input_text_segments(line):
            cmds.append(f"input text {shlex.quote(input_text_argument(seg))}")
        line = ""

    for c in text:
        if c in "\n\t":
            flush()
            cmds.append(f"input keyevent {'KEYCODE_ENTER' if c == chr(10) else 'KEYCODE_TAB'}")
        else:
            line += c
    flush()
    return cmds


def ime_text_commands(text: str) -> list[str]:
    """ADBKeyBoard broadcasts committing `text` (any Unicode) as base64, in chunks split on characters."""
    cmds, chunk, size = [], "", 0
    for c in text:
        n = len(c.encode("utf-8"))
        if size + n > B64_CHUNK_BYTES and chunk:
            cmds.append(_b64_broadcast(chunk))
            chunk, size = "", 0
        chunk += c
        size += n
    if chunk:
        cmds.append(_b64_broadcast(chunk))
    return cmds


def _b64_broadcast(text: str) -> str:
    b64 = base64.b64encode(text.encode("utf-8")).decode("ascii")
    return f"am broadcast -a ADB_INPUT_B64 -p {IME_PACKAGE} --es msg {shlex.quote(b64)}"


def ime_activation_commands() -> list[str]:
    return [f"ime enable {IME_ID} >/dev/null", f"ime set {IME_ID} >/dev/null", "sleep 0.3"]


def typing_commands(text: str, state: InputState) -> list[str]:
    if not text:
        return []
    if typable_by_input_text(text):
        return input_text_commands(text)
    if not state.ime_installed:
        raise Unsupported("typing non-ASCII text needs the ADBKeyBoard IME (com.android.adbkeyboard), which is "
                          "not installed on this device; `input text` can type only ASCII "
                          "(see fixtures/images/android/README.md)")
    pre = [] if state.ime_active else ime_activation_commands()
    state.ime_active = True
    return pre + ime_text_commands(text)


# -- keys --------------------------------------------------------------------------------------------------------
def hotkey_commands(keys: list[str], state: InputState) -> list[str]:
    codes = [keycode(k) for k in keys]
    if len(codes) == 1:
        return [f"input keyevent {codes[0]}"]
    if state.sdk >= KEYCOMBINATION_SDK:
        return ["input keycombination " + " ".join(codes)]
    mods, last = codes[:-1], codes[-1]
    if all(is_modifier(m) for m in mods) and state.ime_installed and last in _CODES:
        meta = 0
        for m in mods:
            meta |= META[m]
        pre = [] if state.ime_active else ime_activation_commands()
        state.ime_active = True
        mcode = shlex.quote(f"{meta},{_CODES[last]}")
        return pre + [f"am broadcast -a ADB_INPUT_TEXT -p {IME_PACKAGE} --es mcode {mcode}"]
    if not any(is_modifier(c) for c in codes):
        return ["input keyevent " + " ".join(codes)]  # a key sequence without modifiers
    raise Unsupported(f"the key combination {'+'.join(keys)} needs Android 12 (`input keycombination`) or the "
                      f"ADBKeyBoard IME; this device runs SDK {state.sdk}")


def _xy(state: InputState, x: int | None, y: int | None) -> tuple[int, int]:
    if x is None or y is None:
        if state.x is None or state.y is None:
            raise Unsupported("no position: give x and y (there is no pointer on a touch screen until one is used)")
        x, y = state.x if x is None else x, state.y if y is None else y
    if not (0 <= x < state.width and 0 <= y < state.height):
        raise Unsupported(f"({x}, {y}) is outside the {state.width}x{state.height} screen")
    state.x, state.y = x, y
    return x, y


def _clamp(v: int, hi: int) -> int:
    return max(1, min(hi - 2, v))


# -- the mapping -------------------------------------------------------------------------------------------------
def commands_for(action: A.Action, state: InputState) -> list[str]:
    """The shell command lines performing `action` (empty: nothing to run); raises Unsupported."""
    t = action.type
    if t == "CLICK":
        x, y = _xy(state, action.x, action.y)
        if action.button == "right":
            return [f"input swipe {x} {y} {x} {y} {LONG_PRESS_MS}"]
        return [f"input tap {x} {y}"] * action.clicks
    if t == "DOUBLE_CLICK":
        x, y = _xy(state, action.x, action.y)
        return [f"input tap {x} {y}"] * 2
    if t == "RIGHT_CLICK":  # the touch-screen context menu: a long press
        x, y = _xy(state, action.x, action.y)
        return [f"input swipe {x} {y} {x} {y} {LONG_PRESS_MS}"]
    if t == "MOVE_TO":
        x, y = _xy(state, action.x, action.y)
        return [f"input motionevent MOVE {x} {y}"] if state.pressed else []
    if t in ("MOUSE_DOWN", "MOUSE_UP"):
        if state.sdk < DRAGANDDROP_SDK:
            raise Unsupported(f"{t} needs `input motionevent` (Android 10+); this device runs SDK {state.sdk}")
        x, y = _xy(state, None, None)
        state.pressed = t == "MOUSE_DOWN"
        return [f"input motionevent {'DOWN' if state.pressed else 'UP'} {x} {y}"]
    if t == "LONG_PRESS":
        x, y = _xy(state, action.x, action.y)
        return [f"input swipe {x} {y} {x} {y} {action.duration}"]
    if t == "SWIPE":
        x, y = _xy(state, action.x, action.y)
        x2, y2 = _clamp(x + action.dx, state.width), _clamp(y + action.dy, state.height)
        state.x, state.y = x2, y2
        return [f"input swipe {x} {y} {x2} {y2} {action.duration}"]
    if t == "DRAG_TO":
        x1, y1 = _xy(state, action.start_x, action.start_y)
        x2, y2 = _xy(state, action.x, action.y)
        if state.sdk >= DRAGANDDROP_SDK:
            return [f"input draganddrop {x1} {y1} {x2} {y2} 1000"]
        return [f"input swipe {x1} {y1} {x2} {y2} 1500"]
    if t == "SCROLL":
        cx = action.x if action.x is not None else (state.x if state.x is not None else state.width // 2)
        cy = action.y if action.y is not None else (state.y if state.y is not None else state.height // 2)
        cx, cy = _xy(state, cx, cy)
        cmds = []
        if action.dy:  # wheel down (dy > 0) shows what is below: the finger moves up
            dist = int(abs(action.dy) * SCROLL_STEP * state.height) * (1 if action.dy > 0 else -1)
            cmds.append(f"input swipe {cx} {_clamp(cy + dist // 2, state.height)} {cx} "
                        f"{_clamp(cy - dist // 2, state.height)} 400")
        if action.dx:
            dist = int(abs(action.dx) * SCROLL_STEP * state.width) * (1 if action.dx > 0 else -1)
            cmds.append(f"input swipe {_clamp(cx + dist // 2, state.width)} {cy} "
                        f"{_clamp(cx - dist // 2, state.width)} {cy} 400")
        return cmds
    if t == "TYPING":
        return typing_commands(action.text, state)
    if t == "HOTKEY":
        codes = [keycode(k) for k in action.keys]
        return hotkey_commands([*state.held, *codes] if state.held else action.keys, state)
    if t == "KEY_DOWN":
        code = keycode(action.key)
        if is_modifier(code):
            if code not in state.held:
                state.held.append(code)
            return []
        return hotkey_commands([*state.held, code], state) if state.held else [f"input keyevent {code}"]
    if t == "KEY_UP":
        code = keycode(action.key)
        if code in state.held:
            state.held.remove(code)
        return []  # the key was pressed and released at KEY_DOWN (`input` cannot hold a key)
    if t == "SYSTEM_BUTTON":
        return [f"input keyevent {SYSTEM_BUTTONS[action.button]}"]
    if t in ("WAIT", "DONE", "FAIL"):
        return []
    if t == "PYAUTOGUI":
        raise Unsupported("PYAUTOGUI scripts run on desktop devices only; use the unified actions on Android")
    raise Unsupported(f"action {t} is not supported on Android")
