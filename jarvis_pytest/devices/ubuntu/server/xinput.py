"""Input through the XTest extension on one X connection: mouse, keys and exact Unicode typing.

Characters that the keyboard map lacks (non-ASCII text) are typed by binding their keysym to a spare keycode
first (kept bound; the least recently used is rebound, never sooner than `REBIND_AFTER_S` after its last use), so
any text types exactly, `<>{}` included, without spawning a process per action.
"""

from __future__ import annotations

import os
import threading
import time
from collections import OrderedDict

from Xlib import X, XK, display
from Xlib.ext import xtest

BUTTONS = {"left": 1, "middle": 2, "right": 3}
REBIND_AFTER_S = 0.3  # a spare keycode is bound to another symbol no sooner than this after its last use
SPARE_ENV = "JARVIS_SPARE_KEYCODES"  # the server's spare keycodes, handed to the child that runs a PYAUTOGUI script
KEY_ALIASES = {
    "ctrl": "Control_L", "control": "Control_L", "alt": "Alt_L", "shift": "Shift_L", "super": "Super_L",
    "win": "Super_L", "meta": "Super_L", "cmd": "Super_L", "enter": "Return", "return": "Return",
    "esc": "Escape", "escape": "Escape", "tab": "Tab", "backspace": "BackSpace", "delete": "Delete",
    "del": "Delete", "space": "space", "up": "Up", "down": "Down", "left": "Left", "right": "Right",
    "pageup": "Prior", "pgup": "Prior", "pagedown": "Next", "pgdn": "Next", "home": "Home", "end": "End",
    "insert": "Insert", "capslock": "Caps_Lock", "printscreen": "Print", "menu": "Menu",
}


class InputError(ValueError):
    """An action the device cannot carry out as asked (bad key name, point off screen)."""


def char_keysym(ch: str) -> int:
    code = ord(ch)
    if ch == "\n":
        return XK.string_to_keysym("Return")
    if ch == "\t":
        return XK.string_to_keysym("Tab")
    if 0x20 <= code <= 0x7E or 0xA0 <= code <= 0xFF:
        return code
    return 0x01000000 + code


