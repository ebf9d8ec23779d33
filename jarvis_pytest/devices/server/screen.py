"""Screen capture: the root window grabbed through XCB (Pillow's C code), the pointer drawn on it, PNG out.

The PNG is written here rather than by Pillow: rows with filter type 0 and zlib level 1 encode a 1920×1080
desktop in about 30 ms against 40 ms for Pillow's adaptive filtering, at a similar size (screens are flat).
"""

from __future__ import annotations

import struct
import threading
import zlib

from PIL import Image, ImageDraw, ImageGrab, ImageStat
from Xlib import display

_ARROW = [(0, 0), (0, 17), (4, 13), (7, 20), (10, 19), (7, 12), (12, 12)]


def encode_png(img: Image.Image, level: int = 1) -> bytes:
    """An RGB image as PNG (8-bit truecolour, no filtering)."""
    img = img.convert("RGB")
    w, h = img.size
    raw, stride = img.tobytes(), w * 3
    rows = b"".join(b"\x00" + raw[i:i + stride] for i in range(0, len(raw), stride))

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows, level)) + chunk(b"IEND", b"")


class Screen:
    """Screenshots of the X display (thread-safe)."""

    def __init__(self, name: str | None = None):
        self.name = name
        self.display = display.Display(name)
        self.root = self.display.screen().root
        self.lock = threading.Lock()

    def size(self) -> tuple[int, int]:
        with self.lock:
            geom = self.root.get_geometry()
        return geom.width, geom.height

    def grab(self) -> Image.Image:
        """The screen with the pointer drawn where it is."""
        img = ImageGrab.grab(xdisplay=self.name or "")
        with self.lock:
            pointer = self.root.query_pointer()
        px, py = pointer.root_x, pointer.root_y
        ImageDraw.Draw(img).polygon([(px + dx, py + dy) for dx, dy in _ARROW], fill=(255, 255, 255),
                                    outline=(0, 0, 0))
        return img

    def painted(self, min_stddev: float = 8.0) -> bool:
        """Whether the screen shows something (a desktop that is up but not yet drawn is one flat colour)."""
        small = ImageGrab.grab(xdisplay=self.name or "").reduce(8).convert("L")
        return ImageStat.Stat(small).stddev[0] >= min_stddev

    def png(self) -> bytes:
        return encode_png(self.grab())
