"""The pure checks behind the Ubuntu library's file, settings and media evaluators: each passes on the state a
solved task leaves and fails, saying what it expected and found, on the state before (no containers)."""

from __future__ import annotations

import io
import zipfile

from jarvis_pytest.devices.platforms import PLATFORMS
from jarvis_pytest.evaluators.file_facts import Entry, trashinfo_original
from jarvis_pytest.evaluators.files import check_ini_value, check_last_line, check_zip_members
from jarvis_pytest.evaluators.folders import check_trashed
from jarvis_pytest.evaluators.media import check_mp3, check_playlist, check_snapshot_color, playlist_entries
from jarvis_pytest.evaluators.settings import check_setting, check_wallpaper
from jarvis_pytest.evaluators.text import check_line_endings, check_lines_deleted
from jarvis_pytest.generators import generate
from PIL import Image


def test_setting_equals_or_matches():
    assert check_setting("Adwaita-dark", "theme", pattern="(?i)-dark$").passed
    bad = check_setting("Adwaita", "theme", pattern="(?i)-dark$")
    assert not bad.passed and "'Adwaita'" in bad.reason
    assert check_setting("false", "focus", expected="False").passed
    assert not check_setting(None, "focus", expected="false").passed


def test_wallpaper_needs_the_picture_on_workspace0_with_a_style():
    base = "/backdrop/screen0/monitorscreen/workspace0"
    shown = {f"{base}/last-image": "/home/user/Pictures/a.png", f"{base}/image-style": "5"}
    assert check_wallpaper(shown, "/home/user/Pictures/a.png").passed
    no_style = {**shown, f"{base}/image-style": "0"}
    assert not check_wallpaper(no_style, "/home/user/Pictures/a.png").passed
    other_ws = {f"{base.replace('workspace0', 'workspace1')}/last-image": "/home/user/Pictures/a.png"}
    verdict = check_wallpaper(other_ws, "/home/user/Pictures/a.png")
    assert not verdict.passed and "no wallpaper set" in verdict.reason


def test_line_endings_last_line_and_filtered_lines():
    assert check_line_endings(b"a\r\nb\r\nc\r\n", "crlf").passed
    assert not check_line_endings(b"a\r\nb\nc\r\n", "crlf").passed
    assert check_line_endings(b"a\nb\n", "lf").passed
    assert check_last_line("bread\ntea\nmilk\n\n", "milk", ["bread", "tea"]).passed
    lost = check_last_line("milk\n", "milk", ["bread"])
    assert not lost.passed and "lost" in lost.reason
    assert check_lines_deleted(b"keep a\nkeep b\n", "drop", ["keep a", "keep b"]).passed
    assert not check_lines_deleted(b"keep a\nDROP me\n", "drop", ["keep a"]).passed
    assert not check_lines_deleted(b"keep a\n", "drop", ["keep a", "keep b"]).passed
    original = b"keep a\r\nDrop me\r\nkeep b\r\n"
    assert check_lines_deleted(b"keep a\r\nkeep b\r\n", "drop", [], original).passed
    for wrong, found in ((b"keep a\nkeep b\n", "the right lines with 2 LF line breaks"),
                         (b"keep a\r\n\r\nkeep b\r\n", "line 2 is '\\r\\n'"),
                         (b"\xef\xbb\xbfkeep a\r\nkeep b\r\n", "the right text but stored as UTF-8 with BOM"),
                         (b"keep a\r\nkeep b", "without a final line break")):
        verdict = check_lines_deleted(wrong, "drop", [], original)
        assert not verdict.passed and found in verdict.reason, (wrong, verdict.reason)
    assert "a broken set-up" in check_lines_deleted(b"x\n", "drop", [], b"x\n").reason


def test_zip_members_trash_and_ini():
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        zf.writestr("thesis/part_one.txt", "x")
        zf.writestr("thesis/cover.png", "y")
    assert check_zip_members(buf.getvalue(), ["part_one.txt", "cover.png"]).passed
    assert not check_zip_members(buf.getvalue(), ["part_two.txt"]).passed
    assert not check_zip_members(b"plain text", ["a"]).passed
    info = "[Trash Info]\nPath=/home/user/Downloads/old%20draft.txt\nDeletionDate=2026-01-01T00:00:00\n"
    trashed = [(trashinfo_original(info), Entry(exists=True, kind="file", size=1, sha256="ab"))]
    assert trashed[0][0] == "/home/user/Downloads/old draft.txt"
    assert check_trashed(PLATFORMS["ubuntu"], trashed, "/home/user/Downloads/old draft.txt", "ab").passed
    assert "holds other content" in check_trashed(PLATFORMS["ubuntu"], trashed, trashed[0][0], "cd").reason
    assert not check_trashed(PLATFORMS["ubuntu"], [], "/home/user/Downloads/x.txt", None).passed
    vlcrc = "[core]\n#snapshot-path=\nsnapshot-path=/home/user/Pictures/snaps/\n"
    assert check_ini_value(vlcrc, "snapshot-path", "/home/user/Pictures/snaps").passed
    assert not check_ini_value("[core]\n#snapshot-path=/x\n", "snapshot-path", "/x").passed


