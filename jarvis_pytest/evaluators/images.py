"""Image checks, read with Pillow on the host: brightness, size, file format, JPEG quality, grayscale, and geometric
or colour transformations of a reference image (flips, rotations, inversion, borders, side by side).

How pictures are compared (the evaluator rules of README "Writing a template"):

- **Pixel by pixel, with stated tolerances.** An edit is compared with what the original gives under the asked
  operation, recomputed on the host: it passes when the mean difference (0–255, per channel) is at most
  `max_difference` *and* at most 1 % of the pixels are off — more than 48 outside the range of the expected
  picture within one pixel of them (see `pixel_difference`). The mean alone lets a band, an erased mark or a
  strong blur over a few percent of the picture through; the share of pixels off does not, while lossy saves
  (JPEG down to quality 50 with 4:2:0 chroma, measured ≤ 0.2 % off) and every resampling filter of GIMP's Scale
  Image (0.0 % off) stay well inside it.
- **Against the original as it was set up.** Inputs the template lists under `baseline` are read as they were
  right after set-up, and must still be there unchanged at the end (an agent that overwrites the original cannot
  move the goalposts, and damage to it is found). An input that an upstream subtask of a composed task fed has no
  baseline: it is then read as it is now, the strongest check left without an original.
- **The output's real format** must be the one its name says (`.png` holds PNG data, `.jpg` JPEG), not only its
  extension.
"""

from __future__ import annotations

import colorsys
import io
import posixpath
from typing import Callable

from PIL import Image, ImageChops, ImageFilter, ImageOps, ImageStat

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

OFF_LEVEL = 48      # a pixel is "off" when a channel lies this far outside the expected values around it
MAX_OFF = 0.01      # at most this share of the pixels may be off
RIM = 2             # pixels next to the edge between a border and the picture, left out of a border's checks
LOSSLESS = ("PNG", "GIF", "BMP", "TIFF", "PPM")
EXT_FORMATS = {".png": "PNG", ".jpg": "JPEG", ".jpeg": "JPEG", ".gif": "GIF", ".bmp": "BMP", ".tif": "TIFF",
               ".tiff": "TIFF", ".webp": "WEBP"}


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


def format_named_by(path: str) -> str | None:
    """The image format (Pillow's name) that the extension of `path` stands for, or None for another extension."""
    return EXT_FORMATS.get(posixpath.splitext(path)[1].lower())


def same_pixels(a: Image.Image, b: Image.Image) -> bool:
    """Two decodings show the same picture (same size, no channel off by more than 2: a lossless re-save)."""
    if a.size != b.size:
        return False
    return max(hi for _, hi in ImageChops.difference(flat_rgb(a), flat_rgb(b)).getextrema()) <= 2


def original_image(state: FinalState, path: str, platform: str | None = None) -> tuple[Image.Image | None, str]:
    """The input picture `path` as the task set it up, and "" — or None and the reason when it is unusable.

    With a baseline (the template lists `path` under `baseline`) the set-up copy is the reference, and the file
    must still be on the device with the same pixels: deleting or overwriting the original is damage. Without
    one (a composed task's upstream subtask fed it) the file as it is now is the reference."""
    base = state.baseline(path, platform)
    now = state.pull(path, platform)
    if base is None:
        if now is None:
            return None, f"no file at {path}"
        img = open_image(now)
        return (img, "") if img is not None else (None, f"{path} is no readable image ({len(now)} bytes)")
    ref = open_image(base)
    if ref is None:
        return None, f"{path} was no readable image when set up"
    if now is None:
        return None, f"the original {path} deleted (it was to be kept)"
    if now != base:
        img = open_image(now)
        if img is None or not same_pixels(img, ref):
            return None, f"the original {path} changed (it was to be kept as it was)"
    return ref, ""


def judge_images(state: FinalState, paths: list[str], want: str, check: Callable[..., Verdict],
                 platform: str | None = None) -> Verdict:
    """Pull and decode the output `paths[0]` and the originals `paths[1:]` and `check(output, *originals)`.

    A missing output or one that is no image fails naming it, and so does an output whose real format is not the
    one its extension names (JPEG data in a `.png`). Originals are read with `original_image`: as set up when
    they have a baseline (and then they must still be there unchanged)."""
    path = paths[0]
    data = state.pull(path, platform)
    if data is None:
        return Verdict.check(False, want, f"no file at {path}")
    img = open_image(data)
    if img is None:
        return Verdict.check(False, want, f"{path} is no readable image ({len(data)} bytes)")
    named = format_named_by(path)
    if named is not None and (img.format or "").upper() != named:
        return Verdict.check(False, want, f"{img.format} data in {path}, whose name says {named}")
    images = [img]
    for ref_path in paths[1:]:
        ref, problem = original_image(state, ref_path, platform)
        if ref is None:
            return Verdict.check(False, want, problem)
        images.append(ref)
    return check(*images)


