"""Image checks, read with Pillow on the host: brightness against a reference, size, format."""

from __future__ import annotations

import io

from PIL import Image, ImageStat

from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.state import FinalState


def _open(state: FinalState, path: str, platform: str | None) -> Image.Image | None:
    data = state.pull(path, platform)
    if data is None:
        return None
    try:
        img = Image.open(io.BytesIO(data))
        img.load()
        return img
    except Exception:
        return None


def mean_luma(img: Image.Image) -> float:
    return ImageStat.Stat(img.convert("L")).mean[0]


@evaluator("image_brighter")
def image_brighter(state: FinalState, path: str, reference: str, min_ratio: float = 1.1,
                   platform: str | None = None) -> Verdict:
    """`path` is an image whose mean brightness is at least `min_ratio` × that of `reference`."""
    img, ref = _open(state, path, platform), _open(state, reference, platform)
    if img is None or ref is None:
        missing = path if img is None else reference
        return Verdict.check(False, f"{path} brighter than {reference}", f"no readable image at {missing}")
    a, b = mean_luma(img), mean_luma(ref)
    ratio = a / b if b else float("inf")
    return Verdict.check(ratio >= float(min_ratio), f"mean brightness ≥ {float(min_ratio):.2f} × {b:.1f}",
                         f"{a:.1f} ({ratio:.2f} ×)")


@evaluator("image_size_is")
def image_size_is(state: FinalState, path: str, width: int, height: int, platform: str | None = None) -> Verdict:
    img = _open(state, path, platform)
    found = "no readable image" if img is None else f"{img.width}×{img.height}"
    return Verdict.check(img is not None and img.size == (int(width), int(height)), f"{width}×{height}", found)
