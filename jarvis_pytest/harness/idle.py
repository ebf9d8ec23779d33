"""Observations of platforms a task does not use (paper appendix): the device's initial screenshot, marked
unavailable; acting on it is answered "device unavailable" by the step loop.

The initial screenshot of each platform is taken from the first device of that platform's image that boots on
this machine, before any set-up, and kept in a cache keyed by the image id (`~/.cache/jarvis/idle/`), so every
later task shows the real initial desktop of the devices it does not use. A platform that has never booted here
(Android without an emulator) shows a neutral screen saying it is unavailable.
"""

from __future__ import annotations

import io
import json
import os
from functools import lru_cache
from pathlib import Path

from PIL import Image, ImageDraw

from jarvis_pytest.devices.base import Observation
from jarvis_pytest.devices.platforms import spec

CACHE = Path(os.environ.get("JARVIS_IDLE_CACHE", Path.home() / ".cache" / "jarvis" / "idle"))


def remember(platform: str, image_id: str, screenshot: bytes) -> None:
    """Keep `screenshot` as the initial screen of `platform` for its image `image_id` (atomic; first wins)."""
    CACHE.mkdir(parents=True, exist_ok=True)
    meta = CACHE / f"{platform}.json"
    tmp = CACHE / f".{platform}.{os.getpid()}.png"
    tmp.write_bytes(screenshot)
    os.replace(tmp, CACHE / f"{platform}.png")
    meta.write_text(json.dumps({"image_id": image_id}))
    _cached.cache_clear()


def known(platform: str, image_id: str) -> bool:
    """Whether the cache holds the initial screen of `platform` for this image."""
    try:
        return json.loads((CACHE / f"{platform}.json").read_text()).get("image_id") == image_id
    except (OSError, ValueError):
        return False


@lru_cache(maxsize=None)
def _cached(platform: str) -> bytes | None:
    try:
        return (CACHE / f"{platform}.png").read_bytes()
    except OSError:
        return None


@lru_cache(maxsize=None)
def _neutral(platform: str) -> bytes:
    w, h = spec(platform).screen
    img = Image.new("RGB", (w, h), (40, 44, 52))
    draw = ImageDraw.Draw(img)
    text = f"{spec(platform).device_name}: not used by this task (device unavailable)"
    draw.text((w // 2 - 3 * len(text), h // 2), text, fill=(200, 200, 200))
    buf = io.BytesIO()
    img.save(buf, format="PNG", compress_level=1)
    return buf.getvalue()


def idle_observation(platform: str) -> Observation:
    """The initial screenshot of `platform` (or a neutral screen), marked unavailable."""
    png = _cached(platform) or _neutral(platform)
    with Image.open(io.BytesIO(png)) as img:
        w, h = img.size
    return Observation(platform=platform, screenshot_png=png, width=w, height=h, available=False)
