"""The pure image checks behind the GIMP, ImageMagick and Terminal image tasks, and the picture generator they set
up with: each check passes on the file a solved task leaves and fails, saying what it expected and found, on the
untouched picture or a wrong edit (no containers)."""

from __future__ import annotations

import io
from pathlib import Path

import pytest
from PIL import Image, ImageDraw, ImageEnhance, ImageOps

from jarvis_pytest.evaluators.images import (TRANSFORM_WORDS, TRANSFORMS, check_border, check_brightened,
                                             check_brighter, check_format, check_grayscale, check_jpeg_quality,
                                             check_scaled, check_side_by_side, check_size, check_transformed,
                                             estimate_jpeg_quality, ijg_table, image_brighter, image_jpeg_quality,
                                             image_scaled_from, image_size_is, image_transformed_from, judge_images,
                                             mean_difference, open_image)
from jarvis_pytest.errors import ConfigError
from jarvis_pytest.generators import generate

COLORS = ["#d62828", "#003f88", "#2a9d8f", "#f4a261"]


def picture(width: int = 300, height: int = 200, **kw) -> Image.Image:
    return open_image(generate("quadrant_image", {"width": width, "height": height, "colors": COLORS, **kw}))


def encode(img: Image.Image, fmt: str, **kw) -> Image.Image:
    buf = io.BytesIO()
    img.save(buf, fmt, **kw)
    return open_image(buf.getvalue())


class FakeState:
    """The part of FinalState the wrappers use: files by path (None = missing) and the set-up copies of the
    template's `baseline` paths."""

    def __init__(self, files: dict[str, bytes], baselines: dict[str, bytes] | None = None):
        self.files, self.baselines = files, baselines or {}

    def pull(self, path, platform=None):
        return self.files.get(path)

    def baseline(self, path, platform=None):
        return self.baselines.get(path)


def test_generator_is_deterministic_and_its_quadrants_differ():
    a = generate("quadrant_image", {"width": 320, "height": 240, "colors": COLORS})
    assert a == generate("quadrant_image", {"width": 320, "height": 240, "colors": COLORS})
    img = open_image(a).convert("RGB")
    assert open_image(a).format == "PNG" and img.size == (320, 240)
    corners = [img.getpixel(p) for p in [(5, 5), (315, 5), (5, 235), (315, 235)]]
    assert [("#%02x%02x%02x" % c) for c in corners] == COLORS
    assert img.getpixel((80, 60)) == (255, 255, 255)  # the mark in the top-left quadrant breaks the symmetry
    jpeg = open_image(generate("quadrant_image", {"width": "64", "height": "48", "format": "jpeg", "quality": "70"}))
    assert jpeg.format == "JPEG" and jpeg.size == (64, 48) and estimate_jpeg_quality(jpeg) == (70, 0)


def test_generator_rejects_bad_arguments_clearly():
    with pytest.raises(ConfigError, match="4 colours"):
        generate("quadrant_image", {"colors": ["#000000"]})
    with pytest.raises(ConfigError):
        generate("quadrant_image", {"size": 3})


def test_every_transform_is_told_apart_from_the_untouched_picture_and_the_others():
    ref = picture()
    assert set(TRANSFORM_WORDS) == set(TRANSFORMS)
    for name, transform in TRANSFORMS.items():
        assert check_transformed(transform(ref), ref, name).passed, name
        if name != "identity":
            bad = check_transformed(ref, ref, name)
            assert not bad.passed and f"expected the reference {TRANSFORM_WORDS[name]}" in bad.reason, name
    assert not check_transformed(ImageOps.flip(ref), ref, "flip_horizontal").passed
    assert not check_transformed(TRANSFORMS["rotate_270"](ref), ref, "rotate_90").passed  # wrong direction
    assert not check_transformed(ImageOps.mirror(ref).convert("L"), ref, "grayscale").passed
    wrong_size = check_transformed(ref, ref, "rotate_90")
    assert "200×300" in wrong_size.reason and "300×200" in wrong_size.reason
    assert not check_transformed(None, ref, "invert").passed


def test_transforms_tolerate_lossy_saves_and_other_grayscale_formulas():
    ref = picture(640, 480)
    assert check_transformed(encode(ImageOps.mirror(ref), "JPEG", quality=60), ref, "flip_horizontal").passed
    assert check_transformed(encode(ref, "JPEG", quality=55), ref, "identity").passed
    r, g, b = ref.convert("RGB").split()
    average = Image.merge("RGB", [Image.blend(Image.blend(r, g, 0.5), b, 1 / 3)] * 3)  # (R + G + B) / 3
    assert check_transformed(average, ref, "grayscale").passed


