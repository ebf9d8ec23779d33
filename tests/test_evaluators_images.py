"""The pure image checks behind the GIMP, ImageMagick and Terminal image tasks, and the picture generator they set
up with: each check passes on the file a solved task leaves and fails, saying what it expected and found, on the
untouched picture or a wrong edit (no containers)."""

from __future__ import annotations

import io

import pytest
from PIL import Image, ImageEnhance, ImageOps

from jarvis_pytest.evaluators.images import (TRANSFORM_WORDS, TRANSFORMS, check_border, check_brighter, check_format,
                                             check_grayscale, check_jpeg_quality, check_scaled, check_side_by_side,
                                             check_size, check_transformed, estimate_jpeg_quality, ijg_table,
                                             image_jpeg_quality, image_size_is, image_transformed_from,
                                             judge_images, open_image)
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
    """The part of FinalState the wrappers use: files by path (None = missing)."""

    def __init__(self, files: dict[str, bytes]):
        self.files = files

    def pull(self, path, platform=None):
        return self.files.get(path)


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
    # GIMP's grayscale weighs channels in linear light, and its Desaturate modes (lightness, average, ...) differ
    # from Pillow's luma by up to ~20 on the generated pictures: the GIMP template allows 24; a plain average passes
    r, g, b = ref.convert("RGB").split()
    average = Image.merge("RGB", [Image.blend(Image.blend(r, g, 0.5), b, 1 / 3)] * 3)  # (R + G + B) / 3
    assert check_transformed(average, ref, "grayscale", max_difference=20).passed


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
