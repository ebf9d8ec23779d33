"""Checks of media files and of what the media player leaves behind: playlists, encoded audio, snapshots.

Media are decoded and compared with their source (README "Writing a template", rule 4):

- **Audio**: an MP3 must be an MPEG audio layer III stream through and through (its frames walked on the host),
  and it is then decoded — on the device, by VLC itself (`cvlc`, the player the task is about; the host has no
  MP3 decoder and none is needed) — to 16-bit PCM at the source's sample rate and compared with the source
  recording sample by sample: duration, loudness and the correlation of the two waveforms once aligned (the
  encoder's delay is searched for). The source is the recording as it was set up (`baseline`), or, when an
  upstream subtask of a composed task fed it, the file as it is now.
- **Snapshots**: the picture VLC saved is compared pixel by pixel with the video's frame, which the template
  describes (its colour, size and the white mark drawn in it).
"""

from __future__ import annotations

import array
import io
import math
import operator
import posixpath
import re
import shlex
import sys
import uuid
import wave
import xml.etree.ElementTree as ET
from urllib.parse import unquote, urlparse

from PIL import Image, ImageDraw, ImageStat

from jarvis_pytest.evaluators.images import (found_words, match_words, matches, open_image, format_named_by,
                                             hex_rgb)
from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.state import FinalState, judge_file

MP3_BITRATES = (0, 32, 40, 48, 56, 64, 80, 96, 112, 128, 160, 192, 224, 256, 320)  # MPEG-1 layer III, kbit/s
MP3_BITRATES_LSF = (0, 8, 16, 24, 32, 40, 48, 56, 64, 80, 96, 112, 128, 144, 160)  # MPEG-2 / 2.5 layer III
MP3_RATES = (44100, 48000, 32000)
XSPF_NS = "http://xspf.org/ns/0/"


# -- playlists ---------------------------------------------------------------------------------------------------
def playlist_entries(data: bytes) -> list[str]:
    """The local file paths of an XSPF or M3U/M3U8 playlist, in order (file:// URLs decoded)."""
    text = data.decode("utf-8", errors="replace").lstrip("\ufeff")
    if text.lstrip().startswith("<"):
        root = ET.fromstring(text)
        raw = [(el.text or "").strip() for el in root.iter() if el.tag.rsplit("}", 1)[-1] == "location"]
    else:
        raw = [line.strip() for line in text.splitlines() if line.strip() and not line.startswith("#")]
    return [unquote(urlparse(r).path) if r.startswith("file:") else r for r in raw]


def playlist_format(data: bytes) -> str:
    """"XSPF" (XML whose root is an XSPF `playlist`), "XML" (other XML) or "M3U" (plain lines)."""
    text = data.decode("utf-8", errors="replace").lstrip("\ufeff").lstrip()
    if not text.startswith("<"):
        return "M3U"
    try:
        root = ET.fromstring(text)
    except ET.ParseError:
        return "XML"
    return "XSPF" if root.tag == f"{{{XSPF_NS}}}playlist" else "XML"


def check_playlist(data: bytes, expected: list[str], base_dir: str | None = None,
                   require_format: str | None = None) -> Verdict:
    """The playlist lists exactly the files `expected`, in this order: by full path where `expected` holds
    absolute paths (relative entries resolved against `base_dir`, the playlist's folder), else by base name.
    `require_format` ("XSPF"): the file must really be one (not an M3U list named .xspf)."""
    want_fmt = f"an {require_format} playlist" if require_format else "a playlist"
    if require_format and playlist_format(data) != require_format.upper():
        return Verdict.check(False, f"{want_fmt} of {expected}", f"a {playlist_format(data)} file")
    try:
        entries = playlist_entries(data)
    except ET.ParseError as exc:
        return Verdict.check(False, f"{want_fmt} of {expected}", f"unreadable XSPF ({exc})")
    if all(posixpath.isabs(e) for e in expected):
        got = [posixpath.normpath(posixpath.join(base_dir or "/", e)) for e in entries]
        want = [posixpath.normpath(e) for e in expected]
    else:
        got = [posixpath.basename(e) for e in entries]
        want = [posixpath.basename(e) for e in expected]
    return Verdict.check(got == want, f"{want_fmt} of {want} in this order", repr(got))


