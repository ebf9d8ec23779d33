"""`screencap`'s raw output, parsed exactly as AOSP's `frameworks/base/cmds/screencap/screencap.cpp` writes it,
and encoded to PNG on the host (PNG on the device, `screencap -p`, costs seconds at phone resolutions).

Layout (every field a native-endian `uint32_t`, little-endian on every Android ABI), then `height` rows of
`width * bytesPerPixel(format)` bytes (the buffer's stride is dropped row by row):

- Android 7.x and older (API <= 25): `width, height, format` — a 12-byte header;
- Android 8.0 and later (API >= 26): `width, height, format, colorspace` — 16 bytes, the colour space being
  0 unknown, 1 sRGB, 2 Display P3 (`dataSpaceToInt`).

`format` is a HAL pixel format (`system/core/include/system/graphics.h`): 1 RGBA_8888, 2 RGBX_8888, 3 RGB_888,
4 RGB_565, 5 BGRA_8888. The SDK level gives the first guess of the header size; the length of the data decides
(the two layouts differ by exactly 4 bytes), so a vendor build that does not match its SDK's layout is still read
right, and anything that fits neither (a cut transfer, text in the stream) is an error, never a skewed image.
Sources (repository, path, commit) are listed in `tests/data/android/README.md`.
"""

from __future__ import annotations

import io
import struct
from dataclasses import dataclass

from jarvis_pytest.errors import InfrastructureError

COLORSPACE_SDK = 26  # first API level whose screencap writes the colorspace field
# HAL pixel format → (name, bytes per pixel, Pillow raw mode decoding it into an RGB image)
PIXEL_FORMATS: dict[int, tuple[str, int, str]] = {
    1: ("RGBA_8888", 4, "RGBX"),
    2: ("RGBX_8888", 4, "RGBX"),
    3: ("RGB_888", 3, "RGB"),
    4: ("RGB_565", 2, "BGR;16"),   # uint16 little-endian, red in the top 5 bits
    5: ("BGRA_8888", 4, "BGRX"),
}
COLORSPACES = {0: "unknown", 1: "sRGB", 2: "Display P3"}
MAX_SIDE = 16384


class UnsupportedFormat(InfrastructureError):
    """A pixel format this parser does not decode (e.g. RGBA_FP16 on a wide-colour display): use `screencap -p`."""


@dataclass(frozen=True)
class RawScreenshot:
    """One parsed `screencap` frame."""

    width: int
    height: int
    pixel_format: int
    colorspace: int | None   # None: a 12-byte header (API <= 25), which has no such field
    # header_size differs from header_size(sdk) only on builds that do not write their SDK's layout
    header_size: int
    pixels: bytes

    @property
    def format_name(self) -> str:
        return PIXEL_FORMATS.get(self.pixel_format, (f"format {self.pixel_format}",))[0]


def header_size(sdk: int | None) -> int | None:
    """12 or 16 bytes by SDK level; None when the SDK level is unknown."""
    if sdk is None:
        return None
    return 16 if sdk >= COLORSPACE_SDK else 12


def parse(data: bytes, sdk: int | None = None) -> RawScreenshot:
    """Parse raw `screencap` output; InfrastructureError (naming what was found) when it is not a frame."""
    if len(data) < 12:
        raise InfrastructureError(f"screencap returned {len(data)} bytes, not a frame: {_preview(data)}")
    width, height, fmt = struct.unpack_from("<III", data, 0)
    if fmt not in PIXEL_FORMATS:
        if 0 < width <= MAX_SIDE and 0 < height <= MAX_SIDE:
            raise UnsupportedFormat(f"screencap pixel format {fmt} ({width}x{height}) is not decoded here")
        raise InfrastructureError(f"screencap output is not a raw frame (header {width}x{height} format "
                                  f"{fmt}): {_preview(data)}")
    if not (0 < width <= MAX_SIDE and 0 < height <= MAX_SIDE):
        raise InfrastructureError(f"screencap header gives an impossible size {width}x{height}")
    bpp = PIXEL_FORMATS[fmt][1]
    body = width * height * bpp
    expected = header_size(sdk)
    candidates = [expected] if expected else []
    candidates += [h for h in (16, 12) if h not in candidates]
    for hs in candidates:
        if len(data) == hs + body:  # exact: the two layouts differ by 4 bytes, so the length decides
            colorspace = struct.unpack_from("<I", data, 12)[0] if hs == 16 else None
            if colorspace is not None and colorspace not in COLORSPACES:
                raise InfrastructureError(f"screencap colorspace field is {colorspace}, not 0, 1 or 2")
            return RawScreenshot(width, height, fmt, colorspace, hs, data[hs:])
    raise InfrastructureError(
        f"screencap frame has {len(data)} bytes; a {width}x{height} {PIXEL_FORMATS[fmt][0]} frame has "
        f"{body} bytes of pixels after a 12- or 16-byte header (truncated transfer, or text mixed into the "
        f"stream: {_preview(data[16:48] if len(data) > 16 else data)})")


def to_png(shot: RawScreenshot, compress_level: int = 1) -> bytes:
    """The frame as an RGB PNG (alpha dropped: screen pixels are opaque)."""
    from PIL import Image

    name, _, rawmode = PIXEL_FORMATS[shot.pixel_format]
    img = Image.frombytes("RGB", (shot.width, shot.height), shot.pixels, "raw", rawmode)
    buf = io.BytesIO()
    img.save(buf, format="PNG", compress_level=compress_level)
    return buf.getvalue()


def _preview(data: bytes) -> str:
    return repr(data[:48])
