"""Generators of media files, deterministic to the byte from their arguments: audio tones as WAV (stdlib `wave`),
still videos as MP4 (PyAV: FFmpeg's MPEG-4 Part 2 encoder and MP4 muxer in bit-exact mode, so neither the time of
making nor the library's version string is written into the file)."""

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


@generator("mp4_still_video")
def mp4_still_video(color: str, seconds: float = 8.0, fps: int = 10, width: int = 320, height: int = 240,
                    mark: list | None = None) -> bytes:
    """An MP4 (MPEG-4 video, 800 kb/s) of `seconds` of one frame: `color` with a white rectangle `mark`
    ([x0, y0, x1, y1], default [20, 20, 90, 90]). Made here, not by VLC on the device: VLC stamps the file and its
    frames with the clock."""
    import av
    from PIL import Image, ImageColor, ImageDraw

    if not 0 < float(seconds) <= 60 or not 1 <= int(fps) <= 60:
        raise TypeError("`seconds` must be in (0, 60] and `fps` in [1, 60]")
    image = Image.new("RGB", (int(width), int(height)), ImageColor.getrgb(str(color)))
    ImageDraw.Draw(image).rectangle(list(mark or [20, 20, 90, 90]), fill="white")
    buf = io.BytesIO()
    with av.open(buf, mode="w", format="mp4", options={"fflags": "+bitexact"}) as out:
        stream = out.add_stream("mpeg4", rate=int(fps))
        stream.width, stream.height, stream.pix_fmt, stream.bit_rate = int(width), int(height), "yuv420p", 800_000
        stream.codec_context.flags |= av.codec.context.Flags.bitexact
        for i in range(int(float(seconds) * int(fps))):
            frame = av.VideoFrame.from_image(image)
            frame.pts = i
            out.mux(stream.encode(frame))
        out.mux(stream.encode())
    return buf.getvalue()
