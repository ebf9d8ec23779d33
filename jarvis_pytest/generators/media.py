"""Generators of media files: audio tones as WAV (stdlib `wave`), deterministic from their arguments."""

from __future__ import annotations

import io
import math
import struct
import wave

from jarvis_pytest.generators.registry import generator


@generator("wav_tone")
def wav_tone(seconds: float = 2.0, frequency: float = 440.0, rate: int = 22050, volume: float = 0.3) -> bytes:
    """A mono 16-bit WAV of a sine tone of `frequency` Hz lasting `seconds`."""
    if not 0 < float(seconds) <= 60 or not 20 <= float(frequency) <= 20000:
        raise TypeError("`seconds` must be in (0, 60] and `frequency` in [20, 20000]")
    n = int(float(seconds) * rate)
    amp = int(32767 * float(volume))
    frames = b"".join(struct.pack("<h", int(amp * math.sin(2 * math.pi * float(frequency) * i / rate)))
                      for i in range(n))
    buf = io.BytesIO()
    with wave.open(buf, "wb") as w:
        w.setnchannels(1)
        w.setsampwidth(2)
        w.setframerate(rate)
        w.writeframes(frames)
    return buf.getvalue()
