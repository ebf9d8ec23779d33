"""Devices a task does not use are shown by their real initial screen (cached from the first device of the image
that booted here), marked unavailable; a platform never booted here shows a neutral screen."""

from __future__ import annotations

import io

from PIL import Image

from jarvis_pytest.harness import idle


def _png(size, colour) -> bytes:
    buf = io.BytesIO()
    Image.new("RGB", size, colour).save(buf, format="PNG")
    return buf.getvalue()


def test_initial_screen_is_remembered_per_image(tmp_path, monkeypatch):
    monkeypatch.setattr(idle, "CACHE", tmp_path)
    idle._cached.cache_clear()
    neutral = idle.idle_observation("android")
    assert not neutral.available and (neutral.width, neutral.height) == (1080, 2400)
    assert not idle.known("windows", "sha256:1")
    idle.remember("windows", "sha256:1", _png((1920, 1080), (1, 2, 3)))
    assert idle.known("windows", "sha256:1") and not idle.known("windows", "sha256:2")
    obs = idle.idle_observation("windows")
    assert not obs.available and obs.screenshot_png == _png((1920, 1080), (1, 2, 3))
    idle.remember("windows", "sha256:2", _png((1920, 1080), (9, 9, 9)))  # a new image: a new initial screen
    assert idle.idle_observation("windows").screenshot_png == _png((1920, 1080), (9, 9, 9))