def test_grayscale_needs_equal_channels_in_every_pixel():
    ref = picture()
    assert check_grayscale(ImageOps.grayscale(ref)).passed
    assert check_grayscale(ImageOps.grayscale(ref).convert("RGB")).passed  # a gray picture kept in RGB mode
    bad = check_grayscale(ref)
    assert not bad.passed and "R = G = B" in bad.reason and "colour pixels" in bad.reason
    nearly = ImageOps.grayscale(ref).convert("RGB")
    nearly.putpixel((0, 0), (200, 100, 100))  # one coloured pixel is enough to fail
    assert not check_grayscale(nearly).passed


def test_scaled_keeps_the_aspect_ratio_and_the_picture():
    ref = picture(640, 480)
    assert check_scaled(ref.resize((160, 120)), ref, percent=25).passed
    assert check_scaled(ref.resize((400, 300)), ref, width=400).passed
    assert check_scaled(ref.resize((401, 300)), ref, width=400).passed  # ±1 pixel of rounding
    squashed = check_scaled(ref.resize((400, 480)), ref, width=400)
    assert not squashed.passed and "400×300" in squashed.reason and "400×480" in squashed.reason
    assert not check_scaled(ref, ref, percent=50).passed  # the untouched picture
    assert not check_scaled(ImageOps.invert(ref).resize((320, 240)), ref, percent=50).passed  # another picture


def test_size_format_and_brightness():
    ref = picture()
    assert check_size(ref, 300, 200).passed and not check_size(ref, 200, 300).passed
    assert check_size(ref, 301, 199, tolerance=1).passed
    assert "found no readable image" in check_size(None, 1, 1).reason
    png_named_jpg = open_image(generate("quadrant_image", {"width": 50, "height": 40}))
    bad = check_format(png_named_jpg, "JPEG")
    assert not bad.passed and bad.reason == "expected a JPEG image, found a PNG image"
    assert check_format(encode(ref, "JPEG"), "jpeg").passed
    assert check_brighter(ImageEnhance.Brightness(ref).enhance(1.4), ref, 1.15).passed
    assert not check_brighter(ref, ref, 1.15).passed


def test_jpeg_quality_is_read_from_the_quantization_tables():
    ref = picture()
    for q in (10, 50, 55, 65, 75, 80, 90, 100):
        assert estimate_jpeg_quality(encode(ref, "JPEG", quality=q)) == (q, 0), q
    assert check_jpeg_quality(encode(ref, "JPEG", quality=65), 65, 65).passed
    assert check_jpeg_quality(encode(ref, "JPEG", quality=65), 60, 70).passed
    default = check_jpeg_quality(encode(ref, "JPEG", quality=90), 65, 65)  # GIMP's default slider value
    assert not default.passed and default.reason == "expected a JPEG of quality 65, found quality 90"
    png = check_jpeg_quality(encode(ref, "PNG"), 65, 65)
    assert not png.passed and "found a PNG image" in png.reason
    assert ijg_table(50)[:3] == [16, 11, 10] and ijg_table(100) == [1] * 64


def test_jpeg_quality_with_tables_that_are_not_libjpegs():
    ref = picture()
    flat = encode(ref, "JPEG", qtables=[[7] * 64])
    verdict = check_jpeg_quality(flat, 1, 100)
    assert "non-standard tables" in verdict.reason


def test_border_checks_width_colour_and_the_picture_size():
    ref = picture()
    framed = ImageOps.expand(ref, border=16, fill="#ffd700")
    assert check_border(framed, ref, 16, "#ffd700").passed
    assert check_border(encode(framed, "JPEG", quality=80), ref, 16, "#ffd700").passed
    wrong_colour = check_border(framed, ref, 16, "#000000")
    assert not wrong_colour.passed and "#ffd700" in wrong_colour.reason
    assert not check_border(ImageOps.expand(ref, border=10, fill="#ffd700"), ref, 16, "#ffd700").passed
    untouched = check_border(ref, ref, 16, "#ffd700")
    assert not untouched.passed and "332×232" in untouched.reason and "300×200" in untouched.reason


