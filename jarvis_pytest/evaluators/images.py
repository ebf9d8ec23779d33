"""Image checks, read with Pillow on the host: brightness, size, file format, JPEG quality, grayscale, and geometric
or colour transformations of a reference image (flips, rotations, inversion, borders, side by side)."""

from __future__ import annotations

import io
from typing import Callable

from PIL import Image, ImageChops, ImageOps, ImageStat

from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.state import FinalState

# What a person's edit of `reference` should look like, for `image_transformed_from`.
TRANSFORMS = {
    "flip_horizontal": lambda im: ImageOps.mirror(im),
    "flip_vertical": lambda im: ImageOps.flip(im),
    "rotate_90": lambda im: im.transpose(Image.Transpose.ROTATE_270),  # clockwise, as `convert -rotate 90`
    "rotate_180": lambda im: im.transpose(Image.Transpose.ROTATE_180),
    "rotate_270": lambda im: im.transpose(Image.Transpose.ROTATE_90),
    "invert": lambda im: ImageOps.invert(im),
    "grayscale": lambda im: ImageOps.grayscale(im).convert("RGB"),
    "identity": lambda im: im,
}
TRANSFORM_WORDS = {"flip_horizontal": "flipped horizontally", "flip_vertical": "flipped vertically",
                   "rotate_90": "rotated 90° clockwise", "rotate_180": "rotated 180°",
                   "rotate_270": "rotated 270° clockwise", "invert": "inverted", "grayscale": "in grayscale",
                   "identity": "unchanged"}


def open_image(data: bytes | None) -> Image.Image | None:
    """The decoded image of `data`, or None when there is none or it does not decode."""
    if data is None:
        return None
    try:
        img = Image.open(io.BytesIO(data))
        img.load()
        return img
    except Exception:
        return None


def judge_images(state: FinalState, paths: list[str], want: str, check: Callable[..., Verdict],
                 platform: str | None = None) -> Verdict:
    """Pull and decode every file of `paths` and `check(*images)`; a missing file or one that is no image is a
    failed verdict naming it."""
    images = []
    for path in paths:
        data = state.pull(path, platform)
        if data is None:
            return Verdict.check(False, want, f"no file at {path}")
        img = open_image(data)
        if img is None:
            return Verdict.check(False, want, f"{path} is no readable image ({len(data)} bytes)")
        images.append(img)
    return check(*images)


def mean_luma(img: Image.Image) -> float:
    return ImageStat.Stat(img.convert("L")).mean[0]


def mean_difference(a: Image.Image, b: Image.Image) -> float:
    """Mean absolute per-channel difference (0–255) of two images, `b` scaled to `a`'s size."""
    a, b = a.convert("RGB"), b.convert("RGB")
    if a.size != b.size:
        b = b.resize(a.size)
    return sum(ImageStat.Stat(ImageChops.difference(a, b)).mean) / 3


def check_brighter(img: Image.Image | None, ref: Image.Image | None, min_ratio: float = 1.1) -> Verdict:
    """The mean brightness of `img` is at least `min_ratio` × that of `ref`."""
    if img is None or ref is None:
        return Verdict.check(False, "an image brighter than the reference", "no readable image")
    a, b = mean_luma(img), mean_luma(ref)
    ratio = a / b if b else float("inf")
    return Verdict.check(ratio >= float(min_ratio), f"mean brightness ≥ {float(min_ratio):.2f} × {b:.1f}",
                         f"{a:.1f} ({ratio:.2f} ×)")


@evaluator("image_brighter")
def image_brighter(state: FinalState, path: str, reference: str, min_ratio: float = 1.1,
                   platform: str | None = None) -> Verdict:
    """`path` is an image whose mean brightness is at least `min_ratio` × that of `reference`."""
    return judge_images(state, [path, reference], f"{path} brighter than {reference}",
                        lambda img, ref: check_brighter(img, ref, float(min_ratio)), platform)


