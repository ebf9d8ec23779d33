"""The devices' shared PNG writer (`jarvis_pytest/devices/png.py`), on the host: every frame decodes to exactly its
pixels, strictly (chunk CRCs and the zlib stream's Adler-32, which is combined from the bands'), whether a band
was compressed anew or reused from the frame before. The device tests run it again inside each device's server."""

from __future__ import annotations

import io
import random
import zlib

import pytest
from PIL import Image

from jarvis_pytest.devices.png import BAND_ROWS, PngEncoder, adler32_combine
from screens import strict_rows


def encode_png(pixels, w: int, h: int, stride: int | None = None, layout: str = "RGB") -> bytes:
    """One frame, by an encoder that has seen no other."""
    return PngEncoder(layout=layout).encode(pixels, w, h, stride)


def decoded(png: bytes, w: int, h: int) -> bytes:
    assert len(strict_rows(png)) == h * (w * 3 + 1)
    img = Image.open(io.BytesIO(png))
    assert img.mode == "RGB" and img.size == (w, h)
    return img.tobytes()


def test_adler32_combine_is_zlibs():
    rnd = random.Random(1)
    for _ in range(200):
        a, b = rnd.randbytes(rnd.randrange(0, 70000)), rnd.randbytes(rnd.randrange(0, 70000))
        assert adler32_combine(zlib.adler32(a), zlib.adler32(b), len(b)) == zlib.adler32(a + b)


def test_one_frame_keeps_every_pixel_in_every_layout():
    rnd = random.Random(2)
    for w, h in ((1, 1), (7, 3), (333, 211), (64, BAND_ROWS), (64, BAND_ROWS + 1)):
        img = Image.frombytes("RGB", (w, h), rnd.randbytes(w * h * 3))
        rgb = img.tobytes()
        for layout in ("RGB", "BGR", "BGRX"):
            assert decoded(encode_png(img.tobytes("raw", layout), w, h, layout=layout), w, h) == rgb, layout
    with pytest.raises(ValueError, match="pixel layout 'RGBA'"):
        PngEncoder(layout="RGBA")


def test_padded_rows_lose_their_padding():
    """GDI pads each row to 4 bytes, X may pad too: a stride wider than the pixels."""
    w, h = 5, 9
    img = Image.frombytes("RGB", (w, h), random.Random(4).randbytes(w * h * 3))
    for layout, stride in (("RGB", 16), ("BGR", 16), ("BGRX", 24)):
        data = img.tobytes("raw", layout)
        used = len(data) // h
        padded = b"".join(data[r * used:(r + 1) * used] + b"\xee" * (stride - used) for r in range(h))
        assert decoded(encode_png(padded, w, h, stride, layout), w, h) == img.tobytes(), layout


def test_successive_frames_reuse_unchanged_bands_and_stay_exact():
    """A screen where a few rows change at a time (typing, a click, the cursor): each frame decodes to exactly
    its pixels; an unchanged frame is the same bytes; a new size starts over."""
    rnd = random.Random(3)
    w, h = 640, 400
    frame = bytearray(bytes([58, 110, 165]) * (w * h))
    enc = PngEncoder()
    first = enc.encode(bytes(frame), w, h)
    assert decoded(first, w, h) == frame
    assert enc.encode(bytes(frame), w, h) == first
    assert enc.encode(bytearray(frame), w, h) == first  # a bytearray of the frame is kept as it is
    for _ in range(30):
        y, x, n = rnd.randrange(h), rnd.randrange(w - 20), rnd.randrange(1, 4)
        for row in range(y, min(h, y + n)):
            frame[(row * w + x) * 3:(row * w + x + 20) * 3] = rnd.randbytes(60)
        png = enc.encode(bytes(frame), w, h)
        assert decoded(png, w, h) == frame == decoded(encode_png(bytes(frame), w, h), w, h)
    small = rnd.randbytes(30 * 20 * 3)
    assert decoded(enc.encode(small, 30, 20), 30, 20) == small
    assert decoded(enc.encode(bytes(frame), w, h), w, h) == frame


def test_a_frame_with_one_changed_band_compresses_only_that_band(monkeypatch):
    import jarvis_pytest.devices.png as png

    calls = []
    real = png._band
    monkeypatch.setattr(png, "_band", lambda *a: calls.append(a[2]) or real(*a))
    w, h = 100, BAND_ROWS * 4
    frame = bytearray(b"\x10" * (w * h * 3))
    enc = PngEncoder()
    enc.encode(bytes(frame), w, h)
    assert len(calls) == 4
    frame[(BAND_ROWS * 2 + 5) * w * 3] = 0xFF  # one byte in the third band
    calls.clear()
    assert decoded(enc.encode(bytes(frame), w, h), w, h) == frame
    assert len(calls) == 1