def test_side_by_side_needs_both_pictures_in_order():
    left, right = picture(320, 240), ImageOps.invert(picture(280, 240))
    both = Image.new("RGB", (600, 240))
    both.paste(left, (0, 0))
    both.paste(right, (320, 0))
    assert check_side_by_side(both, left, right).passed
    swapped = Image.new("RGB", (600, 240))
    swapped.paste(right, (0, 0))
    swapped.paste(left, (280, 0))
    assert not check_side_by_side(swapped, left, right).passed
    stacked = check_side_by_side(ImageOps.expand(left, (0, 0, 0, 240)), left, right)
    assert not stacked.passed and "600×240" in stacked.reason


def test_wrappers_name_a_missing_or_unreadable_file():
    png = generate("quadrant_image", {"width": 80, "height": 60})
    state = FakeState({"/p/a.png": png, "/p/text.png": b"not an image"})
    assert image_size_is(state, "/p/a.png", 80, 60).passed
    missing = image_size_is(state, "/p/b.png", 80, 60)
    assert not missing.passed and missing.reason.endswith("found no file at /p/b.png")
    junk = image_jpeg_quality(state, "/p/text.png", 60, 70)
    assert not junk.passed and "/p/text.png is no readable image" in junk.reason
    assert not image_transformed_from(state, "/p/a.png", "/p/a.png", "rotate_45").passed  # unknown transform
    no_ref = image_transformed_from(state, "/p/a.png", "/p/gone.png", "invert")
    assert "no file at /p/gone.png" in no_ref.reason
    assert judge_images(state, ["/p/a.png", "/p/a.png"], "two", lambda a, b: check_size(b, 80, 60)).passed


# -- hardened checks (issue 16): pixel by pixel against the original as set up, the format the name says ---------
DATA = Path(__file__).parent / "data"


def png_bytes(img: Image.Image, fmt: str = "PNG", **kw) -> bytes:
    buf = io.BytesIO()
    img.save(buf, fmt, **kw)
    return buf.getvalue()


def quadrants(width: int, height: int, tint: str) -> Image.Image:
    return open_image(generate("quadrant_image", {"width": width, "height": height,
                                                  "colors": [tint, "#003f88", "#2a9d8f", "#f4a261"]})).convert("RGB")


def gimp_file(name: str) -> Image.Image:
    return open_image((DATA / "gimp" / name).read_bytes())


def srgb_decode(c: float) -> float:
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


def srgb_encode(y: float) -> float:
    return 12.92 * y if y <= 0.0031308 else 1.055 * y ** (1 / 2.4) - 0.055


# GIMP 2.10's Colors > Desaturate modes, written after app/operations/gimpoperationdesaturate.c (per pixel, on
# R'G'B' in 0..1; Luminance in linear light), independently of the evaluator's versions of them
GIMP_DESATURATE = {
    "lightness": lambda r, g, b: (max(r, g, b) + min(r, g, b)) / 2,
    "luma": lambda r, g, b: 0.2126 * r + 0.7152 * g + 0.0722 * b,
    "average": lambda r, g, b: (r + g + b) / 3,
    "luminance": lambda r, g, b: srgb_encode(0.2126 * srgb_decode(r) + 0.7152 * srgb_decode(g)
                                            + 0.0722 * srgb_decode(b)),
    "value": lambda r, g, b: max(r, g, b),
}


def desaturate(img: Image.Image, mode: str) -> Image.Image:
    """GIMP's Desaturate `mode` of `img`, colour by colour (the generated pictures have a handful of colours)."""
    func, table = GIMP_DESATURATE[mode], {}
    out = Image.new("RGB", img.size)
    px, opx = img.load(), out.load()
    for y in range(img.height):
        for x in range(img.width):
            c = px[x, y]
            if c not in table:
                v = round(255 * func(*(v / 255 for v in c)))
                table[c] = (v, v, v)
            opx[x, y] = table[c]
    return out


@pytest.mark.parametrize("mode", sorted(GIMP_DESATURATE))
@pytest.mark.parametrize("tint", ["#e63946", "#bc6c25", "#e9c46a", "#7209b7"])
def test_every_gimp_desaturate_mode_passes_the_grayscale_checks(mode, tint):
    """The unfair case of the issue: GIMP's own Colors > Desaturate must pass, in each of its modes (Value mode
    differs from a luma by up to 120 levels on a saturated colour), for every tint the template sets up."""
    ref = quadrants(320, 240, tint)
    gray = desaturate(ref, mode)
    assert check_grayscale(gray).passed
    verdict = check_transformed(gray, ref, "grayscale")
    assert verdict.passed, verdict.reason
    assert "pixels off" in verdict.reason and "closest:" in verdict.reason