def check_size(img: Image.Image | None, width: int, height: int, tolerance: int = 0) -> Verdict:
    """The image is `width`×`height` pixels, each side within `tolerance` pixels (rounding of a scale)."""
    found = "no readable image" if img is None else f"{img.width}×{img.height}"
    ok = img is not None and abs(img.width - int(width)) <= tolerance and abs(img.height - int(height)) <= tolerance
    return Verdict.check(ok, f"{width}×{height}" + (f" (±{tolerance})" if tolerance else ""), found)


@evaluator("image_size_is")
def image_size_is(state: FinalState, path: str, width: int, height: int, tolerance: int = 0,
                  platform: str | None = None) -> Verdict:
    return judge_images(state, [path], f"a {width}×{height} image at {path}",
                        lambda img: check_size(img, int(width), int(height), int(tolerance)), platform)


def check_scaled(img: Image.Image | None, ref: Image.Image | None, percent: float | None = None,
                 width: int | None = None) -> Verdict:
    """`img` is `ref` scaled to `percent` % (or to `width` pixels wide), keeping its aspect ratio (±1 pixel)."""
    if img is None or ref is None:
        return Verdict.check(False, "a scaled copy of the picture", "no readable image")
    factor = float(percent) / 100 if percent is not None else int(width) / ref.width
    w, h = round(ref.width * factor), round(ref.height * factor)
    ok = abs(img.width - w) <= 1 and abs(img.height - h) <= 1 and mean_difference(img, ref) <= 16
    return Verdict.check(ok, f"{w}×{h} (±1, {ref.width}×{ref.height} scaled by {factor:.3g}) showing the picture",
                         f"{img.width}×{img.height}, mean difference {mean_difference(img, ref):.1f}")


@evaluator("image_scaled_from")
def image_scaled_from(state: FinalState, path: str, reference: str, percent: float | None = None,
                      width: int | None = None, platform: str | None = None) -> Verdict:
    """`path` is `reference` scaled by `percent` % or to `width` pixels wide, aspect ratio kept."""
    if (percent is None) == (width is None):
        return Verdict(False, "image_scaled_from needs exactly one of `percent` and `width`")
    return judge_images(state, [path, reference], f"{reference} scaled at {path}",
                        lambda img, ref: check_scaled(img, ref, percent, width), platform)


def check_format(img: Image.Image | None, fmt: str) -> Verdict:
    """The file decodes as an image of format `fmt` (Pillow's name: PNG, JPEG, GIF, ...), not merely named so."""
    found = "no readable image" if img is None else f"a {img.format} image"
    return Verdict.check(img is not None and (img.format or "").upper() == fmt.upper(), f"a {fmt.upper()} image",
                         found)


@evaluator("image_format_is")
def image_format_is(state: FinalState, path: str, format: str, platform: str | None = None) -> Verdict:
    return judge_images(state, [path], f"a {format.upper()} image at {path}",
                        lambda img: check_format(img, format), platform)


def check_transformed(img: Image.Image | None, ref: Image.Image | None, transform: str,
                      max_difference: float = 12.0) -> Verdict:
    """`img` looks like `ref` after `transform` (one of TRANSFORMS): the mean difference from the expected image
    is at most `max_difference` and clearly less than from the untransformed reference (so an untouched copy
    fails)."""
    want = f"the reference {TRANSFORM_WORDS[transform]}"
    if img is None or ref is None:
        return Verdict.check(False, want, "no readable image" if img is None else "no readable reference")
    ref = ref.convert("RGB")
    expected = TRANSFORMS[transform](ref)
    if img.size != expected.size:
        return Verdict.check(False, f"{want} ({expected.width}×{expected.height})", f"{img.width}×{img.height}")
    to_expected = mean_difference(img, expected)
    to_original = mean_difference(img, ref) if transform != "identity" else float("inf")
    ok = to_expected <= float(max_difference) and to_expected < to_original / 2
    return Verdict.check(ok, f"{want} (mean difference ≤ {float(max_difference):g})",
                         f"difference {to_expected:.1f} from it" + ("" if transform == "identity" else
                                                                    f", {to_original:.1f} from the reference as it was"))