def flat_rgb(img: Image.Image) -> Image.Image:
    """The picture in RGB, transparent parts laid on white (as a viewer shows them)."""
    if img.mode in ("RGBA", "LA", "PA") or (img.mode == "P" and "transparency" in img.info):
        rgba = img.convert("RGBA")
        out = Image.new("RGB", rgba.size, (255, 255, 255))
        out.paste(rgba, mask=rgba.getchannel("A"))
        return out
    return img.convert("RGB")


def mean_luma(img: Image.Image) -> float:
    return ImageStat.Stat(flat_rgb(img).convert("L")).mean[0]


def mean_difference(a: Image.Image, b: Image.Image) -> float:
    """Mean absolute per-channel difference (0–255) of two images, `b` scaled to `a`'s size."""
    a, b = flat_rgb(a), flat_rgb(b)
    if a.size != b.size:
        b = b.resize(a.size)
    return sum(ImageStat.Stat(ImageChops.difference(a, b)).mean) / 3


def pixel_difference(img: Image.Image, expected: Image.Image, level: int = OFF_LEVEL,
                     near: bool = True) -> tuple[float, float]:
    """(mean absolute per-channel difference 0–255, share of pixels off) of two pictures of one size. A pixel is
    off when a channel lies more than `level` outside the range the expected picture has within one pixel of it
    (`near`; else: differs by more than `level` from the expected pixel itself): an edge that a lossy save or a
    resampling filter smears by a pixel is not off, a changed area is."""
    a, b = flat_rgb(img), flat_rgb(expected)
    lo, hi = (b.filter(ImageFilter.MinFilter(3)), b.filter(ImageFilter.MaxFilter(3))) if near else (b, b)
    outside = ImageChops.lighter(ImageChops.subtract(lo, a), ImageChops.subtract(a, hi))
    r, g, b_ = outside.split()
    worst = ImageChops.lighter(ImageChops.lighter(r, g), b_)
    off = worst.point(lambda v: 255 if v > level else 0).histogram()[255]
    return sum(ImageStat.Stat(ImageChops.difference(a, b)).mean) / 3, off / (a.width * a.height)


def match_words(max_difference: float, max_off: float = MAX_OFF, level: int = OFF_LEVEL) -> str:
    return f"mean difference ≤ {max_difference:g}, ≤ {max_off:.0%} of pixels off by > {level}"  # see pixel_difference


def found_words(mean: float, off: float) -> str:
    return f"mean difference {mean:.1f}, {off:.1%} of pixels off"


def matches(img: Image.Image, expected: Image.Image, max_difference: float = 12.0,
            max_off: float = MAX_OFF, level: int = OFF_LEVEL, near: bool = True) -> tuple[bool, float, float]:
    mean, off = pixel_difference(img, expected, level, near)
    return mean <= max_difference and off <= max_off, mean, off


def copy_matches(img: Image.Image, expected: Image.Image) -> tuple[bool, float, float, str]:
    """Whether `img`, a part of an output that should hold `expected` copied as it is (a border's inside, one
    half of a side-by-side), does: exactly (mean ≤ 1, ≤ 0.1 % of pixels off by > 8, pixel for pixel) when the
    output is in a lossless format — a copy shifted or stretched by a few pixels is not the picture unchanged —
    else within the lossy tolerances of `match_words` (mean ≤ 8); and the tolerances, in words."""
    if (img.format or "").upper() in LOSSLESS:
        ok, mean, off = matches(img, expected, 1.0, 0.001, 8, near=False)
        return ok, mean, off, "mean difference ≤ 1, ≤ 0.1% of pixels off by > 8: a lossless copy"
    ok, mean, off = matches(img, expected, 8.0)
    return ok, mean, off, match_words(8)


def check_brighter(img: Image.Image | None, ref: Image.Image | None, min_ratio: float = 1.1) -> Verdict:
    """The mean brightness of `img` is at least `min_ratio` × that of `ref` (the weak check of old datasets:
    templates give `percent`, see `check_brightened`)."""
    if img is None or ref is None:
        return Verdict.check(False, "an image brighter than the reference", "no readable image")
    a, b = mean_luma(img), mean_luma(ref)
    ratio = a / b if b else float("inf")
    return Verdict.check(ratio >= float(min_ratio), f"mean brightness ≥ {float(min_ratio):.2f} × {b:.1f}",
                         f"{a:.1f} ({ratio:.2f} ×)")


