"""The clipboard as text (CF_UNICODETEXT), owned by a message-only window whose thread pumps messages (so other
programs emptying the clipboard never wait on us)."""

from __future__ import annotations

import ctypes
import threading
import time

from . import win32 as w

_owner: int | None = None
_ready = threading.Event()
_lock = threading.Lock()


def _pump() -> None:
    global _owner
    _owner = w.CreateWindowExW(0, "STATIC", "jarvis clipboard", 0, 0, 0, 0, 0, w.HWND_MESSAGE, None, None, None)
    _ready.set()
    msg = w.W.MSG()
    while w.GetMessageW(ctypes.byref(msg), None, 0, 0) > 0:
        w.TranslateMessage(ctypes.byref(msg))
        w.DispatchMessageW(ctypes.byref(msg))


def _open(timeout: float = 2.0) -> None:
    if not _ready.is_set():
        threading.Thread(target=_pump, name="clipboard owner", daemon=True).start()
        _ready.wait(5)
    deadline = time.monotonic() + timeout
    while not w.OpenClipboard(_owner):
        if time.monotonic() > deadline:
            raise OSError(f"the clipboard stays open in another program (error {ctypes.get_last_error()})")
        time.sleep(0.01)


def get_text() -> str:
    """The clipboard's text ("" when it holds no text)."""
    with _lock:
        _open()
        try:
            if not w.IsClipboardFormatAvailable(w.CF_UNICODETEXT):
                return ""
            handle = w.GetClipboardData(w.CF_UNICODETEXT)
            if not handle:
                return ""
            ptr = w.GlobalLock(handle)
            if not ptr:
                return ""
            try:
                size = w.GlobalSize(handle) // 2
                text = ctypes.wstring_at(ptr, size)
                return text.split("\0", 1)[0]
            finally:
                w.GlobalUnlock(handle)
        finally:
            w.CloseClipboard()


def set_text(text: str) -> None:
    """Put `text` on the clipboard."""
    data = text.encode("utf-16-le") + b"\0\0"
    with _lock:
        _open()
        try:
            w.EmptyClipboard()
            handle = w.GlobalAlloc(w.GMEM_MOVEABLE, len(data))
            if not handle:
                raise MemoryError("GlobalAlloc failed for the clipboard")
            ptr = w.GlobalLock(handle)
            ctypes.memmove(ptr, data, len(data))
            w.GlobalUnlock(handle)
            if not w.SetClipboardData(w.CF_UNICODETEXT, handle):
                w.GlobalFree(handle)
                raise OSError(f"SetClipboardData failed (error {ctypes.get_last_error()})")
        finally:
            w.CloseClipboard()