@evaluator("playlist_is")
def playlist_is(state: FinalState, path: str, entries: list[str], platform: str | None = None) -> Verdict:
    """`path` is a playlist of exactly the files `entries` (full paths), in order, each still there; a `.xspf`
    name must hold a real XSPF playlist."""
    fmt = "XSPF" if path.lower().endswith(".xspf") else None

    def check(data: bytes) -> Verdict:
        verdict = check_playlist(data, entries, posixpath.dirname(path), fmt)
        if not verdict.passed:
            return verdict
        gone = [e for e in entries if not state.exists(e, platform)]
        return Verdict(False, f"{verdict.reason}; but no file at {', '.join(gone)}") if gone else verdict

    return judge_file(state, path, f"a playlist at {path}", bytes, check, platform)


# -- MP3: the frames ---------------------------------------------------------------------------------------------
def mp3_frames(data: bytes) -> tuple[int, float, int, int]:
    """(frames, seconds, first frame's offset, bytes the frame run covers) of the first run of consecutive MPEG
    audio layer III frames (MPEG-1, 2 or 2.5) in `data`, after an ID3v2 tag; (0, 0, 0, 0) when there is none."""
    pos = 0
    if data[:3] == b"ID3" and len(data) >= 10:  # skip an ID3v2 tag (syncsafe size)
        pos = 10 + ((data[6] & 0x7F) << 21 | (data[7] & 0x7F) << 14 | (data[8] & 0x7F) << 7 | (data[9] & 0x7F))
    frames, seconds, start = 0, 0.0, pos
    while pos + 4 <= len(data):
        b1, b2 = data[pos + 1], data[pos + 2]
        version, layer = (b1 >> 3) & 3, (b1 >> 1) & 3  # version 3 = MPEG-1, 2 = MPEG-2, 0 = MPEG-2.5; layer 1 = III
        bitrate_i, rate_i = b2 >> 4, (b2 >> 2) & 3
        if data[pos] != 0xFF or (b1 & 0xE0) != 0xE0 or version == 1 or layer != 1 or bitrate_i in (0, 15) \
                or rate_i == 3:
            if frames:
                break
            pos += 1
            continue
        if not frames:
            start = pos
        rate = MP3_RATES[rate_i] // {3: 1, 2: 2, 0: 4}[version]
        if version == 3:
            size, samples = 144000 * MP3_BITRATES[bitrate_i] // rate, 1152
        else:
            size, samples = 72000 * MP3_BITRATES_LSF[bitrate_i] // rate, 576
        pos += size + ((b2 >> 1) & 1)
        frames, seconds = frames + 1, seconds + samples / rate
    return frames, seconds, start, (min(pos, len(data)) - start if frames else 0)


def mp3_seconds(data: bytes) -> float | None:
    """The duration of an MPEG layer III stream in seconds, by walking its frames; None if it is not one."""
    frames, seconds, _, _ = mp3_frames(data)
    return seconds if frames >= 3 else None


def check_mp3(data: bytes, min_seconds: float) -> Verdict:
    """`data` is an MP3 (MPEG layer III) stream at least `min_seconds` long (by its frames, not decoded)."""
    seconds = mp3_seconds(data)
    found = "not an MP3 stream" + (f" (starts {data[:4]!r})" if data else "") if seconds is None \
        else f"an MP3 of {seconds:.1f} s"
    return Verdict.check(seconds is not None and seconds >= float(min_seconds),
                         f"an MP3 of at least {float(min_seconds):.1f} s", found)


