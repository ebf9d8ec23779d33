"""The checks behind the desktop-settings, image-viewer and VLC-preferences templates (no containers): each passes on
the state a careful person leaves (the settings dialog's way) and fails, naming what is wrong, on the cheap wrong
states of the templates' negatives."""

from __future__ import annotations

import io
import json
from types import SimpleNamespace

import pytest
from PIL import Image

from jarvis_pytest.evaluators import get_evaluator, settings
from jarvis_pytest.evaluators.desktop import check_size_report, check_vlc_option, vlcrc_values
from jarvis_pytest.evaluators.settings import (check_font, check_theme_dark, check_typed_setting, check_unchanged,
                                               check_wallpaper_picture, check_workspaces, css_background,
                                               gtkrc_background, lightness, parse_font, theme_dirs, xfconf_xml)
from tests.file_state import posix_facts_reply, state_with

# -- themes: the lines that decide the colours in the themes the Ubuntu image ships (/usr/share/themes) ---------
ADWAITA_DARK_CSS = '@import url("resource:///org/gtk/libgtk/theme/Adwaita/gtk-contained-dark.css");\n'
ADWAITA_CSS = "/* Adwaita is now part of GTK+ 3, this file is no longer used */\n"
ADWAITA_RC = ('gtk-color-scheme = "text_color:black\\nbase_color:white"\n'
              'gtk-color-scheme = "fg_color:#2e3436\\nbg_color:#e8e8e7"\n'
              'gtk-color-scheme = "selected_fg_color:#ffffff\\nselected_bg_color:#4a90d9"\n')
ADWAITA_DARK_RC = ('gtk-color-scheme = "text_color:white\\nbase_color:#232729"\n'
                   'gtk-color-scheme = "fg_color:#eeeeec\\nbg_color:#33393b"\n'
                   'gtk-color-scheme = "selected_fg_color:#ffffff\\nselected_bg_color:#215d9c"\n')
GREYBIRD_DARK_CSS = ("*, .selection-mode.titlebar:not(headerbar) .subtitle:link { padding: 0; }\n"
                     "@define-color theme_bg_color #3b3e3f;\n"
                     ".background { color: #eeeeec; background-color: #3b3e3f; }\n")
GREYBIRD_CSS = ("@define-color theme_bg_color #cecece;\n"
                ".background { color: #3c3c3c; background-color: #cecece; }\n")
GREYBIRD_DARK_RC = ('gtk-color-scheme\t= "bg_color:#3b3e3f\\nselected_bg_color:#398ee7\\nbase_color:#2d2e30" '
                    '# Background\n')


def theme_files(name: str, where: str = "/usr/share/themes", css: str | None = None,
                rc: str | None = None) -> dict[str, str | None]:
    """The candidate files `theme_is_dark` pulls for `name`, with the theme's files present in `where`."""
    files: dict[str, str | None] = {}
    for d in theme_dirs(name):
        files[f"{d}/gtk-3.0/gtk.css"] = css if d == f"{where}/{name}" else None
        files[f"{d}/gtk-2.0/gtkrc"] = rc if d == f"{where}/{name}" else None
    return files


@pytest.mark.parametrize("name, css, rc", [
    ("Adwaita-dark", ADWAITA_DARK_CSS, ADWAITA_DARK_RC),     # the Style list's dark themes of the image
    ("Greybird-dark", GREYBIRD_DARK_CSS, GREYBIRD_DARK_RC),
])
def test_the_shipped_dark_themes_pass(name, css, rc):
    verdict = check_theme_dark(name, theme_files(name, css=css, rc=rc))
    assert verdict.passed, verdict.reason
    assert repr(name) in verdict.reason and "L*" in verdict.reason


def test_a_dark_theme_not_named_dark_passes_judged_by_its_colours():
    css = "@define-color bg_color #1e2127;\n@define-color theme_bg_color @bg_color;\n"
    verdict = check_theme_dark("Nordic", theme_files("Nordic", where="/home/user/.themes", css=css))
    assert verdict.passed and "#1e2127" in verdict.reason


def test_a_gtk2_only_dark_theme_passes_from_its_gtkrc():
    assert check_theme_dark("Old-night", theme_files("Old-night", rc=GREYBIRD_DARK_RC)).passed