class Keyboard:
    """XTest input on display `:0` (thread-safe)."""

    def __init__(self, name: str | None = None):
        self.d = display.Display(name)
        self.root = self.d.screen().root
        self.lock = threading.Lock()
        geom = self.root.get_geometry()
        self.width, self.height = geom.width, geom.height
        first, last = self.d.display.info.min_keycode, self.d.display.info.max_keycode
        mapping = self.d.get_keyboard_mapping(first, last - first + 1)
        # Keycodes without symbols, bound on demand to keysyms the layout lacks; least recently used rebound first.
        self.spare: OrderedDict[int, tuple[int, float]] = OrderedDict(  # keycode → (bound keysym, last used)
            (first + i, (0, 0.0)) for i, syms in enumerate(mapping) if not any(syms))
        shared = os.environ.get(SPARE_ENV)
        if shared:  # a script's child: the server's spare keycodes, bound as they are now and just used
            now = time.monotonic()
            codes = [int(c) for c in shared.split(",") if c.strip().isdigit() and first <= int(c) <= last]
            self.spare = OrderedDict((c, (mapping[c - first][0], now if mapping[c - first][0] else 0.0))
                                     for c in codes)

    def refresh_spare(self) -> None:
        """Take the spare keycodes' symbols from the server again (a script's child may have bound them anew)."""
        if not self.spare:
            return
        with self.lock:
            first = min(self.spare)
            mapping = self.d.get_keyboard_mapping(first, max(self.spare) - first + 1)
            now = time.monotonic()
            for code, (bound, last_used) in list(self.spare.items()):
                actual = mapping[code - first][0]
                if actual != bound:
                    self.spare[code] = (actual, now)

    # -- primitives -----------------------------------------------------------------------------------------
    def _check_point(self, x: int, y: int) -> None:
        if not (0 <= x < self.width and 0 <= y < self.height):
            raise InputError(f"point ({x}, {y}) is off the {self.width}x{self.height} screen")

    def _move(self, x: int, y: int) -> None:
        self._check_point(x, y)
        xtest.fake_input(self.d, X.MotionNotify, x=x, y=y)

    def _button(self, button: int, down: bool) -> None:
        xtest.fake_input(self.d, X.ButtonPress if down else X.ButtonRelease, button)

    def _key(self, keycode: int, down: bool) -> None:
        xtest.fake_input(self.d, X.KeyPress if down else X.KeyRelease, keycode)

    def keysym_of(self, name: str) -> int:
        if len(name) == 1:
            return char_keysym(name.lower() if name.isalpha() else name)
        key = KEY_ALIASES.get(name.lower(), name)
        sym = XK.string_to_keysym(key)
        if not sym and key[:1].lower() == "f" and key[1:].isdigit():
            sym = XK.string_to_keysym(f"F{key[1:]}")
        if not sym:
            raise InputError(f"unknown key name {name!r} (use names such as ctrl, alt, shift, enter, tab, esc, a, F5)")
        return sym

    def _keycode_for(self, sym: int) -> tuple[int, bool]:
        """A keycode producing `sym`, and whether Shift is needed; binds a spare keycode when none does."""
        for keycode, index in self.d.keysym_to_keycodes(sym):
            if index in (0, 1) and keycode not in self.spare:
                return keycode, index == 1
        for keycode, (bound, _) in self.spare.items():
            if bound == sym:
                break
        else:
            if not self.spare:
                raise InputError(f"cannot type keysym {sym:#x}: the keyboard map has no spare keycode")
            keycode, (bound, last_used) = next(iter(self.spare.items()))
            if bound:
                # Clients translate a key event with the map they fetch when they handle the MappingNotify before
                # it: a client still behind on this keycode's last use would read the new symbol for it.
                time.sleep(max(0.0, last_used + REBIND_AFTER_S - time.monotonic()))
            self.d.change_keyboard_mapping(keycode, [(sym, sym)])
            self.d.sync()
        self.spare[keycode] = (sym, time.monotonic())
        self.spare.move_to_end(keycode)
        return keycode, False

    def _tap_sym(self, sym: int) -> None:
        keycode, shifted = self._keycode_for(sym)
        shift = self.d.keysym_to_keycode(XK.string_to_keysym("Shift_L"))
        if shifted:
            self._key(shift, True)
        self._key(keycode, True)
        self._key(keycode, False)
        if shifted:
            self._key(shift, False)
        self.d.sync()

    # -- actions ----------------------------------------------------------------------------------------------
    def move(self, x: int, y: int) -> None:
        with self.lock:
            self._move(x, y)
            self.d.sync()

    def click(self, x: int | None, y: int | None, button: str = "left", clicks: int = 1) -> None:
        with self.lock:
            if x is not None and y is not None:
                self._move(x, y)
            for _ in range(clicks):
                self._button(BUTTONS[button], True)
                self._button(BUTTONS[button], False)
            self.d.sync()

    def button(self, button: str, down: bool) -> None:
        with self.lock:
            self._button(BUTTONS[button], down)
            self.d.sync()

    def drag(self, x0: int | None, y0: int | None, x1: int, y1: int, duration_ms: int = 200,
             hold_ms: int = 0) -> None:
        with self.lock:
            if x0 is None or y0 is None:
                p = self.root.query_pointer()
                x0, y0 = p.root_x, p.root_y
            self._check_point(x1, y1)
            self._move(x0, y0)
            self._button(1, True)
            self.d.sync()
            if hold_ms:
                time.sleep(hold_ms / 1000)
            steps = max(2, duration_ms // 20)
            for i in range(1, steps + 1):
                self._move(round(x0 + (x1 - x0) * i / steps), round(y0 + (y1 - y0) * i / steps))
                self.d.sync()
                time.sleep(duration_ms / 1000 / steps)
            self._button(1, False)
            self.d.sync()

    def long_press(self, x: int, y: int, duration_ms: int) -> None:
        with self.lock:
            self._move(x, y)
            self._button(1, True)
            self.d.sync()
            time.sleep(duration_ms / 1000)
            self._button(1, False)
            self.d.sync()

    def scroll(self, dx: int, dy: int, x: int | None, y: int | None) -> None:
        with self.lock:
            if x is not None and y is not None:
                self._move(x, y)
            for button, count in ((5 if dy > 0 else 4, abs(dy)), (7 if dx > 0 else 6, abs(dx))):
                for _ in range(count):
                    self._button(button, True)
                    self._button(button, False)
            self.d.sync()

    def key(self, name: str, down: bool) -> None:
        with self.lock:
            keycode, _ = self._keycode_for(self.keysym_of(name))
            self._key(keycode, down)
            self.d.sync()

    def hotkey(self, names: list[str]) -> None:
        with self.lock:
            codes = [self._keycode_for(self.keysym_of(n))[0] for n in names]
            for code in codes:
                self._key(code, True)
            for code in reversed(codes):
                self._key(code, False)
            self.d.sync()

    def type(self, text: str) -> None:
        with self.lock:
            for ch in text:
                if ch == "\r":
                    continue
                self._tap_sym(char_keysym(ch))
