"""Generators of image files drawn with Pillow: pictures whose halves and corners differ, so that size, flips,
rotations, colour changes and crops of them can be told apart."""

from __future__ import annotations

import io

from PIL import Image, ImageDraw

from jarvis_pytest.generators.registry import generator


@generator("quadrant_image")
def quadrant_image(width: int = 640, height: int = 480, colors: list[str] | None = None, mark: str = "#ffffff",
                   format: str = "PNG", quality: int = 92) -> bytes:
    """A `width`×`height` picture of four coloured quadrants (top-left, top-right, bottom-left, bottom-right) with
    a `mark` disc in the top-left one, as PNG or JPEG bytes."""
    colors = colors or ["#d62828", "#003f88", "#2a9d8f", "#f4a261"]
    if len(colors) != 4 or int(width) < 8 or int(height) < 8:
        raise TypeError("`colors` must list 4 colours and the size be at least 8×8")
    w, h = int(width), int(height)
    img = Image.new("RGB", (w, h))
    draw = ImageDraw.Draw(img)
    for i, color in enumerate(colors):
        x, y = (i % 2) * w // 2, (i // 2) * h // 2
        draw.rectangle((x, y, x + w // 2 + 1, y + h // 2 + 1), fill=color)
    r = min(w, h) // 10
    draw.ellipse((w // 4 - r, h // 4 - r, w // 4 + r, h // 4 + r), fill=mark)
    buf = io.BytesIO()
    fmt = format.upper()
    img.save(buf, fmt, **({"quality": int(quality)} if fmt == "JPEG" else {"optimize": False}))
    return buf.getvalue()