@pytest.mark.parametrize("name, files, found", [
    ("Adwaita", theme_files("Adwaita", css=ADWAITA_CSS, rc=ADWAITA_RC), "#e8e8e7"),   # the fresh desktop
    ("Greybird", theme_files("Greybird", css=GREYBIRD_CSS), "#cecece"),
    # the light Greybird copied under a dark-sounding name (a negative of the template)
    ("Paper-dark", theme_files("Paper-dark", where="/home/user/.themes", css=GREYBIRD_CSS), "#cecece"),
    # a name ending in -dark that is not installed (a negative): GTK falls back to its light default
    ("Midnight-dark", theme_files("Midnight-dark"), "no GTK style installed"),
    # a window-border-only (xfwm4) theme as the GTK theme: no application style at all
    ("Greybird-dark-accessibility", theme_files("Greybird-dark-accessibility"), "no GTK style installed"),
    (None, {}, "no theme set"),
])
def test_light_missing_or_border_only_themes_fail(name, files, found):
    verdict = check_theme_dark(name, files)
    assert not verdict.passed and found in verdict.reason, verdict.reason


def test_theme_colour_parsing():
    assert css_background(ADWAITA_DARK_CSS)[0] == (0x35, 0x35, 0x35)
    assert css_background("window { background-color: rgb(20, 20, 30); }")[0] == (20, 20, 30)
    assert css_background("foo { color: red }") == (None, "")
    # selected_bg_color / insensitive_bg_color are not the window background
    assert gtkrc_background('gtk-color-scheme = "selected_bg_color:#000000\\nbg_color:#ffffff"') == (255, 255, 255)
    assert lightness((0, 0, 0)) == 0 and round(lightness((255, 255, 255))) == 100
    assert lightness((0x3b, 0x3e, 0x3f)) < settings.DARK_LIGHTNESS < lightness((0xce, 0xce, 0xce))


def test_a_theme_with_unreadable_colours_is_judged_by_its_name():
    css = '@import url("resource:///org/example/theme/gtk.css");\n'
    assert check_theme_dark("Example-Dark", theme_files("Example-Dark", css=css)).passed
    verdict = check_theme_dark("Example", theme_files("Example", css=css))
    assert not verdict.passed and "judged by its name" in verdict.reason


# -- typed settings and what must stay unchanged ----------------------------------------------------------------
XFWM4_XML = """<?xml version="1.0" encoding="UTF-8"?>
<channel name="xfwm4" version="1.0">
  <property name="general" type="empty">
    <property name="click_to_focus" type="bool" value="true"/>
    <property name="focus_delay" type="int" value="250"/>
    <property name="focus_new" type="bool" value="true"/>
    <property name="raise_on_focus" type="bool" value="false"/>
    <property name="theme" type="string" value="Default"/>
    <property name="workspace_count" type="int" value="4"/>
    <property name="workspace_names" type="array">
      <value type="string" value="Workspace 1"/>
      <value type="string" value="Workspace 2"/>
      <value type="string" value="Workspace 3"/>
      <value type="string" value="Workspace 4"/>
    </property>
  </property>
</channel>
"""


def test_xfconf_xml_is_read_with_types_and_arrays():
    props = xfconf_xml(XFWM4_XML)
    assert props["/general/click_to_focus"] == ("bool", True)
    assert props["/general/focus_delay"] == ("int", 250)
    assert props["/general/workspace_names"][1][0] == ("string", "Workspace 1")
    assert "/general" not in props  # "empty" properties are only folders


def test_focus_follows_mouse_needs_the_boolean_the_dialog_writes():
    assert check_typed_setting(("bool", False), "xfwm4:/general/click_to_focus", "false", "bool").passed
    as_string = check_typed_setting(("string", "false"), "xfwm4:/general/click_to_focus", "false", "bool")
    assert not as_string.passed and "another type" in as_string.reason
    still = check_typed_setting(("bool", True), "xfwm4:/general/click_to_focus", "false", "bool")
    assert not still.passed and "True" in still.reason
    assert not check_typed_setting(None, "xfwm4:/general/click_to_focus", "false", "bool").passed