@evaluator("image_transformed_from")
def image_transformed_from(state: FinalState, path: str, reference: str, transform: str,
                           max_difference: float = 12.0, platform: str | None = None) -> Verdict:
    """`path` is `reference` flipped / rotated / inverted / made grayscale (see TRANSFORMS)."""
    if transform not in TRANSFORMS:
        return Verdict(False, f"unknown transform {transform!r} (use one of {sorted(TRANSFORMS)})")
    return judge_images(state, [path, reference], f"{reference} {TRANSFORM_WORDS[transform]} at {path}",
                        lambda img, ref: check_transformed(img, ref, transform, float(max_difference)), platform)


def check_grayscale(img: Image.Image | None, tolerance: int = 6) -> Verdict:
    """Every pixel of the image is gray (R, G and B within `tolerance` of each other)."""
    if img is None:
        return Verdict.check(False, "a grayscale image", "no readable image")
    if img.mode in ("L", "LA", "1", "I", "I;16"):
        return Verdict.check(True, "a grayscale image", f"mode {img.mode}")
    r, g, b = img.convert("RGB").split()
    spread = max(ImageChops.difference(r, g).getextrema()[1], ImageChops.difference(g, b).getextrema()[1],
                 ImageChops.difference(r, b).getextrema()[1])
    return Verdict.check(spread <= tolerance, "a grayscale image (R = G = B)",
                         f"colour pixels (channels differ by up to {spread})")


@evaluator("image_is_grayscale")
def image_is_grayscale(state: FinalState, path: str, platform: str | None = None) -> Verdict:
    return judge_images(state, [path], f"a grayscale image at {path}", check_grayscale, platform)


def hex_rgb(color: str) -> tuple[int, int, int]:
    c = color.lstrip("#")
    return int(c[0:2], 16), int(c[2:4], 16), int(c[4:6], 16)


