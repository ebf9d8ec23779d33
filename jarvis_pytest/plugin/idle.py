"""Observations of platforms a task does not use: an initial screenshot only (paper appendix, "device unavailable")."""

from __future__ import annotations

import io
from functools import lru_cache

from PIL import Image, ImageDraw

from jarvis_pytest.devices.base import Observation
from jarvis_pytest.devices.platforms import spec


@lru_cache(maxsize=None)
def idle_observation(platform: str) -> Observation:
    """A neutral screen telling the agent that this platform is not part of the task."""
    w, h = spec(platform).screen
    img = Image.new("RGB", (w, h), (40, 44, 52))
    draw = ImageDraw.Draw(img)
    text = f"{platform}: not used by this task (device unavailable)"
    draw.text((w // 2 - 4 * len(text), h // 2), text, fill=(200, 200, 200))
    buf = io.BytesIO()
    img.save(buf, format="PNG", compress_level=1)
    return Observation(platform=platform, screenshot_png=buf.getvalue(), width=w, height=h, available=False)