FOCUS_PROPS = ["/general/focus_new", "/general/focus_delay", "/general/raise_on_focus"]


def test_settings_not_asked_must_stay_as_after_setup():
    base = xfconf_xml(XFWM4_XML)
    careful = {**base, "/general/click_to_focus": ("bool", False)}
    assert check_unchanged(careful, base, FOCUS_PROPS, "xfwm4").passed
    damaged = {**careful, "/general/focus_new": ("bool", False), "/general/raise_on_focus": ("bool", True)}
    verdict = check_unchanged(damaged, base, FOCUS_PROPS, "xfwm4")
    assert not verdict.passed and "/general/focus_new" in verdict.reason and "/general/raise_on_focus" in verdict.reason
    # a property unset after set-up that the agent sets (e.g. a custom DPI) is a change too
    assert not check_unchanged({"/Xft/DPI": ("int", 120)}, {}, ["/Xft/DPI"], "xsettings").passed
    assert "no baseline" in check_unchanged(careful, None, FOCUS_PROPS, "xfwm4").reason


# -- fonts --------------------------------------------------------------------------------------------------------
def test_font_descriptions_are_parsed():
    assert parse_font("Sans 10") == ("Sans", frozenset(), 10.0)
    assert parse_font("Sans Regular 16") == ("Sans", frozenset(), 16.0)
    assert parse_font("DejaVu Sans Book 12") == ("DejaVu Sans", frozenset(), 12.0)
    assert parse_font("Sans Bold Italic 9") == ("Sans", frozenset({"bold", "italic"}), 9.0)


@pytest.mark.parametrize("value", ["Sans 16", "Sans Regular 16", "DejaVu Sans 16", "DejaVu Sans Book 16", "sans 16.0"])
def test_the_default_font_at_the_new_size_passes(value):
    # "Sans 16" is what the Appearance dialog's font chooser writes; its fontconfig name keeps the same font
    verdict = check_font(value, 16, "Sans 10", resolved="DejaVu Sans")
    assert verdict.passed, verdict.reason


@pytest.mark.parametrize("value, found", [
    ("Sans 10", "size 10"),                      # unchanged
    ("Monospace 16", "family 'Monospace'"),      # the family changed
    ("Sans Bold 16", "style bold"),              # the style changed
    ("Sans 15", "size 15"),
    ("Liberation Sans 16", "family 'Liberation Sans'"),
])
def test_another_family_style_or_size_fails(value, found):
    verdict = check_font(value, 16, "Sans 10", resolved="DejaVu Sans")
    assert not verdict.passed and found in verdict.reason, verdict.reason


# -- workspaces ------------------------------------------------------------------------------------------------------
NAMES = ["Workspace 1", "Workspace 2", "Workspace 3", "Workspace 4"]


@pytest.mark.parametrize("count, names", [(6, NAMES + ["Workspace 5", "Workspace 6"]), (2, NAMES)])
def test_the_dialogs_workspace_count_passes(count, names):
    # xfwm4 appends names when the count grows and keeps the array when it shrinks
    verdict = check_workspaces(("int", count), count, count, names, NAMES)
    assert verdict.passed, verdict.reason


@pytest.mark.parametrize("value, desktops, names, found", [
    (("string", "6"), 4, NAMES, "another"),             # a string xfwm4 ignores: the desktop keeps 4 workspaces
    (("int", 7), 7, NAMES, "workspace_count 7"),
    (("int", 6), 6, ["Main"] + NAMES[1:], "renamed 'Workspace 1' → 'Main'"),
])
def test_a_count_the_window_manager_ignores_a_wrong_count_or_renamed_workspaces_fail(value, desktops, names, found):
    verdict = check_workspaces(value, desktops, 6, names, NAMES)
    assert not verdict.passed
    assert found in verdict.reason or (found == "another" and "shows 4 workspaces" in verdict.reason), verdict.reason


# -- wallpaper -------------------------------------------------------------------------------------------------------
BASE = "/backdrop/screen0/monitorscreen/workspace0"
LAKE = "/home/user/Pictures/lake.png"


