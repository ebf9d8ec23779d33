"""PYAUTOGUI actions: scripts written against pyautogui run on a device's own input (XTest on Ubuntu, SendInput on
Windows). Standard library only: it runs inside the devices.

pyautogui itself is not installable offline (PyPI has only its source package, Debian none) nor on the
embeddable Windows CPython, so this module offers the calls agents use — moveTo, move/moveRel, click, doubleClick, tripleClick, rightClick,
middleClick, mouseDown, mouseUp, dragTo, drag/dragRel, scroll, hscroll, write/typewrite, press, keyDown, keyUp,
hotkey, position, size, sleep — with pyautogui's argument names and conventions (scroll > 0 is up). A script
`import pyautogui` gets this module. Anything else it calls is an AttributeError, reported to the agent.

A control server runs each script in a child process of its own (`run_isolated`): a script that exits the
interpreter (`sys.exit`, `os._exit`), sleeps or loops past `SCRIPT_SECONDS`, or crashes its interpreter is the
agent's step error (`ScriptError`), and the server and its device go on as before.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
import types

SCRIPT_SECONDS = 20.0  # a PYAUTOGUI script is stopped after this long (the harness waits 30 s for an action)
OUTPUT_TAIL = 2000  # characters of a failed script's error output kept for the agent
_DONE_LINE = b"\x00jarvis-script-done\n"  # the child's last line on standard output once the script returned
_FAILED = 3  # the child's exit status when the script raised (its error on standard error)



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


class ScriptError(Exception):
    """A PYAUTOGUI script that did not run to its end; the message says why, for the agent."""


def _drain(stream, tail: bytearray) -> None:
    """Read `stream` to its end, keeping its last OUTPUT_TAIL bytes in `tail` as they come."""
    while True:
        chunk = stream.read1(65536)
        if not chunk:
            return
        tail += chunk
        del tail[:-OUTPUT_TAIL]


def _feed(stream, data: bytes) -> None:
    try:
        stream.write(data)
        stream.close()
    except OSError:  # the child ended without reading it all
        pass


def _stop(proc: subprocess.Popen) -> None:
    """Kill the child and, on POSIX, every process of its session (what the script started)."""
    try:
        if os.name == "posix":
            os.killpg(proc.pid, signal.SIGKILL)
        else:
            proc.kill()
    except OSError:  # already gone
        pass
    proc.wait()


def run_isolated(command: list[str], script: str, seconds: float = SCRIPT_SECONDS,
                 env: dict[str, str] | None = None) -> None:
    """Run `script` in a child process started with `command`, a program that hands its standard input to
    `child_main` (a server's `--run-script`); returns once the script returned, else raises ScriptError: it raised,
    exited the interpreter, or ran past `seconds` (then it and what it started are killed; programs a script that
    did return left running, e.g. an application it opened, stay). `env`: the child's environment."""
    options: dict = {"start_new_session": True} if os.name == "posix" else {
        "creationflags": getattr(subprocess, "CREATE_NEW_PROCESS_GROUP", 0)}
    proc = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            env=env, **options)
    out, err = bytearray(), bytearray()
    threads = [threading.Thread(target=_feed, args=(proc.stdin, script.encode("utf-8")), daemon=True),
               threading.Thread(target=_drain, args=(proc.stdout, out), daemon=True),
               threading.Thread(target=_drain, args=(proc.stderr, err), daemon=True)]
    for t in threads:
        t.start()
    try:
        proc.wait(timeout=seconds)
    except subprocess.TimeoutExpired:
        _stop(proc)
        raise ScriptError(f"the script ran past its {seconds:g} s limit and was stopped") from None
    finally:
        # A program the script started (and left running) may hold the pipes open: wait for the output a second
        # at most, and not at all once the done line is in.
        until = time.monotonic() + 1.0
        while any(t.is_alive() for t in threads[1:]) and time.monotonic() < until and not out.endswith(_DONE_LINE):
            time.sleep(0.01)
    stderr = bytes(err).decode("utf-8", "replace").strip()
    if proc.returncode == 0 and out.endswith(_DONE_LINE):
        return
    if proc.returncode == _FAILED and stderr:
        raise ScriptError(stderr.splitlines()[-1])
    raise ScriptError(f"the script ended its interpreter (exit status {proc.returncode}) before it finished"
                      + (f": {stderr[-300:]}" if stderr else ""))


def child_main(run) -> None:
    """The child of `run_isolated`: `run(script)` on the script read from standard input, then exit 0 after the
    done line, or with status 3 and the script's error on the last line of standard error."""
    script = sys.stdin.buffer.read().decode("utf-8")
    try:
        run(script)
    except SystemExit as exc:
        sys.stderr.write(f"the script exited the interpreter (sys.exit({exc.code!r}))\n")
        sys.stderr.flush()
        os._exit(_FAILED)
    except BaseException as exc:
        text = " ".join(f"{exc.__class__.__name__}: {exc}".split())
        sys.stderr.write(text[:OUTPUT_TAIL] + "\n")
        sys.stderr.flush()
        os._exit(_FAILED)
    sys.stdout.flush()
    sys.stdout.buffer.write(_DONE_LINE)
    sys.stdout.flush()
    os._exit(0)  # no clean-up of the script's leftovers (atexit handlers, threads) may hang the child