def _lut(func: Callable[[float, float, float], tuple[float, ...]]) -> ImageFilter.Color3DLUT:
    return ImageFilter.Color3DLUT.generate(33, func)


def brightened(ref: Image.Image, percent: float) -> dict[str, Image.Image]:
    """`ref` with its brightness set to `percent` % and hue and saturation kept, each way a careful person may
    read "brightness": HSL lightness × percent (ImageMagick's `-modulate P,100,100`, its default colour space)
    and HSB/HSV brightness × percent (`-define modulate:colorspace=HSB -modulate`, `-evaluate multiply`, which
    scales R, G and B alike)."""
    k = float(percent) / 100

    def hsl(r: float, g: float, b: float) -> tuple[float, float, float]:
        h, l, s = colorsys.rgb_to_hls(r, g, b)
        return colorsys.hls_to_rgb(h, min(1.0, l * k), s)

    rgb = flat_rgb(ref)
    return {"HSL lightness": rgb.filter(_lut(hsl)),
            "HSB brightness": rgb.point(lambda v: min(255, round(v * k)))}


def check_brightened(img: Image.Image | None, ref: Image.Image | None, percent: float,
                     tolerance: float = 3.0) -> Verdict:
    """`img` is `ref` with its brightness raised to `percent` % of the original, hue and saturation unchanged:
    same size; pixel by pixel within mean 4 (≤ 1 % of pixels off by > 24) of `ref` brightened so (HSL lightness
    or HSB brightness, see `brightened`); and its mean brightness `percent` ± `tolerance` percentage points of
    the original's (less where the brightest parts saturate at white, as the expected picture says)."""
    want = f"the picture at {float(percent):g}% brightness (± {float(tolerance):g} points), hue and saturation kept"
    if img is None or ref is None:
        return Verdict.check(False, want, "no readable image")
    if img.size != ref.size:
        return Verdict.check(False, f"{want} ({ref.width}×{ref.height})", f"{img.width}×{img.height}")
    base = mean_luma(ref) or 1.0
    found = mean_luma(img) / base * 100
    best = None
    for name, expected in brightened(ref, percent).items():
        ok, mean, off = matches(img, expected, 4.0, MAX_OFF, 24)
        target = mean_luma(expected) / base * 100
        ok = ok and abs(found - target) <= float(tolerance)
        if best is None or (ok, -mean) > (best[0], -best[2]):
            best = (ok, name, mean, off, target)
    ok, name, mean, off, target = best
    return Verdict.check(ok, f"{want}: {match_words(4, MAX_OFF, 24)} of it",
                         f"brightness {found:.0f}% of the original (the asked edit gives {target:.0f}%), "
                         f"{found_words(mean, off)} from the {name} edit")


@evaluator("image_brighter")
def image_brighter(state: FinalState, path: str, reference: str, min_ratio: float = 1.1,
                   percent: float | None = None, tolerance: float = 3.0, platform: str | None = None) -> Verdict:
    """`path` is `reference` brightened to `percent` % (± `tolerance` points; see `check_brightened`), with
    `reference` kept as it was. Without `percent` (old datasets) only: mean brightness ≥ `min_ratio` ×."""
    if percent is None:
        return judge_images(state, [path, reference], f"{path} brighter than {reference}",
                            lambda img, ref: check_brighter(img, ref, float(min_ratio)), platform)
    return judge_images(state, [path, reference], f"{reference} at {float(percent):g}% brightness at {path}",
                        lambda img, ref: check_brightened(img, ref, float(percent), float(tolerance)), platform)


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
                 width: int | None = None, max_difference: float = 12.0) -> Verdict:
    """`img` is `ref` scaled to `percent` % (or to `width` pixels wide), keeping its aspect ratio (±1 pixel), and
    shows the picture: pixel by pixel like `ref` resampled to its size (Lanczos; `match_words` tolerances)."""
    if img is None or ref is None:
        return Verdict.check(False, "a scaled copy of the picture", "no readable image")
    factor = float(percent) / 100 if percent is not None else int(width) / ref.width
    w, h = round(ref.width * factor), round(ref.height * factor)
    want = f"{w}×{h} (±1, {ref.width}×{ref.height} scaled by {factor:.3g}) showing the picture"
    if abs(img.width - w) > 1 or abs(img.height - h) > 1:
        return Verdict.check(False, want, f"{img.width}×{img.height}")
    expected = flat_rgb(ref).resize(img.size, Image.Resampling.LANCZOS)
    ok, mean, off = matches(img, expected, max_difference)
    return Verdict.check(ok, f"{want} ({match_words(max_difference)})",
                         f"{img.width}×{img.height}, {found_words(mean, off)}")


