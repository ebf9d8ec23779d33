"""Checks of media files and of what the media player leaves behind: playlists, encoded audio, snapshots."""

from __future__ import annotations

import io
import posixpath
import re
import shlex
import xml.etree.ElementTree as ET
from urllib.parse import unquote, urlparse

from PIL import Image, ImageStat

from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.state import FinalState, judge_file

MP3_BITRATES = (0, 32, 40, 48, 56, 64, 80, 96, 112, 128, 160, 192, 224, 256, 320)  # MPEG-1 layer III, kbit/s
MP3_RATES = (44100, 48000, 32000)


def playlist_entries(data: bytes) -> list[str]:
    """The local file paths of an XSPF or M3U/M3U8 playlist, in order (file:// URLs decoded)."""
    text = data.decode("utf-8", errors="replace").lstrip("\ufeff")
    if text.lstrip().startswith("<"):
        root = ET.fromstring(text)
        raw = [el.text or "" for el in root.iter() if el.tag.rsplit("}", 1)[-1] == "location"]
    else:
        raw = [line.strip() for line in text.splitlines() if line.strip() and not line.startswith("#")]
    return [unquote(urlparse(r).path) if r.startswith("file:") else r for r in raw]


def check_playlist(data: bytes, expected: list[str]) -> Verdict:
    """The playlist lists exactly the files `expected` (by base name), in this order."""
    try:
        entries = playlist_entries(data)
    except ET.ParseError as exc:
        return Verdict.check(False, f"a playlist of {expected}", f"unreadable XSPF ({exc})")
    got = [posixpath.basename(e) for e in entries]
    want = [posixpath.basename(e) for e in expected]
    return Verdict.check(got == want, f"a playlist of {want} in this order", repr(got))


@evaluator("playlist_is")
def playlist_is(state: FinalState, path: str, entries: list[str], platform: str | None = None) -> Verdict:
    return judge_file(state, path, f"a playlist at {path}", bytes, lambda data: check_playlist(data, entries),
                      platform)


def mp3_seconds(data: bytes) -> float | None:
    """The duration of an MPEG-1 layer III stream in seconds, by walking its frames; None if it is not one."""
    pos = 0
    if data[:3] == b"ID3" and len(data) >= 10:  # skip an ID3v2 tag (syncsafe size)
        pos = 10 + ((data[6] & 0x7F) << 21 | (data[7] & 0x7F) << 14 | (data[8] & 0x7F) << 7 | (data[9] & 0x7F))
    frames, seconds = 0, 0.0
    while pos + 4 <= len(data):
        b1, b2 = data[pos + 1], data[pos + 2]
        if data[pos] != 0xFF or (b1 & 0xFE) != 0xFA:  # sync, MPEG-1, layer III
            if frames:
                break
            pos += 1
            continue
        bitrate_i, rate_i = b2 >> 4, (b2 >> 2) & 3
        if bitrate_i in (0, 15) or rate_i == 3:
            pos += 1
            continue
        rate = MP3_RATES[rate_i]
        pos += 144000 * MP3_BITRATES[bitrate_i] // rate + ((b2 >> 1) & 1)
        frames, seconds = frames + 1, seconds + 1152 / rate
    return seconds if frames >= 3 else None


def check_mp3(data: bytes, min_seconds: float) -> Verdict:
    """`data` is an MP3 (MPEG-1 layer III) stream at least `min_seconds` long."""
    seconds = mp3_seconds(data)
    found = "not an MP3 stream" + (f" (starts {data[:4]!r})" if data else "") if seconds is None \
        else f"an MP3 of {seconds:.1f} s"
    return Verdict.check(seconds is not None and seconds >= float(min_seconds),
                         f"an MP3 of at least {float(min_seconds):.1f} s", found)


@evaluator("audio_is_mp3")
def audio_is_mp3(state: FinalState, path: str, min_seconds: float = 1.0, platform: str | None = None) -> Verdict:
    return judge_file(state, path, f"an MP3 at {path}", bytes, lambda data: check_mp3(data, min_seconds), platform)


def hex_rgb(color: str) -> tuple[int, int, int]:
    c = color.lstrip("#")
    return int(c[0:2], 16), int(c[2:4], 16), int(c[4:6], 16)


def check_snapshot_color(data: bytes, color: str, tolerance: float = 40.0) -> Verdict:
    """The image's median colour is within `tolerance` (per channel) of `color` (#rrggbb)."""
    try:
        img = Image.open(io.BytesIO(data)).convert("RGB")
    except Exception:
        return Verdict.check(False, f"an image mostly {color}", "no readable image")
    median = tuple(int(v) for v in ImageStat.Stat(img).median)
    want = hex_rgb(color)
    ok = all(abs(a - b) <= tolerance for a, b in zip(median, want))
    return Verdict.check(ok, f"a frame mostly {color}", "median colour #%02x%02x%02x" % median)


@evaluator("snapshot_taken")
def snapshot_taken(state: FinalState, folders: list[str], color: str, platform: str | None = None) -> Verdict:
    """A VLC snapshot (vlcsnap-*.png/jpg) in one of `folders` shows the video's frame (mostly `color`)."""
    listing = state.run("ls -1d " + " ".join(f"{shlex.quote(f.rstrip('/'))}/vlcsnap-*" for f in folders)
                        + " 2>/dev/null", platform).stdout.split("\n")
    snaps = [p for p in listing if re.search(r"vlcsnap-.*\.(png|jpe?g)$", p)]
    if not snaps:
        return Verdict.check(False, f"a VLC snapshot in {', '.join(folders)}", "none")
    last = Verdict(False, "")
    for path in snaps:
        last = check_snapshot_color(state.pull(path, platform) or b"", color)
        if last.passed:
            return Verdict(True, f"{path}: {last.reason}")
    return Verdict(False, f"{snaps[-1]}: {last.reason}")
