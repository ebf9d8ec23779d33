"""Test screenshots made with Pillow (a plain background with coloured rectangles at known places), and a strict
reader of the devices' own PNGs."""

from __future__ import annotations

import io
import zlib

from PIL import Image, ImageDraw

RED = (220, 20, 20)


def screenshot(width: int, height: int, boxes: list[tuple[int, int, int, int]] = (),
               color: tuple[int, int, int] = RED, background: tuple[int, int, int] = (235, 235, 240)) -> bytes:
    """A PNG of `width`x`height` with filled rectangles (x1, y1, x2, y2) in `color`."""
    img = Image.new("RGB", (width, height), background)
    draw = ImageDraw.Draw(img)
    for box in boxes:
        draw.rectangle(box, fill=color)
    out = io.BytesIO()
    img.save(out, format="PNG", compress_level=1)
    return out.getvalue()


def red_box(png: bytes) -> tuple[int, int, int, int]:
    """The bounding box of the red pixels of `png` (what a fake grounding model "sees")."""
    from PIL import ImageChops

    with Image.open(io.BytesIO(png)) as img:
        r, g, _ = img.convert("RGB").split()
        mask = ImageChops.subtract(r, g).point(lambda v: 255 if v > 120 else 0)
        box = mask.getbbox()
    assert box is not None, "no red element in the image"
    return box


def strict_rows(png: bytes) -> bytes:
    """The filtered rows of a PNG, its chunk CRCs and zlib stream (Adler-32 included) checked."""
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat = 8, b""
    while pos < len(png):
        n = int.from_bytes(png[pos:pos + 4], "big")
        kind, data = png[pos + 4:pos + 8], png[pos + 8:pos + 8 + n]
        assert zlib.crc32(kind + data) == int.from_bytes(png[pos + 8 + n:pos + 12 + n], "big")
        idat += data if kind == b"IDAT" else b""
        pos += 12 + n
    return zlib.decompress(idat)