def png(color, size=(80, 60), gradient: bool = False) -> bytes:
    img = Image.new("RGB", size, color)
    if gradient:
        for x in range(size[0]):
            for y in range(size[1]):
                img.putpixel((x, y), (x * 3 % 256, y * 4 % 256, 120))
    buf = io.BytesIO()
    img.save(buf, "PNG")
    return buf.getvalue()


PICTURE = png("white", gradient=True)


def test_the_asked_picture_as_wallpaper_passes():
    listing = {f"{BASE}/last-image": LAKE, f"{BASE}/image-style": "5"}
    verdict = check_wallpaper_picture(listing, LAKE, {LAKE: PICTURE}, PICTURE)
    assert verdict.passed and "mean difference 0.0" in verdict.reason
    # a faithful copy of the picture elsewhere shows the same wallpaper
    copy = "/home/user/Pictures/wallpapers/lake.png"
    assert check_wallpaper_picture({f"{BASE}/last-image": copy}, LAKE, {copy: PICTURE}, PICTURE).passed


def test_a_replaced_picture_another_picture_or_no_style_fail():
    listing = {f"{BASE}/last-image": LAKE, f"{BASE}/image-style": "5"}
    grey = check_wallpaper_picture(listing, LAKE, {LAKE: png("#808080")}, PICTURE)
    assert not grey.passed and "other pixels" in grey.reason
    other = "/home/user/Pictures/other.png"
    wrong = check_wallpaper_picture({f"{BASE}/last-image": other}, LAKE, {other: png("#2a6f97")}, PICTURE)
    assert not wrong.passed and other in wrong.reason
    none_style = check_wallpaper_picture({**listing, f"{BASE}/image-style": "0"}, LAKE, {LAKE: PICTURE}, PICTURE)
    assert not none_style.passed and "only the colour shows" in none_style.reason
    small = check_wallpaper_picture(listing, LAKE, {LAKE: png("white", (40, 30))}, PICTURE)
    assert not small.passed and "40x30" in small.reason
    svg = check_wallpaper_picture(listing, LAKE, {LAKE: b"<svg/>"}, PICTURE)
    assert not svg.passed and "no readable picture" in svg.reason


def test_without_a_baseline_the_wallpaper_must_be_the_path():
    listing = {f"{BASE}/last-image": LAKE, f"{BASE}/image-style": "5"}
    assert check_wallpaper_picture(listing, LAKE, {}, None).passed
    assert not check_wallpaper_picture({f"{BASE}/last-image": "/x.png"}, LAKE, {}, None).passed


def test_the_wallpaper_evaluator_reads_xfconf_and_pulls_the_shown_file():
    listing = f"{BASE}/image-style  5\n{BASE}/last-image   {LAKE}\n"
    state = SimpleNamespace(run=lambda cmd, platform=None: SimpleNamespace(returncode=0, stdout=listing),
                            baseline=lambda path, platform=None: PICTURE if path == LAKE else None,
                            pull=lambda path, platform=None: png("#808080") if path == LAKE else None)
    verdict = settings.wallpaper_is(state, LAKE)
    assert not verdict.passed and "other pixels" in verdict.reason


# -- image viewer (its deletion: `folders.file_deleted`, tested in test_evaluators_files.py) -------------------------
@pytest.mark.parametrize("text", ["731x417", "731x417\n", " 731 x 417 ", "731×417", "731X417 px"])
def test_the_size_as_width_x_height_passes(text):
    assert check_size_report(text, 731, 417).passed


@pytest.mark.parametrize("text, found", [
    ("417x731", "swapped"),
    ("731", "not WIDTHxHEIGHT alone"),
    ("scan_01.png PNG 731x417 731x417+0+0 8-bit sRGB", "not WIDTHxHEIGHT alone"),
    ("1024x768", "1024x768"),
    (None, "no file"),
])
def test_a_swapped_partial_or_noisy_size_fails(text, found):
    verdict = check_size_report(text, 731, 417)
    assert not verdict.passed and found in verdict.reason, verdict.reason


ORIGINAL = png("white", gradient=True)