def test_playlists_in_xspf_and_m3u():
    xspf = (b'<?xml version="1.0"?><playlist xmlns="http://xspf.org/ns/0/" version="1"><trackList>'
            b"<track><location>file:///home/user/Music/a%20b.wav</location></track>"
            b"<track><location>file:///home/user/Music/c.wav</location></track></trackList></playlist>")
    assert playlist_entries(xspf) == ["/home/user/Music/a b.wav", "/home/user/Music/c.wav"]
    assert check_playlist(xspf, ["/home/user/Music/a b.wav", "/home/user/Music/c.wav"]).passed
    assert not check_playlist(xspf, ["/home/user/Music/c.wav", "/home/user/Music/a b.wav"]).passed
    m3u = b"#EXTM3U\n#EXTINF:3,a\n/home/user/Music/a.wav\nfile:///home/user/Music/c.wav\n"
    assert check_playlist(m3u, ["a.wav", "c.wav"]).passed
    assert not check_playlist(b"<playlist", ["a.wav"]).passed


def test_mp3_and_snapshot_checks():
    wav = generate("wav_tone", {"seconds": 1.5})
    verdict = check_mp3(wav, 1.0)
    assert not verdict.passed and "not an MP3" in verdict.reason
    # three MPEG-1 layer III frames at 128 kbit/s, 44.1 kHz: 417 bytes each (no padding)
    frame = b"\xff\xfb\x90\x00" + bytes(413)
    assert check_mp3(frame * 40, 1.0).passed  # 40 × 1152 / 44100 ≈ 1.04 s
    assert not check_mp3(frame * 10, 1.0).passed
    png = io.BytesIO()
    Image.new("RGB", (64, 48), "#c03020").save(png, "PNG")
    assert check_snapshot_color(png.getvalue(), "#c03020").passed
    assert not check_snapshot_color(png.getvalue(), "#2060c0").passed


def test_image_checks_tell_transformations_apart():
    from jarvis_pytest.evaluators.images import (TRANSFORMS, check_border, check_format, check_grayscale,
                                                 check_scaled, check_side_by_side, check_transformed,
                                                 open_image)
    from PIL import ImageOps

    png = generate("quadrant_image", {"width": 300, "height": 200})
    ref = open_image(png).convert("RGB")
    for name, transform in TRANSFORMS.items():
        assert check_transformed(transform(ref), ref, name).passed, name
        if name != "identity":
            assert not check_transformed(ref, ref, name).passed, name  # the untouched picture fails
    assert not check_transformed(ImageOps.flip(ref), ref, "flip_horizontal").passed
    assert check_format(open_image(png), "PNG").passed and not check_format(open_image(png), "JPEG").passed
    jpeg = open_image(generate("quadrant_image", {"width": 300, "height": 200, "format": "JPEG"}))
    assert check_format(jpeg, "jpeg").passed
    assert check_scaled(ref.resize((150, 100)), ref, percent=50).passed
    assert check_scaled(ref.resize((120, 80)), ref, width=120).passed
    assert not check_scaled(ref.resize((120, 100)), ref, width=120).passed  # aspect ratio lost
    assert check_grayscale(ImageOps.grayscale(ref)).passed and not check_grayscale(ref).passed
    framed = ImageOps.expand(ref, border=10, fill="#ffd700")
    assert check_border(framed, ref, 10, "#ffd700").passed
    assert not check_border(framed, ref, 10, "#000000").passed and not check_border(ref, ref, 10, "#ffd700").passed
    both = Image.new("RGB", (600, 200))
    both.paste(ref, (0, 0))
    both.paste(ImageOps.invert(ref), (300, 0))
    assert check_side_by_side(both, ref, ImageOps.invert(ref)).passed
    assert not check_side_by_side(both, ImageOps.invert(ref), ref).passed


def test_bookmarks_in_every_folder():
    import json

    from jarvis_pytest.evaluators.browser import bookmarks_checksum, check_bookmark

    data = json.loads('{"roots": {"bookmark_bar": {"children": [], "type": "folder"}, "other": {"type": "folder", '
                      '"children": [{"type": "folder", "children": [{"type": "url", "name": "Read later", '
                      '"url": "file:///home/user/site/a.html"}]}]}}}')
    data["checksum"] = bookmarks_checksum(data)  # as Chromium writes it (a file edited by hand fails)
    text = json.dumps(data)
    assert check_bookmark(text, "file:///home/user/site/a.html", "Read later").passed
    assert not check_bookmark(text, "file:///home/user/site/a.html", "Other name").passed
    assert not check_bookmark(text, "file:///home/user/site/b.html").passed
    assert not check_bookmark(None, "file:///x").passed and not check_bookmark("{", "file:///x").passed
