"""The media checks behind the VLC tasks: MP3s decoded and compared with their source recording, playlists by
their real format and full paths, snapshots pixel by pixel against the video's frame. The pure checks run on the
host; the last test decodes real MP3s with VLC on a real Ubuntu device (marked `containers`)."""

from __future__ import annotations

import io
import math
import posixpath
import re
import struct
import wave

import pytest
from PIL import Image

from jarvis_pytest.devices.base import CommandResult
from jarvis_pytest.evaluators.media import (align, audio_is_mp3, check_mp3, check_mp3_stream, check_playlist,
                                            check_snapshot_frame, compare_audio, mp3_frames, pitch, playlist_format,
                                            playlist_is, snapshot_taken, video_frame, wav_samples)
from jarvis_pytest.generators import generate

RATE = 22050
FRAME = b"\xff\xfb\x90\x00" + bytes(413)  # an MPEG-1 layer III frame header, 128 kbit/s, 44.1 kHz: 417 bytes, silent


def tone(seconds: float = 4.0, frequency: float = 392.0, rate: int = RATE, amp: float = 0.3, delay: int = 0,
         noise: float = 0.0) -> list[float]:
    """Samples of a sine tone after `delay` samples of silence, with a deterministic ripple of size `noise`."""
    n = int(seconds * rate)
    return [0.0] * delay + [amp * math.sin(2 * math.pi * frequency * i / rate) + noise * math.sin(i * 1.7)
                            for i in range(n)]


def wav_bytes(samples: list[float], rate: int = RATE) -> bytes:
    buf = io.BytesIO()
    with wave.open(buf, "wb") as w:
        w.setnchannels(1)
        w.setsampwidth(2)
        w.setframerate(rate)
        w.writeframes(b"".join(struct.pack("<h", max(-32768, min(32767, int(v * 32767)))) for v in samples))
    return buf.getvalue()


class FakeDevice:
    """Files by path, and the one command the MP3 check runs: `cvlc … IN --sout '#transcode{…samplerate=R}…dst=OUT'`,
    which "decodes" IN by looking up the samples this test says VLC would give for it."""

    def __init__(self, files: dict[str, bytes], decodes: dict[str, list[float]]):
        self.files, self.decodes, self.commands = files, decodes, []

    def run(self, command: str, user=None, timeout: float = 60.0) -> CommandResult:
        self.commands.append(command)
        m = re.match(r"cvlc .*?'?(/[^' ]+)'? --sout .*samplerate=(\d+).*dst=([^}]+)}", command)
        if m and m.group(1) in self.decodes and m.group(1) in self.files:
            self.files[m.group(3)] = wav_bytes(self.decodes[m.group(1)], int(m.group(2)))
        elif command.startswith("rm -f "):
            self.files.pop(command.split()[-1], None)
        elif command.startswith("test -e "):
            return CommandResult(0 if command.split(" ", 2)[2].strip("'") in self.files else 1, "", "")
        return CommandResult(0, "", "")


class FakeState:
    """The part of FinalState the media checks use, over a FakeDevice."""

    def __init__(self, files: dict[str, bytes], decodes: dict[str, list[float]] | None = None,
                 baselines: dict[str, bytes] | None = None):
        self.dev = FakeDevice(files, decodes or {})
        self.baselines = baselines or {}

    def run(self, command, platform=None, user=None):
        return self.dev.run(command)

    def pull(self, path, platform=None):
        return self.dev.files.get(path)

    def exists(self, path, platform=None):
        return path in self.dev.files

    def baseline(self, path, platform=None):
        return self.baselines.get(path)