def saved_copy(copy: bytes | None, now: bytes | None):
    """file_copied on a device holding the copy `copy` at /d/backup.png and the original `now` at /p/receipt.png
    (None: no file), the original as set up being ORIGINAL."""
    files = {p: d for p, d in (("/d/backup.png", copy), ("/p/receipt.png", now)) if d is not None}
    return get_evaluator("file_copied")(state_with(files, baselines={"/p/receipt.png": ORIGINAL}),
                                        path="/d/backup.png", source="/p/receipt.png")


def test_a_byte_identical_copy_with_the_original_kept_passes():
    assert saved_copy(ORIGINAL, ORIGINAL).passed


@pytest.mark.parametrize("copy, now, found", [
    (png("white"), png("white"), "the original changed"),        # junk written over both: they agree, not the picture
    (ORIGINAL[:-1] + b"\x00", ORIGINAL, "copy holds other content"),  # re-encoded or altered
    (ORIGINAL, None, "the original gone"),                       # the original moved to the copy's name
    (None, ORIGINAL, "no copy"),
])
def test_a_copy_of_junk_a_changed_copy_or_a_move_fails(copy, now, found):
    verdict = saved_copy(copy, now)
    assert not verdict.passed and found in verdict.reason, verdict.reason


# -- VLC preferences ---------------------------------------------------------------------------------------------
FOLDER = "/home/user/Desktop/captures"
SETUP_VLCRC = "[qt]\nqt-privacy-ask=0\n"
# the lines of the vlcrc VLC's Save writes (87 kB, all defaults as comments), around the snapshot options
SAVED_VLCRC = ("\ufeff###\n### vlc 3.0.18\n###\n[qt] # Qt interface\nqt-privacy-ask=0\n[core] # core program\n"
               "# Video snapshot directory (or filename) (string)\nsnapshot-path=/home/user/Desktop/captures\n\n"
               "# Video snapshot file prefix (string)\n#snapshot-prefix=vlcsnap-\n\n"
               "# Video snapshot format (string)\n#snapshot-format=png\n\nvout=any\n")
SNAP_KEYS = ["snapshot-prefix", "snapshot-format", "snapshot-sequential", "snapshot-preview"]


def test_vlcrc_is_read_as_vlc_reads_it():
    values, unread = vlcrc_values(SAVED_VLCRC + "snapshot-format = jpg\n")
    assert values["snapshot-path"] == FOLDER and "snapshot-prefix" not in values and values["vout"] == "any"
    assert unread == ["snapshot-format = jpg"]


@pytest.mark.parametrize("text", [SAVED_VLCRC, SETUP_VLCRC + f"[core]\nsnapshot-path={FOLDER}\n",
                                  SETUP_VLCRC + f"snapshot-path={FOLDER}/\n"])
def test_the_folder_saved_by_vlc_passes(text):
    verdict = check_vlc_option(text, "snapshot-path", FOLDER, SETUP_VLCRC, SNAP_KEYS, folder_exists=True)
    assert verdict.passed, verdict.reason


@pytest.mark.parametrize("text, exists, found", [
    (SETUP_VLCRC + f"snapshot-path = {FOLDER}\n", True, "VLC does not read the line"),
    (SETUP_VLCRC + "snapshot-path=/home/user/Desktop\n", True, "snapshot-path=/home/user/Desktop"),
    (SETUP_VLCRC + f"#snapshot-path={FOLDER}\n", True, "snapshot-path unset"),
    (SETUP_VLCRC + f"snapshot-path={FOLDER}\nsnapshot-prefix=\nsnapshot-format=jpg\n", True,
     "snapshot-format: default → jpg"),
    (SETUP_VLCRC + f"snapshot-path={FOLDER}\n", False, "does not exist"),
    (None, True, "no preferences file"),
])
def test_an_unread_line_the_wrong_folder_or_other_changes_fail(text, exists, found):
    verdict = check_vlc_option(text, "snapshot-path", FOLDER, SETUP_VLCRC, SNAP_KEYS, folder_exists=exists)
    assert not verdict.passed and found in verdict.reason, verdict.reason


