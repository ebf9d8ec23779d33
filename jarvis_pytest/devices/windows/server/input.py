"""Mouse and keyboard input through SendInput, from one lock: exact Unicode typing (KEYEVENTF_UNICODE, surrogate
pairs included), key names like the Ubuntu server's, wheel notches, drags with intermediate moves."""

from __future__ import annotations

import ctypes
import threading
import time

from . import win32 as w
from .screen import virtual_screen

BUTTON_FLAGS = {"left": (w.MOUSEEVENTF_LEFTDOWN, w.MOUSEEVENTF_LEFTUP),
                "middle": (w.MOUSEEVENTF_MIDDLEDOWN, w.MOUSEEVENTF_MIDDLEUP),
                "right": (w.MOUSEEVENTF_RIGHTDOWN, w.MOUSEEVENTF_RIGHTUP)}

# Key names (case-insensitive) → virtual-key codes; pyautogui's names and the X keysym names agents use too.
VK = {
    "ctrl": 0x11, "control": 0x11, "ctrlleft": 0xA2, "ctrlright": 0xA3, "lctrl": 0xA2, "rctrl": 0xA3,
    "control_l": 0xA2, "control_r": 0xA3,
    "alt": 0x12, "altleft": 0xA4, "altright": 0xA5, "lalt": 0xA4, "ralt": 0xA5, "alt_l": 0xA4, "alt_r": 0xA5,
    "option": 0x12, "altgr": 0xA5,
    "shift": 0x10, "shiftleft": 0xA0, "shiftright": 0xA1, "lshift": 0xA0, "rshift": 0xA1, "shift_l": 0xA0,
    "shift_r": 0xA1,
    "win": 0x5B, "super": 0x5B, "meta": 0x5B, "cmd": 0x5B, "command": 0x5B, "winleft": 0x5B, "winright": 0x5C,
    "super_l": 0x5B, "super_r": 0x5C, "windows": 0x5B, "start": 0x5B,
    "enter": 0x0D, "return": 0x0D, "kp_enter": 0x0D, "tab": 0x09, "esc": 0x1B, "escape": 0x1B,
    "backspace": 0x08, "back": 0x08, "delete": 0x2E, "del": 0x2E, "insert": 0x2D, "ins": 0x2D,
    "home": 0x24, "end": 0x23, "pageup": 0x21, "pgup": 0x21, "prior": 0x21, "page_up": 0x21,
    "pagedown": 0x22, "pgdn": 0x22, "next": 0x22, "page_down": 0x22,
    "up": 0x26, "down": 0x28, "left": 0x25, "right": 0x27,
    "space": 0x20, "spacebar": 0x20, "capslock": 0x14, "caps_lock": 0x14, "numlock": 0x90, "num_lock": 0x90,
    "scrolllock": 0x91, "pause": 0x13, "printscreen": 0x2C, "prtsc": 0x2C, "print": 0x2C, "prntscrn": 0x2C,
    "menu": 0x5D, "apps": 0x5D, "clear": 0x0C,
    "volumemute": 0xAD, "volumedown": 0xAE, "volumeup": 0xAF,
    "minus": 0xBD, "plus": 0xBB, "equal": 0xBB, "comma": 0xBC, "period": 0xBE, "slash": 0xBF,
    "semicolon": 0xBA, "apostrophe": 0xDE, "bracketleft": 0xDB, "bracketright": 0xDD, "backslash": 0xDC,
    "grave": 0xC0,
}
VK.update({f"f{i}": 0x6F + i for i in range(1, 25)})
VK.update({f"num{i}": 0x60 + i for i in range(10)})
# Keys whose scan code has the E0 prefix: they need KEYEVENTF_EXTENDEDKEY or they act as their keypad twins.
EXTENDED = {0x21, 0x22, 0x23, 0x24, 0x25, 0x26, 0x27, 0x28, 0x2D, 0x2E, 0x5B, 0x5C, 0x5D, 0xA3, 0xA5, 0x2C, 0x90,
            0x6F}