# -- MP3 frames ------------------------------------------------------------------------------------------------------
def test_mp3_frames_of_mpeg1_and_mpeg2_layer_iii():
    assert mp3_frames(FRAME * 60)[:2] == (60, pytest.approx(60 * 1152 / 44100))
    lsf = b"\xff\xf3\xc0\x00" + bytes(72000 * 128 // 22050 - 4)  # MPEG-2 layer III, 128 kbit/s, 22.05 kHz
    frames, seconds, start, covered = mp3_frames(b"ID3\x03\x00\x00\x00\x00\x00\x05" + bytes(5) + lsf * 20)
    assert frames == 20 and seconds == pytest.approx(20 * 576 / 22050) and start == 15 and covered == len(lsf) * 20
    assert check_mp3(FRAME * 40, 1.0).passed  # the frame walk alone, kept for old datasets


def test_an_mp3_stream_is_frames_through_and_through():
    assert check_mp3_stream(FRAME * 60 + b"TAG" + bytes(125)).passed  # an ID3v1 tag may end it
    wav = check_mp3_stream(generate("wav_tone", {"seconds": 2}))
    assert not wav.passed and "not an MP3 stream" in wav.reason
    glued = check_mp3_stream(FRAME * 5 + generate("wav_tone", {"seconds": 2}))
    assert not glued.passed and "covering 2% of the file" in glued.reason


# -- decoded audio against the source --------------------------------------------------------------------------
def test_wav_samples_reads_the_generator_and_stereo():
    rate, samples = wav_samples(generate("wav_tone", {"seconds": 1, "frequency": 392}))
    assert rate == 22050 and len(samples) == 22050 and max(samples) == pytest.approx(0.3, abs=0.01)
    assert pitch(samples, rate) == pytest.approx(392, rel=0.005)
    buf = io.BytesIO()
    with wave.open(buf, "wb") as w:
        w.setnchannels(2)
        w.setsampwidth(2)
        w.setframerate(8000)
        w.writeframes(struct.pack("<4h", 1000, 3000, -2000, 0))
    assert wav_samples(buf.getvalue()) == (8000, [2000 / 32768, -1000 / 32768])


def test_the_encoders_delay_is_found():
    periods = (align(tone(2.0, delay=1105), tone(2.0), RATE) - 1105) / (RATE / 392)  # a tone fits every period on
    assert abs(periods - round(periods)) < 0.05
    voice = [math.sin(i * i / 4e5) * 0.3 for i in range(2 * RATE)]  # a chirp: one lag only fits
    assert align([0.0] * 777 + voice, voice, RATE) == 777


def test_decoded_audio_must_be_the_source_recording():
    ref = tone(4.0)
    good = compare_audio(tone(4.0, delay=1105, noise=0.01), ref, RATE)  # an encoder's delay and a little noise
    assert good.passed, good.reason
    assert "a 392 Hz tone" in good.reason
    other = compare_audio(tone(4.0, 880), ref, RATE)
    assert not other.passed and "a 880 Hz tone" in other.reason and "correlation 0.0" in other.reason
    part = compare_audio(tone(1.5), ref, RATE)
    assert not part.passed and "found 1.50 s" in part.reason
    silent = compare_audio([0.0] * 4 * RATE, ref, RATE)
    assert not silent.passed and "silence" in silent.reason
    quiet = compare_audio(tone(4.0, amp=0.03), ref, RATE)
    assert not quiet.passed and "level -20.0 dB" in quiet.reason


def test_audio_is_mp3_decodes_the_file_and_compares_it_with_the_recording_as_set_up():
    source = generate("wav_tone", {"seconds": 4, "frequency": 392})
    mp3, wav = "/home/user/Music/memo.mp3", "/home/user/Music/memo.wav"
    _, samples = wav_samples(source)
    good = FakeState({mp3: FRAME * 150, wav: source}, {mp3: [0.0] * 1105 + samples}, {wav: source})
    verdict = audio_is_mp3(good, mp3, source=wav)
    assert verdict.passed, verdict.reason
    assert any("cvlc" in c and "--ignore-config" in c for c in good.dev.commands)
    assert not any(p.startswith("/tmp/jarvis-decoded-") for p in good.dev.files)  # the decoding is removed
    # issue 16's cheap state: 60 empty MP3 frame headers — VLC decodes them to 1.6 s of silence
    empty = FakeState({mp3: FRAME * 60, wav: source}, {mp3: [0.0] * int(1.567 * RATE)}, {wav: source})
    assert audio_is_mp3(empty, mp3, min_seconds=1.0).passed  # what the old check (frames only) accepted
    verdict = audio_is_mp3(empty, mp3, source=wav)
    assert not verdict.passed and "1.57 s of silence" in verdict.reason
    copied = audio_is_mp3(FakeState({mp3: source, wav: source}, {}, {wav: source}), mp3, source=wav)
    assert not copied.passed and "not an MP3 stream" in copied.reason
    deleted = audio_is_mp3(FakeState({mp3: FRAME * 150}, {mp3: samples}, {wav: source}), mp3, source=wav)
    assert not deleted.passed and "the recording /home/user/Music/memo.wav deleted" in deleted.reason
    undecodable = audio_is_mp3(FakeState({mp3: FRAME * 150, wav: source}, {}, {wav: source}), mp3, source=wav)
    assert not undecodable.passed and "VLC decoded nothing" in undecodable.reason
    # a composed task's fed recording has no baseline: the file as it is now is the source
    fed = FakeState({mp3: FRAME * 150, wav: source}, {mp3: samples})
    assert audio_is_mp3(fed, mp3, source=wav).passed
    assert not audio_is_mp3(FakeState({mp3: FRAME * 150}, {mp3: samples}), mp3, source=wav).passed


# -- playlists -----------------------------------------------------------------------------------------------------
def xspf(*paths: str) -> bytes:
    tracks = "".join(f"<track><location>{p}</location></track>" for p in paths)
    return (f'<?xml version="1.0" encoding="UTF-8"?><playlist xmlns="http://xspf.org/ns/0/" version="1">'
            f"<trackList>{tracks}</trackList></playlist>").encode()


MUSIC = ["/home/user/Music/intro.wav", "/home/user/Music/waltz.wav", "/home/user/Music/coda.wav"]


def test_playlist_format_is_read_from_the_content():
    assert playlist_format(xspf("file:///a.wav")) == "XSPF"
    assert playlist_format(b"/a.wav\n/b.wav\n") == "M3U"
    assert playlist_format(b"<html><body/></html>") == "XML"
    m3u = check_playlist("\n".join(MUSIC).encode(), MUSIC, "/home/user/Music", "XSPF")
    assert not m3u.passed and "found a M3U file" in m3u.reason


def test_playlist_entries_are_compared_by_full_path():
    assert check_playlist(xspf(*("file://" + p for p in MUSIC)), MUSIC, "/home/user/Music", "XSPF").passed
    assert check_playlist(xspf("intro.wav", "waltz.wav", "./coda.wav"), MUSIC, "/home/user/Music", "XSPF").passed
    assert check_playlist(xspf("file:///home/user/Music/intro%2Ewav", *MUSIC[1:]), MUSIC, "/home/user/Music").passed
    elsewhere = check_playlist(xspf("file:///tmp/intro.wav", "file:///tmp/waltz.wav", "file:///tmp/coda.wav"),
                               MUSIC, "/home/user/Music", "XSPF")
    assert not elsewhere.passed and "/tmp/intro.wav" in elsewhere.reason
    assert check_playlist(b"/x/a.wav\n/y/c.wav\n", ["a.wav", "c.wav"]).passed  # names only: by base name


def test_playlist_is_wants_an_xspf_of_files_that_are_there():
    path = "/home/user/Music/evening.xspf"
    files = {p: b"RIFF" for p in MUSIC}
    good = FakeState({**files, path: xspf(*("file://" + p for p in MUSIC))})
    assert playlist_is(good, path, MUSIC).passed
    m3u = FakeState({**files, path: "\n".join(MUSIC).encode()})
    assert not playlist_is(m3u, path, MUSIC).passed
    moved = FakeState({path: xspf(*("file://" + p for p in MUSIC))})
    verdict = playlist_is(moved, path, MUSIC)
    assert not verdict.passed and "no file at /home/user/Music/intro.wav" in verdict.reason
    swapped = FakeState({**files, path: xspf(*("file://" + p for p in (MUSIC[1], MUSIC[0], MUSIC[2])))})
    assert not playlist_is(swapped, path, MUSIC).passed


# -- snapshots -----------------------------------------------------------------------------------------------------
def encoded(img: Image.Image, fmt: str = "PNG", **kw) -> bytes:
    buf = io.BytesIO()
    img.save(buf, fmt, **kw)
    return buf.getvalue()


def test_snapshot_is_the_videos_frame_pixel_by_pixel():
    frame = video_frame("#2060c0", 320, 240, [20, 20, 90, 90])
    assert frame.getpixel((20, 20)) == (255, 255, 255) and frame.getpixel((90, 90)) == (255, 255, 255)
    assert frame.getpixel((91, 91)) == (0x20, 0x60, 0xc0)
    p = "/home/user/Pictures/vlcsnap-2025-01-01-12h00m00s000.png"
    assert check_snapshot_frame(encoded(frame), p, frame).passed
    lossy = encoded(frame, "JPEG", quality=70)
    assert check_snapshot_frame(lossy, p.replace(".png", ".jpg"), frame).passed
    assert check_snapshot_frame(encoded(frame.resize((640, 480))), p, frame).passed  # another snapshot size
    flat = check_snapshot_frame(encoded(Image.new("RGB", (320, 240), "#2060c0")), p, frame)
    assert not flat.passed and "pixels off" in flat.reason  # issue 16: a flat image of the colour passed
    other = check_snapshot_frame(encoded(video_frame("#808080", 320, 240, [20, 20, 90, 90])), p, frame)
    assert not other.passed
    screen = Image.new("RGB", (1920, 1080), "#2060c0")
    assert not check_snapshot_frame(encoded(screen), p, frame).passed
    assert not check_snapshot_frame(lossy, p, frame).passed  # JPEG data under a .png name


def test_snapshot_taken_looks_in_the_folders_and_keeps_the_old_form():
    frame = video_frame("#30a040", 320, 240, [20, 20, 90, 90])
    p = "/home/user/Pictures/vlcsnap-2025-01-01-12h00m00s000.png"

    class Listing(FakeState):
        def run(self, command, platform=None, user=None):
            folders = re.findall(r"'?(/[^' ]+)/vlcsnap-\*", command)
            names = [f for f in self.dev.files if "/vlcsnap-" in f and posixpath.dirname(f) in folders]
            return CommandResult(0, "\n".join(names), "")

    good = Listing({p: encoded(frame)})
    args = {"folders": ["/home/user", "/home/user/Pictures"], "color": "#30a040", "width": 320, "height": 240,
            "mark": [20, 20, 90, 90]}
    assert snapshot_taken(good, **args).passed
    flat = Listing({p: encoded(Image.new("RGB", (320, 240), "#30a040"))})
    assert not snapshot_taken(flat, **args).passed
    assert snapshot_taken(flat, args["folders"], "#30a040").passed  # the old form (median colour): weak
    elsewhere = Listing({"/tmp/vlcsnap-1.png": encoded(frame)})
    assert not snapshot_taken(elsewhere, **args).passed


# -- the real decoder --------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def ubuntu_device(tmp_path_factory):
    """A real Ubuntu device booted from its image (built when missing or stale, one builder at a time)."""
    from filelock import FileLock

    from jarvis_pytest.bench.probe import boot
    from jarvis_pytest.infra import engine, images

    engine.ensure_engine()  # raises with the fix when no engine can be had: the test errors, loudly
    with FileLock(str(tmp_path_factory.getbasetemp().parent / "jarvis-images.lock")):
        tag = images.build_all(["ubuntu"])["ubuntu"]
    with boot(tag, timeout=120) as booted:
        yield booted.device


@pytest.mark.containers
def test_vlc_on_the_device_decodes_real_mp3s_for_the_check(ubuntu_device):
    """The oracle's VLC conversion of the set-up tone passes; issue 16's 60 empty frame headers, another tone and
    a cut conversion fail, each with its reason — decoded by the device's own VLC."""
    from jarvis_pytest.evaluators.state import FinalState

    device = ubuntu_device
    wav = "/home/user/Music/memo.wav"
    source = generate("wav_tone", {"seconds": 4, "frequency": 392})
    device.upload(wav, source)
    device.upload("/tmp/other.wav", generate("wav_tone", {"seconds": 4, "frequency": 880}))
    device.upload("/home/user/Music/empty.mp3", FRAME * 60)

    def to_mp3(src: str, dst: str, extra: str = "") -> None:
        chain = f"#transcode{{acodec=mp3,ab=128,channels=2,samplerate=44100}}:std{{access=file,mux=raw,dst={dst}}}"
        res = device.run(f"cvlc -q '{src}' {extra} --sout '{chain}' vlc://quit", user="user", timeout=60)
        assert res.returncode == 0, res.stderr

    to_mp3(wav, "/home/user/Music/good.mp3")
    to_mp3("/tmp/other.wav", "/home/user/Music/other.mp3")
    to_mp3(wav, "/home/user/Music/cut.mp3", "--stop-time=1.5")
    state = FinalState(platform="ubuntu", devices={"ubuntu": device}, baselines={("ubuntu", wav): source})
    good = audio_is_mp3(state, "/home/user/Music/good.mp3", source=wav)
    assert good.passed, good.reason
    for name, words in (("empty", "silence"), ("other", "a 880 Hz tone"), ("cut", "found 1.")):
        verdict = audio_is_mp3(state, f"/home/user/Music/{name}.mp3", source=wav)
        assert not verdict.passed and words in verdict.reason, (name, verdict.reason)
