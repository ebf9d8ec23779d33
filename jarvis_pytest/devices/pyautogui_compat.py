"""PYAUTOGUI actions: scripts written against pyautogui run on a device's own input (XTest on Ubuntu, SendInput on
Windows). Standard library only: it runs inside the devices.

pyautogui itself is not installable offline (PyPI has only its source package, Debian none) nor on the
embeddable Windows CPython, so this module offers the calls agents use — moveTo, move/moveRel, click, doubleClick, tripleClick, rightClick,
middleClick, mouseDown, mouseUp, dragTo, drag/dragRel, scroll, hscroll, write/typewrite, press, keyDown, keyUp,
hotkey, position, size, sleep — with pyautogui's argument names and conventions (scroll > 0 is up). A script
`import pyautogui` gets this module. Anything else it calls is an AttributeError, reported to the agent.
"""

from __future__ import annotations

import sys
import time
import types



def _opt(v):
    return None if v is None else int(v)


def _module(kb, position, size) -> types.ModuleType:
    """A `pyautogui` module bound to a device's input object `kb` (move, click, button, drag, scroll, type, key,
    hotkey), its pointer `position()` and screen `size()`."""
    m = types.ModuleType("pyautogui")
    m.FAILSAFE, m.PAUSE = False, 0.0

    def moveTo(x=None, y=None, duration=0.0, *a, **k):
        cx, cy = position()
        kb.move(int(cx if x is None else x), int(cy if y is None else y))

    def move(xOffset=0, yOffset=0, *a, **k):
        cx, cy = position()
        kb.move(cx + int(xOffset or 0), cy + int(yOffset or 0))

    def click(x=None, y=None, clicks=1, interval=0.0, button="left", *a, **k):
        kb.click(_opt(x), _opt(y), button, int(clicks))

    def mouseDown(x=None, y=None, button="left", *a, **k):
        if x is not None and y is not None:
            kb.move(int(x), int(y))
        kb.button(button, True)

    def mouseUp(x=None, y=None, button="left", *a, **k):
        if x is not None and y is not None:
            kb.move(int(x), int(y))
        kb.button(button, False)

    def dragTo(x=None, y=None, duration=0.2, button="left", *a, **k):
        extra = {} if button == "left" else {"button": button}  # not every device drags with other buttons
        kb.drag(None, None, int(x), int(y), int(max(duration, 0.04) * 1000), **extra)

    def drag(xOffset=0, yOffset=0, duration=0.2, *a, **k):
        cx, cy = position()
        dragTo(cx + int(xOffset), cy + int(yOffset), duration)

    def scroll(clicks, x=None, y=None, *a, **k):
        kb.scroll(0, -int(clicks), _opt(x), _opt(y))

    def hscroll(clicks, x=None, y=None, *a, **k):
        kb.scroll(int(clicks), 0, _opt(x), _opt(y))

    def write(message, interval=0.0, *a, **k):
        if isinstance(message, (list, tuple)):
            for key in message:
                press(key)
        else:
            kb.type(str(message))

    def press(keys, presses=1, interval=0.0, *a, **k):
        for _ in range(int(presses)):
            for key in ([keys] if isinstance(keys, str) else keys):
                kb.hotkey([key])

    def hotkey(*keys, **k):
        kb.hotkey([str(key) for key in keys])

    m.position, m.moveTo, m.move, m.moveRel = position, moveTo, move, move
    m.click, m.mouseDown, m.mouseUp, m.dragTo, m.drag, m.dragRel = click, mouseDown, mouseUp, dragTo, drag, drag
    m.doubleClick = lambda x=None, y=None, *a, **k: click(x, y, 2)
    m.tripleClick = lambda x=None, y=None, *a, **k: click(x, y, 3)
    m.rightClick = lambda x=None, y=None, *a, **k: click(x, y, 1, button="right")
    m.middleClick = lambda x=None, y=None, *a, **k: click(x, y, 1, button="middle")
    m.scroll, m.hscroll, m.vscroll = scroll, hscroll, scroll
    m.write, m.typewrite, m.press, m.hotkey = write, write, press, hotkey
    m.keyDown = lambda key, *a, **k: kb.key(str(key), True)
    m.keyUp = lambda key, *a, **k: kb.key(str(key), False)
    m.size = size
    m.sleep = time.sleep
    return m


def run_script(script: str, kb, position, size) -> None:
    """Execute a pyautogui script on this device (its errors propagate to the caller)."""
    module = _module(kb, position, size)
    sys.modules["pyautogui"] = module
    exec(compile(script, "<PYAUTOGUI action>", "exec"), {"pyautogui": module, "time": time, "__name__": "__action__"})