class InputError(ValueError):
    """An action the device cannot carry out as asked (bad key name, point off screen)."""


def _send(events: list[w.INPUT]) -> None:
    if not events:
        return
    arr = (w.INPUT * len(events))(*events)
    sent = w.SendInput(len(events), arr, ctypes.sizeof(w.INPUT))
    if sent != len(events):
        raise OSError(f"SendInput sent {sent} of {len(events)} events (error {ctypes.get_last_error()})")


def _key_event(vk: int, up: bool, scan: int | None = None, unicode: bool = False) -> w.INPUT:
    ev = w.INPUT(type=w.INPUT_KEYBOARD)
    if unicode:
        ev.ki.wVk, ev.ki.wScan = 0, scan
        ev.ki.dwFlags = w.KEYEVENTF_UNICODE | (w.KEYEVENTF_KEYUP if up else 0)
        return ev
    ev.ki.wVk = vk
    ev.ki.wScan = w.MapVirtualKeyW(vk, 0) if scan is None else scan
    ev.ki.dwFlags = (w.KEYEVENTF_KEYUP if up else 0) | (w.KEYEVENTF_EXTENDEDKEY if vk in EXTENDED else 0)
    return ev


def _unicode_events(ch: str) -> list[w.INPUT]:
    """Key down and up of each UTF-16 code unit of `ch` (two for characters beyond the BMP)."""
    units = ch.encode("utf-16-le")
    out = []
    for i in range(0, len(units), 2):
        unit = int.from_bytes(units[i:i + 2], "little")
        out += [_key_event(0, False, unit, unicode=True), _key_event(0, True, unit, unicode=True)]
    return out


_KEY_SCANS: dict[str, int] = {}


def key_scan(ch: str) -> int:
    """VkKeyScanW's answer for `ch` (virtual key | 0x100 for Shift; -1: no key), asking the layout key by key where
    VkKeyScanW finds none. Under Wine on Xvfb it finds no key for ( and ), which Shift+9 and Shift+0 type; typed
    as Unicode instead (VK_PACKET) they never reached a Wine console, so an agent's `for /f (...)` lost them."""
    if ch not in _KEY_SCANS:
        scan = w.VkKeyScanW(ch)
        if scan == -1 or scan & 0xFF == 0xFF:
            scan = -1
            state, buf = (ctypes.c_ubyte * 256)(), ctypes.create_unicode_buffer(8)
            for vk in range(0x20, 0xFF):
                for shift in (False, True):
                    state[0x10] = 0x80 if shift else 0
                    if w.ToUnicode(vk, w.MapVirtualKeyW(vk, 0), state, buf, 8, 0) == 1 and buf.value[:1] == ch:
                        scan = vk | (0x100 if shift else 0)
                        break
                if scan != -1:
                    break
        _KEY_SCANS[ch] = scan
    return _KEY_SCANS[ch]


def _char_events(ch: str) -> list[w.INPUT]:
    """The key events typing one character: its key (and Shift) when the layout has it among printable ASCII,
    else the character itself as Unicode."""
    if " " <= ch <= "~":
        scan = key_scan(ch)
        if scan != -1 and not scan & 0x600:  # no Ctrl or Alt needed
            vk, shift = scan & 0xFF, bool(scan & 0x100)
            keys = [_key_event(vk, False), _key_event(vk, True)]
            return [_key_event(0xA0, False), *keys, _key_event(0xA0, True)] if shift else keys
    return _unicode_events(ch)