def check_border(img: Image.Image | None, ref: Image.Image | None, width: int, color: str,
                 tolerance: int = 30) -> Verdict:
    """`img` is `ref` framed by a border `width` pixels wide of `color`: both sides grew by 2 × `width` and the
    middle of every border strip has the colour."""
    if img is None or ref is None:
        return Verdict.check(False, f"a {width}px {color} border", "no readable image")
    w, h = ref.width + 2 * int(width), ref.height + 2 * int(width)
    if img.size != (w, h):
        return Verdict.check(False, f"{w}×{h} (the picture with a {width}px border)", f"{img.width}×{img.height}")
    rgb, half = img.convert("RGB"), int(width) // 2
    points = [(w // 2, half), (w // 2, h - 1 - half), (half, h // 2), (w - 1 - half, h // 2)]
    want = hex_rgb(color)
    seen = [rgb.getpixel(p) for p in points]
    ok = all(all(abs(a - b) <= tolerance for a, b in zip(px, want)) for px in seen)
    return Verdict.check(ok, f"a {width}px border of {color}", "border colours " +
                         ", ".join("#%02x%02x%02x" % px for px in seen))


@evaluator("image_has_border")
def image_has_border(state: FinalState, path: str, reference: str, width: int, color: str,
                     platform: str | None = None) -> Verdict:
    return judge_images(state, [path, reference], f"{reference} with a {width}px {color} border at {path}",
                        lambda img, ref: check_border(img, ref, int(width), color), platform)


def check_side_by_side(img: Image.Image | None, left: Image.Image | None, right: Image.Image | None) -> Verdict:
    """`img` shows `left` and `right` next to each other (left first), each at its own size."""
    if img is None or left is None or right is None:
        return Verdict.check(False, "the two pictures side by side", "no readable image")
    w, h = left.width + right.width, max(left.height, right.height)
    if img.size != (w, h):
        return Verdict.check(False, f"{w}×{h} (both pictures side by side)", f"{img.width}×{img.height}")
    a = mean_difference(img.crop((0, 0, left.width, left.height)), left)
    b = mean_difference(img.crop((left.width, 0, w, right.height)), right)
    return Verdict.check(a <= 12 and b <= 12, "the left and right picture in their halves",
                         f"differences {a:.1f} (left) and {b:.1f} (right)")


@evaluator("image_side_by_side")
def image_side_by_side(state: FinalState, path: str, left: str, right: str, platform: str | None = None) -> Verdict:
    return judge_images(state, [path, left, right], f"{left} and {right} side by side at {path}",
                        check_side_by_side, platform)


# The IJG (libjpeg) standard luminance quantization table, which libjpeg scales by the quality setting; GIMP,
# ImageMagick and Pillow all write JPEGs with it unless told otherwise.
IJG_LUMINANCE = [16, 11, 10, 16, 24, 40, 51, 61, 12, 12, 14, 19, 26, 58, 60, 55, 14, 13, 16, 24, 40, 57, 69, 56,
                 14, 17, 22, 29, 51, 87, 80, 62, 18, 22, 37, 56, 68, 109, 103, 77, 24, 35, 55, 64, 81, 104, 113, 92,
                 49, 64, 78, 87, 103, 121, 120, 101, 72, 92, 95, 98, 112, 100, 103, 99]


def ijg_table(quality: int) -> list[int]:
    """The luminance table libjpeg's jpeg_set_quality(`quality`, force_baseline) writes."""
    q = min(max(int(quality), 1), 100)
    scale = 5000 // q if q < 50 else 200 - 2 * q
    return [min(max((v * scale + 50) // 100, 1), 255) for v in IJG_LUMINANCE]


def estimate_jpeg_quality(img: Image.Image) -> tuple[int, int] | None:
    """(quality, distance): the libjpeg quality setting whose luminance table is closest to the file's (distance 0
    for a file written with the standard tables), or None when the image is no JPEG. Values are compared sorted,
    so the order the tables are stored in (zigzag or natural) does not matter."""
    tables = getattr(img, "quantization", None)
    if (img.format or "").upper() != "JPEG" or not tables:
        return None
    table = sorted(tables[min(tables)])
    return min(((q, sum(abs(a - b) for a, b in zip(table, sorted(ijg_table(q))))) for q in range(1, 101)),
               key=lambda qd: (qd[1], -qd[0]))


def quality_words(minimum: int, maximum: int) -> str:
    return f"a JPEG of quality {minimum}" if minimum == maximum else f"a JPEG of quality {minimum}–{maximum}"


def check_jpeg_quality(img: Image.Image | None, minimum: int, maximum: int) -> Verdict:
    """The file is a real JPEG saved at a quality setting between `minimum` and `maximum` (estimated from its
    quantization tables, as `identify -format %Q` does)."""
    want = quality_words(minimum, maximum)
    if img is None:
        return Verdict.check(False, want, "no readable image")
    estimate = estimate_jpeg_quality(img)
    if estimate is None:
        return Verdict.check(False, want, f"a {img.format} image")
    q, distance = estimate
    approx = "" if distance == 0 else f" (non-standard tables, nearest standard quality, off by {distance})"
    return Verdict.check(int(minimum) <= q <= int(maximum) and distance <= 64, want, f"quality {q}{approx}")


@evaluator("image_jpeg_quality")
def image_jpeg_quality(state: FinalState, path: str, minimum: int, maximum: int,
                       platform: str | None = None) -> Verdict:
    """`path` is a JPEG (by its bytes, not its name) saved at a quality between `minimum` and `maximum`."""
    return judge_images(state, [path], f"{quality_words(int(minimum), int(maximum))} at {path}",
                        lambda img: check_jpeg_quality(img, int(minimum), int(maximum)), platform)
