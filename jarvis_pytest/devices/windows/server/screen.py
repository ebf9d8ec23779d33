"""Screen capture through GDI: the whole virtual screen BitBlt'ed into a DIB section, the cursor drawn with
DrawIconEx where GetCursorInfo says it is, then PNG (default) or BMP out.

Under Wine the cursor handle GetCursorInfo gives belongs to the program under the pointer and cannot be drawn by
another process, so the standard arrow stands in for it there (real Windows draws the actual shape)."""

from __future__ import annotations

import ctypes
import struct
import threading

from jarvis_pytest.devices.png import PngEncoder
from . import win32 as w


def virtual_screen() -> tuple[int, int, int, int]:
    """(x, y, width, height) of the virtual screen in physical pixels (the process is DPI-aware)."""
    return (w.GetSystemMetrics(w.SM_XVIRTUALSCREEN), w.GetSystemMetrics(w.SM_YVIRTUALSCREEN),
            w.GetSystemMetrics(w.SM_CXVIRTUALSCREEN), w.GetSystemMetrics(w.SM_CYVIRTUALSCREEN))


class Screen:
    """Screenshots of the desktop (thread-safe; one DIB section kept while the screen size stays)."""

    def __init__(self):
        self.lock = threading.Lock()
        self._dib = None  # (width, height, memory DC, bitmap, bits pointer, stride)
        self._hotspots: dict[int, tuple[int, int]] = {}
        self._encoder = PngEncoder(layout="BGR")

    def size(self) -> tuple[int, int]:
        _, _, cx, cy = virtual_screen()
        return cx, cy

    def _surface(self, width: int, height: int):
        if self._dib and self._dib[:2] == (width, height):
            return self._dib
        if self._dib:
            _, _, dc, bmp, _, _ = self._dib
            w.DeleteDC(dc)
            w.DeleteObject(bmp)
            self._dib = None
        info = w.BITMAPINFO()
        h = info.bmiHeader
        h.biSize, h.biWidth, h.biHeight = ctypes.sizeof(w.BITMAPINFOHEADER), width, -height  # top-down rows
        h.biPlanes, h.biBitCount, h.biCompression = 1, 24, w.BI_RGB
        bits = ctypes.c_void_p()
        screen_dc = w.GetDC(None)
        try:
            dc = w.CreateCompatibleDC(screen_dc)
            bmp = w.CreateDIBSection(screen_dc, ctypes.byref(info), w.DIB_RGB_COLORS, ctypes.byref(bits), None, 0)
        finally:
            w.ReleaseDC(None, screen_dc)
        if not dc or not bmp or not bits.value:
            raise OSError(f"cannot create a {width}x{height} DIB section (error {ctypes.get_last_error()})")
        w.SelectObject(dc, bmp)
        self._dib = (width, height, dc, bmp, bits.value, (width * 3 + 3) // 4 * 4)
        return self._dib

    def _hotspot(self, cursor: int) -> tuple[int, int]:
        if cursor not in self._hotspots:
            info = w.ICONINFO()
            if w.GetIconInfo(cursor, ctypes.byref(info)):
                for bmp in (info.hbmMask, info.hbmColor):
                    if bmp:
                        w.DeleteObject(bmp)
                self._hotspots[cursor] = (info.xHotspot, info.yHotspot)
            else:
                return (0, 0)
        return self._hotspots[cursor]

    def _draw_cursor(self, dc: int, x0: int, y0: int) -> None:
        ci = w.CURSORINFO()
        ci.cbSize = ctypes.sizeof(ci)
        if not (w.GetCursorInfo(ctypes.byref(ci)) and ci.flags & w.CURSOR_SHOWING and ci.hCursor):
            return
        x, y = ci.ptScreenPos.x - x0, ci.ptScreenPos.y - y0
        hx, hy = self._hotspot(ci.hCursor)
        if w.DrawIconEx(dc, x - hx, y - hy, ci.hCursor, 0, 0, 0, None, w.DI_NORMAL):
            return
        # Under Wine another program's cursor handle is not valid here: draw the standard arrow instead.
        arrow = w.LoadCursorW(None, w.IDC_ARROW)
        hx, hy = self._hotspot(arrow)
        w.DrawIconEx(dc, x - hx, y - hy, arrow, 0, 0, 0, None, w.DI_NORMAL)

    def _grab(self, cursor: bool):
        """BitBlt the virtual screen into the DIB section (call with the lock held); returns (the section's memory,
        width, height, stride), valid until the next grab."""
        x0, y0, width, height = virtual_screen()
        _, _, dc, _, bits, stride = self._surface(width, height)
        screen_dc = w.GetDC(None)
        try:
            if not w.BitBlt(dc, 0, 0, width, height, screen_dc, x0, y0, w.SRCCOPY | w.CAPTUREBLT):
                raise OSError(f"BitBlt of the screen failed (error {ctypes.get_last_error()})")
        finally:
            w.ReleaseDC(None, screen_dc)
        if cursor:
            self._draw_cursor(dc, x0, y0)
        w.GdiFlush()
        return (ctypes.c_char * (stride * height)).from_address(bits), width, height, stride

    def capture(self, cursor: bool = True) -> tuple[bytes, int, int, int]:
        """(BGR rows top-down, width, height, stride) of the whole virtual screen, the cursor drawn on it."""
        with self.lock:
            view, width, height, stride = self._grab(cursor)
            return bytes(view), width, height, stride

    def png(self) -> bytes:
        with self.lock:  # encoded straight from the DIB section's memory
            return self._encoder.encode(*self._grab(True))

    def bmp(self) -> bytes:
        with self.lock:
            return bgr_to_bmp(*self._grab(True))

    def painted(self, box: list[int]) -> bool:
        """Whether the screen area `box` [x, y, w, h] shows more than one colour (something is drawn there)."""
        data, width, height, stride = self.capture(cursor=False)
        x, y, bw, bh = box
        x, y = max(0, x), max(0, y)
        bw, bh = min(bw, width - x), min(bh, height - y)
        if bw <= 0 or bh <= 0:
            return False
        first = data[y * stride + x * 3:y * stride + x * 3 + 3]
        for row in range(y, y + bh, max(1, bh // 8)):
            line = data[row * stride + x * 3:row * stride + (x + bw) * 3]
            if line != first * bw:
                return True
        return False


def bgr_to_bmp(bgr, width: int, height: int, stride: int | None = None) -> bytes:
    """A top-down 24-bit BMP of GDI's rows as they are (no pixel touched; 6 MB at 1920x1080)."""
    stride = stride or (width * 3 + 3) // 4 * 4
    size = stride * height
    info = struct.pack("<IiiHHIIiiII", 40, width, -height, 1, 24, 0, size, 3780, 3780, 0, 0)
    return b"".join((b"BM", struct.pack("<IHHI", 14 + 40 + size, 0, 0, 14 + 40), info, memoryview(bgr)[:size]))