@evaluator("image_scaled_from")
def image_scaled_from(state: FinalState, path: str, reference: str, percent: float | None = None,
                      width: int | None = None, platform: str | None = None) -> Verdict:
    """`path` is `reference` scaled by `percent` % or to `width` pixels wide, aspect ratio kept; `reference` kept."""
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


def _decode(c: float) -> float:  # sRGB → linear light
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


def _encode(y: float) -> float:  # linear light → sRGB
    return 12.92 * y if y <= 0.0031308 else 1.055 * y ** (1 / 2.4) - 0.055


def grayscale_versions(ref: Image.Image) -> dict[str, Image.Image]:
    """`ref` made gray each way the applications offer (a careful person's result is one of them):

    - luminance: Rec. 709 weights in linear light, re-encoded to sRGB — GIMP's Image > Mode > Grayscale and its
      Desaturate "Luminance";
    - luma (Rec. 709): 0.2126 R' + 0.7152 G' + 0.0722 B' — GIMP's Desaturate "Luma", ImageMagick's
      `-colorspace Gray`;
    - luma (Rec. 601): 0.299 R' + 0.587 G' + 0.114 B' — Pillow, `-grayscale Rec601Luma`, LibreOffice;
    - lightness: (max + min) / 2 — GIMP's Desaturate "Lightness (HSL)";
    - average: (R + G + B) / 3 — GIMP's Desaturate "Average (HSI Intensity)";
    - value: max(R, G, B) — GIMP's Desaturate "Value (HSV)".
    """
    rgb = flat_rgb(ref)
    r, g, b = rgb.split()
    hi, lo = ImageChops.lighter(ImageChops.lighter(r, g), b), ImageChops.darker(ImageChops.darker(r, g), b)
    luminance = rgb.filter(_lut(lambda r_, g_, b_: (_encode(0.2126 * _decode(r_) + 0.7152 * _decode(g_)
                                                            + 0.0722 * _decode(b_)),) * 3)).getchannel("R")
    gray = {"luminance (GIMP's Grayscale mode)": luminance,
            "luma Rec. 709": rgb.convert("L", (0.2126, 0.7152, 0.0722, 0)),
            "luma Rec. 601": rgb.convert("L", (0.299, 0.587, 0.114, 0)),
            "lightness (HSL)": Image.blend(hi, lo, 0.5),
            "average": rgb.convert("L", (1 / 3, 1 / 3, 1 / 3, 0)),
            "value (HSV)": hi}
    return {name: im.convert("RGB") for name, im in gray.items()}


def check_transformed(img: Image.Image | None, ref: Image.Image | None, transform: str,
                      max_difference: float = 12.0) -> Verdict:
    """`img` looks like `ref` after `transform` (one of TRANSFORMS; for "grayscale" any of `grayscale_versions`):
    pixel by pixel within `match_words` of the expected picture, and clearly closer to it than to the untouched
    reference (so a copy of the original fails)."""
    want = f"the reference {TRANSFORM_WORDS[transform]}"
    if img is None or ref is None:
        return Verdict.check(False, want, "no readable image" if img is None else "no readable reference")
    ref = flat_rgb(ref)
    candidates = grayscale_versions(ref) if transform == "grayscale" else {"": TRANSFORMS[transform](ref)}
    first = next(iter(candidates.values()))
    if img.size != first.size:
        return Verdict.check(False, f"{want} ({first.width}×{first.height})", f"{img.width}×{img.height}")
    scored = [(matches(img, expected, float(max_difference)), name) for name, expected in candidates.items()]
    (ok, mean, off), name = min(scored, key=lambda s: (not s[0][0], s[0][1]))
    to_original = mean_difference(img, ref) if transform != "identity" else float("inf")
    ok = ok and mean < to_original / 2
    which = f" (closest: {name})" if len(candidates) > 1 else ""
    before = "" if transform == "identity" else f", {to_original:.1f} from the reference as it was"
    return Verdict.check(ok, f"{want} ({match_words(float(max_difference))})",
                         f"{found_words(mean, off)} from it{which}{before}")


