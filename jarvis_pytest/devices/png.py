"""PNG encoding of screen captures with the standard library alone: it runs in the control servers of the Ubuntu
device (BGRX pixels from X's shared memory) and of the Windows device (BGR rows from GDI, on the embeddable CPython).

The image is cut into bands of rows, each compressed on its own (raw deflate, level 1, filter type 0, ended on a
byte boundary) so the bands concatenate into one zlib stream; the stream's Adler-32 is combined from the bands'.
`PngEncoder` keeps the last frame: a band whose pixels did not change reuses its compressed bytes, so an agent's
next screenshot after a click or a few typed letters costs the few bands that changed (a whole 1920x1080 frame
costs about 15 ms of zlib). Changed bands are compressed on two threads (zlib releases the GIL). Pixels other
than RGB are reordered only in the bands that changed: with extended-slice assignments (C loops, never per pixel
in Python), or by a faster converter the caller has (Pillow's, in the Ubuntu server).
"""

from __future__ import annotations

import struct
import threading
import zlib
from concurrent.futures import ThreadPoolExecutor
from typing import Callable

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
BAND_ROWS = 32
ADLER_BASE = 65521
FINAL_BLOCK = b"\x03\x00"  # an empty final deflate block (fixed Huffman, end of block)
PIXEL_BYTES = {"RGB": 3, "BGR": 3, "BGRX": 4}  # the pixel layouts a frame may come in


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def adler32_combine(adler1: int, adler2: int, len2: int) -> int:
    """The Adler-32 of A+B from those of A and B and the length of B (zlib's adler32_combine)."""
    rem = len2 % ADLER_BASE
    sum1 = adler1 & 0xFFFF
    sum2 = (rem * sum1) % ADLER_BASE
    sum1 += (adler2 & 0xFFFF) + ADLER_BASE - 1
    sum2 += ((adler1 >> 16) & 0xFFFF) + ((adler2 >> 16) & 0xFFFF) + ADLER_BASE - rem
    sum1 = sum1 - ADLER_BASE if sum1 >= ADLER_BASE else sum1
    sum1 = sum1 - ADLER_BASE if sum1 >= ADLER_BASE else sum1
    sum2 = sum2 - 2 * ADLER_BASE if sum2 >= 2 * ADLER_BASE else sum2
    sum2 = sum2 - ADLER_BASE if sum2 >= ADLER_BASE else sum2
    return sum1 | (sum2 << 16)


def packed_rgb(layout: str) -> Callable[[bytes, int, int, int], bytes]:
    """The standard library's converter of rows in `layout` to packed RGB: `convert(pixels, width, rows, stride)`
    (any padding past a row's pixels dropped)."""
    step = PIXEL_BYTES[layout]

    def convert(pixels: bytes, width: int, rows: int, stride: int) -> bytes:
        used = width * step
        if stride != used:
            pixels = b"".join(pixels[i * stride:i * stride + used] for i in range(rows))
        if layout == "RGB":
            return pixels
        rgb = bytearray(width * rows * 3)
        rgb[0::3], rgb[1::3], rgb[2::3] = pixels[2::step], pixels[1::step], pixels[0::step]
        return rgb

    return convert


def _band(pixels: bytes, width: int, rows: int, stride: int, level: int,
          to_rgb: Callable[[bytes, int, int, int], bytes]) -> tuple[bytes, int, int]:
    """(raw deflate ending on a byte boundary, Adler-32, length) of `rows` rows: filter byte 0, then RGB."""
    rgb, row = to_rgb(pixels, width, rows, stride), width * 3
    raw = b"\0" + b"\0".join(rgb[i * row:(i + 1) * row] for i in range(rows))
    z = zlib.compressobj(level, zlib.DEFLATED, -15)
    return z.compress(raw) + z.flush(zlib.Z_SYNC_FLUSH), zlib.adler32(raw), len(raw)


def _png(width: int, height: int, bands: list[tuple[bytes, int, int]]) -> bytes:
    adler = 1
    for _, band_adler, length in bands:
        adler = adler32_combine(adler, band_adler, length)
    idat = b"".join([b"\x78\x01", *(b[0] for b in bands), FINAL_BLOCK, struct.pack(">I", adler)])
    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return PNG_SIGNATURE + _chunk(b"IHDR", header) + _chunk(b"IDAT", idat) + _chunk(b"IEND", b"")


class PngEncoder:
    """PNG encoding of successive frames of one screen, reusing the compressed bands that did not change
    (thread-safe). `layout`: how a pixel lies in memory, "RGB", "BGR" (GDI) or "BGRX" (X, 32 bits a pixel);
    `to_rgb`: a faster converter of such rows to packed RGB where there is one (`packed_rgb`'s signature;
    Pillow's is 4x faster than the standard library's)."""

    def __init__(self, level: int = 1, threads: int = 2, layout: str = "RGB",
                 to_rgb: Callable[[bytes, int, int, int], bytes] | None = None):
        if layout not in PIXEL_BYTES:
            raise ValueError(f"pixel layout {layout!r}: one of {', '.join(PIXEL_BYTES)}")
        self.level = level
        self.layout = layout
        self.to_rgb = to_rgb or packed_rgb(layout)
        self.lock = threading.Lock()
        self.pool = ThreadPoolExecutor(max_workers=threads, thread_name_prefix="png")
        self._key: tuple[int, int, int] | None = None
        self._frame = b""
        self._bands: list[tuple[bytes, int, int]] = []
        self._png = b""

    def encode(self, pixels, width: int, height: int, stride: int | None = None) -> bytes:
        """PNG of top-down rows of `stride` bytes (the pixels, then any padding). `pixels` is any buffer (e.g. the
        DIB section's memory itself), copied unless it is `bytes` or a `bytearray` of exactly the frame: those
        are kept, to compare the next frame with, and must not change afterwards."""
        stride = stride or width * PIXEL_BYTES[self.layout]
        size = stride * height
        owned = type(pixels) in (bytes, bytearray) and len(pixels) == size
        frame = pixels if owned else bytes(memoryview(pixels)[:size])  # the one copy, kept for the next frame
        with self.lock:
            same_size = self._key == (width, height, stride)
            if same_size and frame == self._frame:
                return self._png
            step = BAND_ROWS * stride
            starts = range(0, height, BAND_ROWS)
            jobs = {}
            for i, top in enumerate(starts):
                lo, hi = top * stride, min(height, top + BAND_ROWS) * stride
                if not (same_size and frame[lo:hi] == self._frame[lo:hi]):
                    rows = min(BAND_ROWS, height - top)
                    jobs[i] = self.pool.submit(_band, frame[lo:lo + step], width, rows, stride, self.level,
                                               self.to_rgb)
            bands = self._bands if same_size else [None] * len(starts)
            for i, job in jobs.items():
                bands[i] = job.result()
            self._key, self._frame, self._bands = (width, height, stride), frame, bands
            self._png = _png(width, height, bands)
            return self._png