def check_mp3_stream(data: bytes) -> Verdict:
    """`data` is MP3 through and through: its layer III frames, after an optional ID3v2 tag, cover at least 95 %
    of the rest of the file (an ID3v1 tag may end it). A WAV, or a few frame headers glued to other data,
    is not."""
    frames, seconds, start, covered = mp3_frames(data)
    body = len(data) - start - (128 if data[-128:-125] == b"TAG" else 0)
    ok = frames >= 3 and body > 0 and covered >= 0.95 * body
    found = ("not an MP3 stream" + (f" (starts {data[:4]!r})" if data else "") if frames < 3 else
             f"{frames} layer III frames ({seconds:.1f} s) covering {covered / max(body, 1):.0%} of the file")
    return Verdict.check(ok, "an MP3 stream (MPEG layer III frames throughout)", found)


# -- audio: decoded samples ----------------------------------------------------------------------------------------
def wav_samples(data: bytes) -> tuple[int, list[float]]:
    """(sample rate, mono samples in [-1, 1]) of a PCM WAV (8, 16 or 32 bit; channels averaged). Raises on
    anything else."""
    with wave.open(io.BytesIO(data), "rb") as w:
        rate, channels, width = w.getframerate(), w.getnchannels(), w.getsampwidth()
        raw = w.readframes(w.getnframes())
    if width == 1:
        values = [(v - 128) / 128 for v in raw]
    elif width in (2, 4):
        arr = array.array("h" if width == 2 else "i")
        arr.frombytes(raw[: len(raw) - len(raw) % width])
        if sys.byteorder == "big":
            arr.byteswap()
        scale = 32768.0 if width == 2 else 2147483648.0
        values = [v / scale for v in arr]
    else:
        raise ValueError(f"{8 * width}-bit samples are not supported")
    if channels > 1:
        values = [sum(values[i:i + channels]) / channels for i in range(0, len(values) - channels + 1, channels)]
    return rate, values


def rms(x: list[float]) -> float:
    return math.sqrt(sum(v * v for v in x) / len(x)) if x else 0.0


def pitch(x: list[float], rate: int) -> float:
    """The frequency (Hz) of a tone: its rising crossings per second, with hysteresis (from below −h to above +h,
    h a tenth of the RMS level) so that near-silent noise does not count; only the span from the first to the
    last crossing is timed."""
    h = 0.1 * rms(x)
    low, times = False, []
    for i, v in enumerate(x):
        if v < -h:
            low = True
        elif v > h and low:
            low = False
            times.append(i)
    return (len(times) - 1) * rate / (times[-1] - times[0]) if len(times) > 2 else 0.0


def _dot(a, b) -> float:
    return sum(map(operator.mul, a, b))


def _ncc(a: list[float], b: list[float]) -> float:
    """Normalised correlation of two equally long sequences (0 when either is silent)."""
    den = math.sqrt(_dot(a, a) * _dot(b, b))
    return _dot(a, b) / den if den else 0.0