@pytest.mark.parametrize("name", ["desat_lightness", "desat_luma", "desat_average", "desat_luminance",
                                  "desat_value", "mode_gray"])
@pytest.mark.parametrize("tint", ["e63946", "7209b7"])
def test_files_gimp_itself_wrote_pass_the_grayscale_checks(name, tint):
    """The same with GIMP 2.10's own output files (tests/data/gimp, written by the device's GIMP)."""
    ref = quadrants(640, 480, f"#{tint}")
    gray = gimp_file(f"{name}_{tint}.png")
    assert check_grayscale(gray).passed
    verdict = check_transformed(gray, ref, "grayscale")
    assert verdict.passed, verdict.reason


def test_grayscale_still_rejects_what_is_no_desaturation_of_the_picture():
    ref = quadrants(640, 480, "#e63946")
    flat = check_transformed(Image.new("RGB", ref.size, (127, 127, 127)), ref, "grayscale")
    assert not flat.passed and "pixels off" in flat.reason
    banded = ImageOps.grayscale(ref).convert("RGB")
    ImageDraw.Draw(banded).rectangle((0, 0, 639, 18), fill="black")  # 4% of the picture blacked out
    verdict = check_transformed(banded, ref, "grayscale")
    assert not verdict.passed and "4.0% of pixels off" in verdict.reason
    darker = ImageOps.grayscale(ref).point(lambda v: int(v * 0.6)).convert("RGB")
    assert not check_transformed(darker, ref, "grayscale").passed
    assert not check_transformed(ImageOps.grayscale(ImageOps.mirror(ref)).convert("RGB"), ref, "grayscale").passed


def test_gimp_exports_scales_flips_and_inverts_pass():
    jpeg_ref = quadrants(720, 540, "#bc4749")
    export = gimp_file("export_q50.jpg")
    assert check_jpeg_quality(export, 50, 50).passed
    assert check_transformed(export, jpeg_ref, "identity").passed
    scale_ref = quadrants(960, 720, "#9b2226")
    for interpolation in ("cubic", "nohalo", "lohalo"):
        verdict = check_scaled(gimp_file(f"scale_320_{interpolation}.png"), scale_ref, width=320)
        assert verdict.passed, (interpolation, verdict.reason)
    ref = quadrants(640, 480, "#ffbe0b")
    assert check_transformed(gimp_file("flip.png"), ref, "flip_horizontal").passed
    assert check_transformed(gimp_file("invert.png"), ref, "invert").passed


def test_a_few_percent_of_the_picture_wrong_fails_though_the_mean_is_small():
    """The mean difference alone let these through (a band, an erased mark, a blur): the share of pixels off
    does not, while JPEG at quality 50 stays far inside it."""
    ref = quadrants(720, 540, "#bc4749")
    assert check_transformed(encode(ref, "JPEG", quality=50), ref, "identity").passed
    band = ref.copy()
    ImageDraw.Draw(band).rectangle((0, 0, 719, 20), fill="black")
    mark_gone = ref.copy()
    ImageDraw.Draw(mark_gone).ellipse((180 - 54, 135 - 54, 180 + 54, 135 + 54), fill="#bc4749")
    blurred = ref.resize((72, 54)).resize((720, 540))
    for wrong in (band, mark_gone, blurred):
        verdict = check_transformed(encode(wrong, "JPEG", quality=80), ref, "identity")
        assert not verdict.passed and "% of pixels off" in verdict.reason, verdict.reason
        assert mean_difference(wrong, ref) < 12  # what the old check alone looked at
    flipped_band = ImageOps.mirror(band)
    assert not check_transformed(flipped_band, ref, "flip_horizontal").passed
    assert not check_scaled(band.resize((360, 270)), ref, percent=50).passed