class Input:
    """SendInput-based mouse and keyboard (thread-safe: one action at a time).

    Under Wine every mouse event carries the absolute point it is meant for (button events too), so a click lands
    where it was aimed even though the cursor position lags there: each move warps the X pointer, and the X
    server's motion events for earlier warps come back a few milliseconds later and move the cursor to where it
    was (it settles on the last point within ~150 ms); Wine maps the normalised point to exactly that pixel. On
    Windows, whose mapping of normalised points is not specified to the pixel, the cursor is put in place with
    SetCursorPos (as pyautogui does) and button events come where it is.
    """

    absolute = w.IS_WINE

    def __init__(self):
        self.lock = threading.Lock()
        self._at: tuple[int, int] | None = None  # where our last mouse event put the cursor

    # -- mouse primitives ------------------------------------------------------------------------------------
    def _screen(self) -> tuple[int, int, int, int]:
        return virtual_screen()

    def _check_point(self, x: int, y: int) -> None:
        vx, vy, cx, cy = self._screen()
        if not (vx <= x < vx + cx and vy <= y < vy + cy):
            raise InputError(f"point ({x}, {y}) is off the {cx}x{cy} screen")

    def _mouse_event(self, flags: int, x: int | None = None, y: int | None = None, data: int = 0) -> w.INPUT:
        ev = w.INPUT(type=w.INPUT_MOUSE)
        if x is not None and y is not None and self.absolute:
            vx, vy, cx, cy = self._screen()
            # normalised 0..65535 over the virtual desktop; rounded up so the pixel the system maps it to is (x, y)
            ev.mi.dx = ((x - vx) * 65536 + cx - 1) // cx
            ev.mi.dy = ((y - vy) * 65536 + cy - 1) // cy
            flags |= w.MOUSEEVENTF_MOVE | w.MOUSEEVENTF_ABSOLUTE | w.MOUSEEVENTF_VIRTUALDESK
        ev.mi.dwFlags = flags
        ev.mi.mouseData = data & 0xFFFFFFFF
        return ev

    def _move(self, x: int, y: int) -> None:
        self._check_point(x, y)
        if self.absolute:
            _send([self._mouse_event(0, x, y)])
        else:
            w.SetCursorPos(x, y)
        self._at = (x, y)

    def _cursor(self) -> tuple[int, int]:
        p = w.W.POINT()
        w.GetCursorPos(ctypes.byref(p))
        return p.x, p.y

    def position(self) -> tuple[int, int]:
        """Where the cursor is meant to be: under Wine the point of our last mouse event (the system's cursor
        may still lag), else the system's cursor."""
        return (self._at if self.absolute else None) or self._cursor()

    def _here(self, flags: int) -> w.INPUT:
        """A mouse event at the cursor's intended point."""
        x, y = self.position()
        return self._mouse_event(flags, x, y)

    def _button(self, button: str, down: bool) -> None:
        if button not in BUTTON_FLAGS:
            raise InputError(f"unknown mouse button {button!r} (left, middle or right)")
        _send([self._here(BUTTON_FLAGS[button][0 if down else 1])])

    # -- mouse actions ---------------------------------------------------------------------------------------
    def move(self, x: int, y: int) -> None:
        with self.lock:
            self._move(x, y)

    def click(self, x: int | None, y: int | None, button: str = "left", clicks: int = 1) -> None:
        if button not in BUTTON_FLAGS:
            raise InputError(f"unknown mouse button {button!r} (left, middle or right)")
        with self.lock:
            if x is not None and y is not None:
                self._move(x, y)
            down, up = BUTTON_FLAGS[button]
            _send([self._here(f) for _ in range(clicks) for f in (down, up)])

    def button(self, button: str, down: bool) -> None:
        with self.lock:
            self._button(button, down)

    def drag(self, x0: int | None, y0: int | None, x1: int, y1: int, duration_ms: int = 200, hold_ms: int = 0,
             button: str = "left") -> None:
        """Press at (x0, y0) (default: where the cursor is), move in steps of about 20 ms, release at (x1, y1)."""
        with self.lock:
            if x0 is None or y0 is None:
                x0, y0 = self.position()
            self._check_point(x0, y0)
            self._check_point(x1, y1)
            self._move(x0, y0)
            self._button(button, True)
            if hold_ms:
                time.sleep(hold_ms / 1000)
            steps = max(2, duration_ms // 20)
            for i in range(1, steps + 1):
                time.sleep(duration_ms / 1000 / steps)
                self._move(round(x0 + (x1 - x0) * i / steps), round(y0 + (y1 - y0) * i / steps))
            self._button(button, False)

    def long_press(self, x: int, y: int, duration_ms: int) -> None:
        with self.lock:
            self._move(x, y)
            self._button("left", True)
            time.sleep(duration_ms / 1000)
            self._button("left", False)

    def scroll(self, dx: int, dy: int, x: int | None, y: int | None) -> None:
        """`dy` notches down (negative: up) and `dx` notches right (negative: left), one wheel event each."""
        with self.lock:
            if x is not None and y is not None:
                self._move(x, y)
            x, y = self.position()
            events = [self._mouse_event(w.MOUSEEVENTF_WHEEL, x, y, -w.WHEEL_DELTA if dy > 0 else w.WHEEL_DELTA)
                      for _ in range(abs(dy))]
            events += [self._mouse_event(w.MOUSEEVENTF_HWHEEL, x, y, w.WHEEL_DELTA if dx > 0 else -w.WHEEL_DELTA)
                       for _ in range(abs(dx))]
            _send(events)

    # -- keys --------------------------------------------------------------------------------------------------
    @staticmethod
    def vk_of(name: str) -> tuple[int | None, str | None]:
        """(virtual key, None) for a key name or a character the layout has; (None, char) for a character it
        lacks (typed as Unicode); InputError for an unknown name."""
        if len(name) == 1:
            ch = name
            if ch.isascii() and ch.isalpha():
                return ord(ch.upper()), None
            if ch.isascii() and ch.isdigit():
                return ord(ch), None
            scan = w.VkKeyScanW(ch)
            if scan != -1 and scan & 0xFF != 0xFF:
                return scan & 0xFF, None
            return None, ch
        vk = VK.get(name.lower())
        if vk is None:
            raise InputError(f"unknown key name {name!r} (use names such as ctrl, alt, shift, win, enter, tab, esc, "
                             "backspace, delete, home, pageup, up, f5, space, a, 1, /)")
        return vk, None

    def key(self, name: str, down: bool) -> None:
        vk, ch = self.vk_of(name)
        with self.lock:
            if vk is None:  # press and release of a character the layout lacks happen on the down event
                if down:
                    _send(_unicode_events(ch))
                return
            _send([_key_event(vk, not down)])

    def hotkey(self, names: list[str]) -> None:
        """Press the keys in order, release them in reverse order."""
        keys = [self.vk_of(n) for n in names]
        with self.lock:
            events = []
            for vk, ch in keys:
                events += [_key_event(vk, False)] if vk is not None else _unicode_events(ch)[:1]
            for vk, ch in reversed(keys):
                events += [_key_event(vk, True)] if vk is not None else _unicode_events(ch)[1:2]
            _send(events)

    def type(self, text: str) -> None:
        """Type `text` exactly: newlines as Enter, tabs as Tab, printable ASCII as the keys of the keyboard layout
        (with Shift where needed: console windows take only real keys), everything else as Unicode characters
        (KEYEVENTF_UNICODE, one event pair per UTF-16 code unit)."""
        events: list[w.INPUT] = []
        for i, ch in enumerate(text):
            if ch == "\r":
                if text[i + 1:i + 2] != "\n":
                    events += [_key_event(0x0D, False), _key_event(0x0D, True)]
            elif ch == "\n":
                events += [_key_event(0x0D, False), _key_event(0x0D, True)]
            elif ch == "\t":
                events += [_key_event(0x09, False), _key_event(0x09, True)]
            else:
                events += _char_events(ch)
        with self.lock:
            for start in range(0, len(events), 256):
                _send(events[start:start + 256])