def align(out: list[float], ref: list[float], rate: int, max_lead: float = 0.1, max_delay: float = 0.3) -> int:
    """The lag (samples; positive: `out` starts later) that best lines `out` up with `ref`: a coarse search on
    4× decimated signals over −`max_lead`…+`max_delay` s, then a fine one around it, on a window of `ref`."""
    def decimate(x: list[float], d: int) -> list[float]:
        return [sum(x[i:i + d]) / d for i in range(0, len(x) - d + 1, d)]

    def search(sig: list[float], window: list[float], at: int, lags: range) -> tuple[float, int]:
        energy = [0.0]
        for v in sig:
            energy.append(energy[-1] + v * v)
        w_energy, n, best = _dot(window, window), len(window), (-2.0, lags.start)
        for lag in lags:
            a = at + lag
            if a < 0 or a + n > len(sig):
                continue
            den = math.sqrt((energy[a + n] - energy[a]) * w_energy)
            c = _dot(sig[a:a + n], window) / den if den > 0 else 0.0
            best = max(best, (c, lag))
        return best

    d = 4
    start = min(int(0.25 * rate), len(ref) // 4)
    width = max(d, min(int(0.5 * rate), len(ref) // 2))
    coarse = search(decimate(out, d), decimate(ref, d)[start // d:(start + width) // d], start // d,
                    range(-int(max_lead * rate) // d, int(max_delay * rate) // d + 1))[1] * d
    return search(out, ref[start:start + width], start, range(coarse - d, coarse + d + 1))[1]


def compare_audio(out: list[float], ref: list[float], rate: int, min_correlation: float = 0.9,
                  max_level_db: float = 6.0) -> Verdict:
    """Decoded `out` against the source `ref` (both mono at `rate`): the same duration (± 0.25 s + 3 %, room for
    an encoder's padding), the same loudness (RMS within ± `max_level_db` dB) and the same waveform (normalised
    correlation ≥ `min_correlation` once aligned)."""
    d_out, d_ref = len(out) / rate, len(ref) / rate
    level_out, level_ref = rms(out), rms(ref)
    want = (f"the source's audio: {d_ref:.2f} s (± {0.25 + 0.03 * d_ref:.2f}), RMS level ± {max_level_db:g} dB, "
            f"correlation ≥ {min_correlation:g} with it (a {pitch(ref, rate):.0f} Hz tone)")
    if not out or level_out < 1e-4:
        return Verdict.check(False, want, f"{d_out:.2f} s of silence")
    db = 20 * math.log10(level_out / level_ref) if level_ref else float("inf")
    lag = align(out, ref, rate)
    a, b = (out[lag:], ref) if lag >= 0 else (out, ref[-lag:])
    n = min(len(a), len(b))
    corr = _ncc(a[:n], b[:n])
    ok = abs(d_out - d_ref) <= 0.25 + 0.03 * d_ref and abs(db) <= max_level_db and corr >= min_correlation
    return Verdict.check(ok, want, f"{d_out:.2f} s, level {db:+.1f} dB, correlation {corr:.2f} "
                         f"(a {pitch(out, rate):.0f} Hz tone, aligned at {lag / rate * 1000:+.0f} ms)")


def decode_on_device(state: FinalState, path: str, rate: int, platform: str | None = None) -> bytes | None:
    """`path` decoded on the device by VLC to a mono 16-bit PCM WAV at `rate` Hz (its bytes), or None when VLC
    cannot decode it. VLC runs without the user's configuration, so settings the agent changed do not apply."""
    tmp = f"/tmp/jarvis-decoded-{uuid.uuid4().hex[:12]}.wav"
    chain = f"#transcode{{acodec=s16l,channels=1,samplerate={int(rate)}}}:std{{access=file,mux=wav,dst={tmp}}}"
    state.run(f"cvlc -q --ignore-config --no-video {shlex.quote(path)} --sout {shlex.quote(chain)} vlc://quit "
              f">/dev/null 2>&1", platform)
    try:
        return state.pull(tmp, platform)
    finally:
        state.run(f"rm -f {tmp}", platform)


def source_audio(state: FinalState, source: str,
                 platform: str | None = None) -> tuple[tuple[int, list[float]] | None, str]:
    """The samples of the source recording as set up (baseline; it must then still be there unchanged), or as it
    is now when an upstream subtask fed it; None and the reason when there is none."""
    base, now = state.baseline(source, platform), state.pull(source, platform)
    if base is not None and now is None:
        return None, f"the recording {source} deleted (it was to be kept)"
    if base is not None and now != base:
        return None, f"the recording {source} changed (it was to be kept as it was)"
    data = base if base is not None else now
    if data is None:
        return None, f"no recording at {source}"
    try:
        return wav_samples(data), ""
    except Exception:
        decoded = decode_on_device(state, source, 22050, platform) if base is None else None
        if decoded is None:
            return None, f"the recording {source} could not be decoded"
        return wav_samples(decoded), ""


@evaluator("audio_is_mp3")
def audio_is_mp3(state: FinalState, path: str, min_seconds: float = 1.0, source: str | None = None,
                 platform: str | None = None) -> Verdict:
    """`path` is an MP3 (MPEG layer III frames throughout) that decodes to the audio of the recording `source`
    (see `compare_audio`: duration, loudness, waveform), with `source` kept. Without `source` (old datasets)
    only the frames are walked: an MP3 of at least `min_seconds`."""
    want = f"an MP3 of {source or 'audio'} at {path}"
    data = state.pull(path, platform)
    if data is None:
        return Verdict.check(False, want, f"no file at {path}")
    if source is None:
        return check_mp3(data, min_seconds)
    stream = check_mp3_stream(data)
    if not stream.passed:
        return stream
    ref, problem = source_audio(state, source, platform)
    if ref is None:
        return Verdict.check(False, want, problem)
    rate, samples = ref
    decoded = decode_on_device(state, path, rate, platform)
    if decoded is None:
        return Verdict.check(False, want, f"{path}: VLC decoded nothing from it")
    try:
        _, out = wav_samples(decoded)
    except Exception as exc:
        return Verdict.check(False, want, f"{path}: its decoding is unreadable ({exc})")
    return compare_audio(out, samples, rate)


# -- snapshots -----------------------------------------------------------------------------------------------------
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


def video_frame(color: str, width: int, height: int, mark: list[int] | None) -> Image.Image:
    """The frame a task's video shows: `color` with a white rectangle `mark` (x0, y0, x1, y1, inclusive, as
    ImageMagick's `-draw 'rectangle …'`)."""
    img = Image.new("RGB", (int(width), int(height)), hex_rgb(color))
    if mark:
        ImageDraw.Draw(img).rectangle(tuple(int(v) for v in mark), fill=(255, 255, 255))
    return img


def check_snapshot_frame(data: bytes, path: str, frame: Image.Image, max_difference: float = 16.0,
                         max_off: float = 0.02) -> Verdict:
    """The snapshot at `path` is a picture in the format its name says, of about the frame's aspect ratio (± 10 %:
    VLC may be set to another snapshot size, and its decoder may hand over a picture padded to whole 16-pixel
    macroblocks, 320×256 for 320×240) and, scaled to the frame's size, pixel by pixel the frame (mean
    difference ≤ `max_difference`, ≤ `max_off` of the pixels off by > 48: video compression)."""
    want = f"the video's frame ({frame.width}×{frame.height})"
    img = open_image(data)
    if img is None:
        return Verdict.check(False, want, f"{path}: no readable image")
    named = format_named_by(path)
    if named is not None and (img.format or "").upper() != named:
        return Verdict.check(False, want, f"{path}: {img.format} data under a {named} name")
    if abs(img.width / img.height - frame.width / frame.height) > 0.1 * frame.width / frame.height:
        return Verdict.check(False, want, f"{path}: {img.width}×{img.height}")
    ok, mean, off = matches(img.convert("RGB").resize(frame.size, Image.Resampling.LANCZOS), frame,
                            max_difference, max_off)
    return Verdict.check(ok, f"{want} ({match_words(max_difference, max_off)})",
                         f"{path}: {img.width}×{img.height}, {found_words(mean, off)}")


@evaluator("snapshot_taken")
def snapshot_taken(state: FinalState, folders: list[str], color: str, width: int | None = None,
                   height: int | None = None, mark: list[int] | None = None, platform: str | None = None) -> Verdict:
    """A VLC snapshot (vlcsnap-*.png/jpg) in one of `folders` shows the video's frame: with `width` and `height`
    (and the white `mark`) compared pixel by pixel with that frame (`check_snapshot_frame`); without (old
    datasets) only its median colour is checked."""
    listing = state.run("ls -1d " + " ".join(f"{shlex.quote(f.rstrip('/'))}/vlcsnap-*" for f in folders)
                        + " 2>/dev/null", platform).stdout.split("\n")
    snaps = [p for p in listing if re.search(r"vlcsnap-.*\.(png|jpe?g)$", p)]
    if not snaps:
        return Verdict.check(False, f"a VLC snapshot in {', '.join(folders)}", "none")
    frame = video_frame(color, int(width), int(height), mark) if width and height else None
    last = Verdict(False, "")
    for path in snaps:
        data = state.pull(path, platform) or b""
        last = check_snapshot_frame(data, path, frame) if frame is not None else check_snapshot_color(data, color)
        if last.passed:
            return Verdict(True, last.reason if frame is not None else f"{path}: {last.reason}")
    return last if frame is not None else Verdict(False, f"{snaps[-1]}: {last.reason}")