def test_border_needs_the_picture_itself_inside():
    """Issue 16's cheap state: a solid rectangle of the border colour, the right size, no picture."""
    ref = quadrants(500, 360, "#5e60ce")
    solid = check_border(Image.new("RGB", (548, 408), "#ffd700"), ref, 24, "#ffd700")
    assert not solid.passed and "inside mean difference" in solid.reason
    framed = ImageOps.expand(ref, border=24, fill="#ffd700")
    assert check_border(framed, ref, 24, "#ffd700").passed
    stretched = ImageOps.expand(ref.resize((548, 408)).crop((24, 24, 524, 384)), border=24, fill="#ffd700")
    assert not check_border(stretched, ref, 24, "#ffd700").passed
    half = framed.copy()
    half.paste((255, 255, 255), (524, 0, 548, 408))  # the right-hand strip of the frame missing
    verdict = check_border(half, ref, 24, "#ffd700")
    assert not verdict.passed and "of the border another colour" in verdict.reason


def test_side_by_side_needs_each_picture_pixel_by_pixel():
    left, right = quadrants(320, 240, "#ef476f"), ImageOps.invert(quadrants(280, 240, "#073b4c"))
    both = Image.new("RGB", (600, 240))
    both.paste(left, (0, 0))
    both.paste(right, (320, 0))
    assert check_side_by_side(both, left, right).passed
    blank_right = both.copy()
    blank_right.paste((255, 255, 255), (320, 0, 600, 240))
    assert not check_side_by_side(blank_right, left, right).passed
    dented = both.copy()
    ImageDraw.Draw(dented).rectangle((330, 0, 600, 10), fill="black")  # 4.7% of the right picture
    assert not check_side_by_side(dented, left, right).passed


def test_brightness_is_checked_at_the_asked_percentage():
    """Issue 16: an 8×8 white image passed (mean brightness ≥ 1.15× only). Now the size, every pixel and the asked
    percentage (± 3 points) are checked — and ImageMagick's own results pass, in HSL and in HSB."""
    im = DATA / "imagemagick"
    ref = open_image((im / "grad.png").read_bytes())
    for name, percent in (("mod_145.png", 145), ("mod_160.png", 160), ("hsb_145.png", 145)):
        verdict = check_brightened(open_image((im / name).read_bytes()), ref, percent)
        assert verdict.passed, (name, verdict.reason)
    white = check_brightened(Image.new("RGB", (8, 8), "white"), ref, 145)
    assert not white.passed and "640×480" in white.reason and "8×8" in white.reason
    too_much = check_brightened(open_image((im / "mod_160.png").read_bytes()), ref, 130)
    assert not too_much.passed and "brightness 161% of the original" in too_much.reason
    saturated = check_brightened(open_image((im / "sat_145.png").read_bytes()), ref, 145)
    assert not saturated.passed and "mean difference" in saturated.reason
    assert not check_brightened(ref, ref, 145).passed
    assert check_brightened(ImageEnhance.Brightness(ref).enhance(1.45), ref, 145).passed  # RGB × 1.45 (HSB)


def test_wrappers_read_originals_as_set_up_and_want_them_kept():
    """The comparison uses the set-up copy (`baseline`): writing the expected result over the original no longer
    moves the goalposts, and deleting or overwriting the original fails."""
    ref = quadrants(200, 150, "#7209b7")
    a = png_bytes(ref)
    stand_in = Image.linear_gradient("L").rotate(90).resize((200, 150)).convert("RGB")  # dark to light, left to right
    swapped = FakeState({"/p/out.png": png_bytes(stand_in), "/p/in.png": png_bytes(ImageOps.mirror(stand_in))},
                        {"/p/in.png": a})
    verdict = image_transformed_from(swapped, "/p/out.png", "/p/in.png", "flip_horizontal")
    assert not verdict.passed and "the original /p/in.png changed" in verdict.reason
    no_baseline = FakeState(dict(swapped.files))  # a fed input: no set-up copy, the file as it is now is used
    assert image_transformed_from(no_baseline, "/p/out.png", "/p/in.png", "flip_horizontal").passed
    good = FakeState({"/p/out.png": png_bytes(ImageOps.mirror(ref)), "/p/in.png": a}, {"/p/in.png": a})
    assert image_transformed_from(good, "/p/out.png", "/p/in.png", "flip_horizontal").passed
    resaved = FakeState({"/p/out.png": png_bytes(ImageOps.mirror(ref)), "/p/in.png": png_bytes(ref, optimize=True)},
                        {"/p/in.png": a})  # the same pixels saved again: kept
    assert image_transformed_from(resaved, "/p/out.png", "/p/in.png", "flip_horizontal").passed
    deleted = FakeState({"/p/out.png": png_bytes(ImageOps.mirror(ref))}, {"/p/in.png": a})
    verdict = image_transformed_from(deleted, "/p/out.png", "/p/in.png", "flip_horizontal")
    assert not verdict.passed and "the original /p/in.png deleted" in verdict.reason
    small = png_bytes(ref.resize((100, 75)))
    scaled_over = FakeState({"/p/out.png": small, "/p/in.png": small}, {"/p/in.png": a})
    assert not image_scaled_from(scaled_over, "/p/out.png", "/p/in.png", percent=50).passed