@evaluator("image_transformed_from")
def image_transformed_from(state: FinalState, path: str, reference: str, transform: str,
                           max_difference: float = 12.0, platform: str | None = None) -> Verdict:
    """`path` is `reference` flipped / rotated / inverted / made grayscale (see TRANSFORMS), in the format its
    name says; `reference` kept as set up."""
    if transform not in TRANSFORMS:
        return Verdict(False, f"unknown transform {transform!r} (use one of {sorted(TRANSFORMS)})")
    want = (f"the picture of {reference} at {path}" if transform == "identity" else
            f"{reference} {TRANSFORM_WORDS[transform]} at {path}")
    return judge_images(state, [path, reference], want,
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
                 tolerance: int = 48) -> Verdict:
    """`img` is `ref` framed by a border `width` pixels wide of `color`: both sides grew by 2 × `width`; inside
    the frame the picture itself, unchanged (`copy_matches`: pixel for pixel in a lossless file); and ≥ 98 % of
    the border's pixels within `tolerance` of `color` in every channel. In a lossy file the `RIM` pixels on
    either side of the picture's edge are left out of both comparisons: 4:2:0 JPEG smears colour across it."""
    want = f"the picture framed by a {width}px {color} border"
    if img is None or ref is None:
        return Verdict.check(False, want, "no readable image")
    bw = int(width)
    w, h = ref.width + 2 * bw, ref.height + 2 * bw
    if img.size != (w, h):
        return Verdict.check(False, f"{w}×{h} (the picture with a {width}px border)", f"{img.width}×{img.height}")
    lossless = (img.format or "").upper() in LOSSLESS
    rgb, rim = flat_rgb(img), RIM if min(ref.size) > 4 * RIM and not lossless else 0
    inside = rgb.crop((bw + rim, bw + rim, bw + ref.width - rim, bw + ref.height - rim))
    inside.format = img.format
    inside_ok, mean, off, words = copy_matches(inside, ref.crop((rim, rim, ref.width - rim, ref.height - rim)))
    diff = ImageChops.difference(rgb, Image.new("RGB", (w, h), hex_rgb(color)))
    r, g, b = diff.split()
    wrong = ImageChops.lighter(ImageChops.lighter(r, g), b).point(lambda v: 255 if v > tolerance else 0)
    wrong.paste(0, (bw - rim, bw - rim, bw + ref.width + rim, bw + ref.height + rim))
    border_px = w * h - (ref.width + 2 * rim) * (ref.height + 2 * rim)
    bad_border = wrong.histogram()[255] / border_px if border_px else 1.0
    mask = Image.new("L", (w, h), 255)
    mask.paste(0, (bw - rim, bw - rim, bw + ref.width + rim, bw + ref.height + rim))
    median = tuple(int(v) for v in ImageStat.Stat(rgb, mask).median)
    ok = inside_ok and bad_border <= 0.02
    return Verdict.check(ok, f"{want}: inside it the picture ({words}), ≥ 98% of the border "
                         f"{color} (±{tolerance})",
                         f"inside {found_words(mean, off)}; {bad_border:.1%} of the border another colour "
                         f"(mostly {'#%02x%02x%02x' % median})")


@evaluator("image_has_border")
def image_has_border(state: FinalState, path: str, reference: str, width: int, color: str,
                     platform: str | None = None) -> Verdict:
    """`path` is `reference` unchanged inside a `width`px border of `color`; `reference` kept as set up."""
    return judge_images(state, [path, reference], f"{reference} with a {width}px {color} border at {path}",
                        lambda img, ref: check_border(img, ref, int(width), color), platform)


def check_side_by_side(img: Image.Image | None, left: Image.Image | None, right: Image.Image | None) -> Verdict:
    """`img` shows `left` and `right` next to each other (left first, top-aligned), each at its own size and pixel
    by pixel itself (`copy_matches`: exactly, in a lossless file)."""
    if img is None or left is None or right is None:
        return Verdict.check(False, "the two pictures side by side", "no readable image")
    w, h = left.width + right.width, max(left.height, right.height)
    if img.size != (w, h):
        return Verdict.check(False, f"{w}×{h} (both pictures side by side)", f"{img.width}×{img.height}")
    halves = img.crop((0, 0, left.width, left.height)), img.crop((left.width, 0, w, right.height))
    for half in halves:
        half.format = img.format
    a_ok, a_mean, a_off, words = copy_matches(halves[0], left)
    b_ok, b_mean, b_off, _ = copy_matches(halves[1], right)
    return Verdict.check(a_ok and b_ok, f"the left and right picture in their halves ({words})",
                         f"left: {found_words(a_mean, a_off)}; right: {found_words(b_mean, b_off)}")


@evaluator("image_side_by_side")
def image_side_by_side(state: FinalState, path: str, left: str, right: str, platform: str | None = None) -> Verdict:
    """`path` holds `left` and `right` side by side; both originals kept as set up."""
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