# -- the evaluators around the checks, on a stand-in device ----------------------------------------------------------
class FakeDevice:
    """Answers the commands the evaluators run: `responses` maps a command's start to (returncode, stdout); the
    file-facts script is answered from `files`."""

    platform = "ubuntu"

    def __init__(self, responses: dict[str, tuple[int, str]], files: dict[str, bytes] | None = None,
                 baselines: dict[str, bytes] | None = None) -> None:
        self.responses, self.files, self.baselines, self.commands = responses, files or {}, baselines or {}, []

    def run(self, command: str, platform=None, user=None):
        self.commands.append(command)
        facts = posix_facts_reply(command, self.files)
        if facts is not None:
            return SimpleNamespace(returncode=0, stdout=facts, stderr="")
        for start, (rc, out) in self.responses.items():
            if command.startswith(start):
                return SimpleNamespace(returncode=rc, stdout=out, stderr="")
        return SimpleNamespace(returncode=1, stdout="", stderr="")

    def exists(self, path, platform=None):
        return path in self.files

    def pull(self, path, platform=None):
        return self.files.get(path)

    def pull_text(self, path, platform=None):
        data = self.files.get(path)
        return None if data is None else data.decode()

    def baseline(self, path, platform=None):
        return self.baselines.get(path)


def test_setting_is_reads_the_type_from_the_xfconf_daemon():
    dump = '{"/general/click_to_focus": ["s", "false"], "/general/focus_new": ["b", true]}'
    state = FakeDevice({"python3 -c": (0, dump)})
    verdict = settings.setting_is(state, "xfwm4", "/general/click_to_focus", expected="false", type="bool")
    assert not verdict.passed and "another type" in verdict.reason
    state = FakeDevice({"python3 -c": (0, dump.replace('["s", "false"]', '["b", false]'))})
    assert settings.setting_is(state, "xfwm4", "/general/click_to_focus", expected="false", type="bool").passed


def test_workspace_names_come_back_typed_from_the_daemon():
    dump = '{"/general/workspace_count": ["i", 6], "/general/workspace_names": ["av", ["Main", "Workspace 2"]]}'
    live = settings.live_channel(FakeDevice({"python3 -c": (0, dump)}), "xfwm4")
    assert live["/general/workspace_count"] == ("int", 6)
    assert live["/general/workspace_names"] == ("array", [("string", "Main"), ("string", "Workspace 2")])


def test_theme_is_dark_looks_in_the_users_themes_first():
    css = "@define-color theme_bg_color #202020;\n"
    state = FakeDevice({"xfconf-query": (0, "Carbon\n")},
                       files={"/home/user/.themes/Carbon/gtk-3.0/gtk.css": css.encode()})
    verdict = settings.theme_is_dark(state)
    assert verdict.passed and "/home/user/.themes/Carbon" in verdict.reason


def test_one_evaluator_checks_the_asked_change_and_what_must_stay():
    """The untouched device fails (the asked change missing), the careful change passes, and the change with
    damage to settings not asked fails naming them — all in the one evaluator, as the gate needs."""
    user_xml = f"{settings.USER_XFCONF}/xfwm4.xml"
    args = dict(channel="xfwm4", property="/general/click_to_focus", expected="false", type="bool",
                unchanged=FOCUS_PROPS)

    def device(**live):
        props = {"/general/click_to_focus": ["b", True], "/general/focus_new": ["b", True],
                 "/general/focus_delay": ["i", 250], "/general/raise_on_focus": ["b", False], **live}
        return FakeDevice({"python3 -c": (0, json.dumps(props))}, baselines={user_xml: XFWM4_XML.encode()})

    untouched = settings.setting_is(device(), **args)
    assert not untouched.passed and "True (bool)" in untouched.reason
    careful = settings.setting_is(device(**{"/general/click_to_focus": ["b", False]}), **args)
    assert careful.passed and "all unchanged" in careful.reason
    damaged = settings.setting_is(device(**{"/general/click_to_focus": ["b", False],
                                           "/general/raise_on_focus": ["b", True]}), **args)
    assert not damaged.passed and "/general/raise_on_focus: False (bool) → True (bool)" in damaged.reason
    both = settings.setting_is(device(**{"/general/focus_new": ["b", False]}), **args)
    assert not both.passed and "True (bool)" in both.reason and "/general/focus_new" in both.reason