def test_the_output_must_be_in_the_format_its_name_says():
    ref = quadrants(200, 150, "#7209b7")
    a = png_bytes(ref)
    jpeg_as_png = FakeState({"/p/out.png": png_bytes(ImageOps.mirror(ref), "JPEG", quality=95), "/p/in.png": a},
                            {"/p/in.png": a})
    verdict = image_transformed_from(jpeg_as_png, "/p/out.png", "/p/in.png", "flip_horizontal")
    assert not verdict.passed and "JPEG data in /p/out.png, whose name says PNG" in verdict.reason
    as_jpeg = FakeState({"/p/out.jpeg": png_bytes(ImageOps.mirror(ref), "JPEG", quality=95), "/p/in.png": a},
                        {"/p/in.png": a})
    assert image_transformed_from(as_jpeg, "/p/out.jpeg", "/p/in.png", "flip_horizontal").passed
    odd_name = FakeState({"/p/out.img": png_bytes(ImageOps.mirror(ref)), "/p/in.png": a}, {"/p/in.png": a})
    assert image_transformed_from(odd_name, "/p/out.img", "/p/in.png", "flip_horizontal").passed  # no format named


def test_brighter_wrapper_checks_the_percentage_and_keeps_the_old_form():
    ref = open_image((DATA / "imagemagick" / "grad.png").read_bytes())
    a = (DATA / "imagemagick" / "grad.png").read_bytes()
    white = FakeState({"/p/b.png": png_bytes(Image.new("RGB", (8, 8), "white")), "/p/a.png": a}, {"/p/a.png": a})
    assert image_brighter(white, "/p/b.png", "/p/a.png", min_ratio=1.15).passed  # the old, weak form (old datasets)
    assert not image_brighter(white, "/p/b.png", "/p/a.png", percent=145).passed
    good = FakeState({"/p/b.png": (DATA / "imagemagick" / "mod_145.png").read_bytes(), "/p/a.png": a},
                     {"/p/a.png": a})
    assert image_brighter(good, "/p/b.png", "/p/a.png", percent=145).passed
    assert not image_brighter(good, "/p/b.png", "/p/a.png", percent=130).passed
    assert ref.size == (640, 480)


def test_a_border_in_a_png_must_hold_the_picture_pixel_for_pixel():
    """In a lossless file the inside must be the picture exactly: stretched under a 10px border, the picture moves
    by a few pixels at its edges (0.6 % of its pixels) — within the lossy tolerances, not a copy."""
    ref = quadrants(500, 360, "#5e60ce")
    framed = open_image(png_bytes(ImageOps.expand(ref, border=10, fill="#000000")))
    assert check_border(framed, ref, 10, "#000000").passed
    stretched = ImageOps.expand(ref.resize((520, 380)).crop((10, 10, 510, 370)), border=10, fill="#000000")
    verdict = check_border(open_image(png_bytes(stretched)), ref, 10, "#000000")
    assert not verdict.passed and "a lossless copy" in verdict.reason
    assert check_border(stretched, ref, 10, "#000000").passed  # what the lossy tolerances alone would accept
    assert check_border(encode(ImageOps.expand(ref, border=10, fill="#000000"), "JPEG", quality=90), ref, 10,
                        "#000000").passed
    left, right = quadrants(320, 240, "#ef476f"), quadrants(280, 240, "#073b4c")
    both = Image.new("RGB", (600, 240))
    both.paste(left, (0, 0))
    both.paste(right.resize((290, 250)).crop((5, 5, 285, 245)), (320, 0))
    assert not check_side_by_side(open_image(png_bytes(both)), left, right).passed
    both.paste(right, (320, 0))
    assert check_side_by_side(open_image(png_bytes(both)), left, right).passed
