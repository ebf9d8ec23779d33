"""Checks of desktop settings, read from XFCE's settings store (xfconf) on the device.

Settings made in the Settings applications (Appearance, Mouse, Workspaces, Desktop), by an image viewer's
"Set as wallpaper" or with `xfconf-query` all land in xfconf, so the checks read the values there — with their
types (the dialogs write a boolean or an integer; the window manager ignores a value of another type) and, where a
running program shows the effect, the effect itself (the number of workspaces the window manager made, the pixels
of the wallpaper). What the task did not ask to change is compared with the channel's XML files as they were
right after set-up (the template lists them under `baseline`: the user's file, which overrides the system one).
"""

from __future__ import annotations

import io
import json
import posixpath
import re
import shlex
import time
import xml.etree.ElementTree as ET
from typing import Any

from PIL import Image, ImageChops, ImageStat

from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.state import FinalState, as_text

BACKDROP = "xfce4-desktop"
WORKSPACE0_IMAGE = re.compile(r"^/backdrop/screen0/monitor[^/]+/workspace0/last-image$")
USER_XFCONF = "/home/user/.config/xfce4/xfconf/xfce-perchannel-xml"
SYSTEM_XFCONF = "/etc/xdg/xfce4/xfconf/xfce-perchannel-xml"

# Prints every property of an xfconf channel with its GVariant type, as JSON {property: [type, value]}, read from
# the xfconf daemon over D-Bus (`xfconf-query -lv` loses the types and arrays).
XFCONF_DUMP = r"""python3 -c '
import json, sys
from gi.repository import Gio, GLib
bus = Gio.bus_get_sync(Gio.BusType.SESSION, None)
reply = bus.call_sync("org.xfce.Xfconf", "/org/xfce/Xfconf", "org.xfce.Xfconf", "GetAllProperties",
                      GLib.Variant("(ss)", (sys.argv[1], "/")), None, 0, -1, None)
props = reply.get_child_value(0)
out = {}
for i in range(props.n_children()):
    entry = props.get_child_value(i)
    value = entry.get_child_value(1).get_variant()
    out[entry.get_child_value(0).get_string()] = [value.get_type_string(), value.unpack()]
print(json.dumps(out))
' """

# xfconf XML types and GVariant type strings → one kind per comparable family
KINDS = {"bool": "bool", "b": "bool", "int": "int", "uint": "int", "int64": "int", "uint64": "int", "i": "int",
         "u": "int", "x": "int", "t": "int", "n": "int", "q": "int", "y": "int", "uchar": "int", "char": "int",
         "double": "double", "float": "double", "d": "double", "string": "string", "s": "string",
         "array": "array", "av": "array"}


def xfconf_value(state: FinalState, channel: str, prop: str, platform: str | None = None) -> str | None:
    """The value of an xfconf property as `xfconf-query` prints it, or None when it is not set."""
    res = state.run(f"xfconf-query -c {shlex.quote(channel)} -p {shlex.quote(prop)}", platform)
    return res.stdout.strip() if res.returncode == 0 else None


def typed(kind_name: str, value: Any) -> tuple[str, Any]:
    """(kind, value) of an xfconf value: kind is bool/int/double/string/array; arrays hold typed items."""
    kind = KINDS.get(kind_name, kind_name)
    if kind == "array":
        return kind, [typed(k, v) for k, v in value]
    if kind == "bool" and isinstance(value, str):
        return kind, value.strip().lower() == "true"
    if kind == "int":
        return kind, int(value)
    if kind == "double":
        return kind, float(value)
    return kind, value


def live_channel(state: FinalState, channel: str, platform: str | None = None) -> dict[str, tuple[str, Any]]:
    """Every property of `channel` as the xfconf daemon holds it now: {property: (kind, value)}."""
    res = state.run(XFCONF_DUMP + shlex.quote(channel), platform)
    if res.returncode != 0:
        raise RuntimeError(f"could not read xfconf channel {channel}: {res.stderr.strip()[-300:]}")
    out = {}
    for prop, (sig, value) in json.loads(res.stdout).items():
        if sig == "av":  # unpack() gives the items' values: type them from their python type
            value = [("b" if isinstance(v, bool) else "i" if isinstance(v, int) else
                      "d" if isinstance(v, float) else "s", v) for v in value]
        out[prop] = typed(sig, value)
    return out


def xfconf_xml(text: str) -> dict[str, tuple[str, Any]]:
    """The properties of an xfconf channel XML file: {"/a/b": (kind, value)}; "empty" ones are left out."""
    out: dict[str, tuple[str, Any]] = {}

    def walk(node: ET.Element, prefix: str) -> None:
        for prop in node.findall("property"):
            path = f"{prefix}/{prop.get('name')}"
            kind = prop.get("type", "empty")
            if kind == "array":
                out[path] = ("array", [typed(v.get("type", "string"), v.get("value", ""))
                                       for v in prop.findall("value")])
            elif kind != "empty":
                out[path] = typed(kind, prop.get("value", ""))
            walk(prop, path)

    walk(ET.fromstring(text), "")
    return out


def baseline_channel(state: FinalState, channel: str, platform: str | None = None) -> dict[str, tuple[str, Any]] | None:
    """The channel as it was right after set-up, from the baselines of its system and user XML files (the user's
    values override the system's); None when the template captured neither."""
    system = state.baseline(f"{SYSTEM_XFCONF}/{channel}.xml", platform)
    user = state.baseline(f"{USER_XFCONF}/{channel}.xml", platform)
    if system is None and user is None:
        return None
    merged: dict[str, tuple[str, Any]] = {}
    for data in (system, user):
        if data is not None:
            merged.update(xfconf_xml(as_text(data)))
    return merged


def show(value: tuple[str, Any] | None) -> str:
    if value is None:
        return "unset"
    kind, v = value
    if kind == "array":
        return "[" + ", ".join(show(x) for x in v) + "]"
    return f"{v!r} ({kind})"


def check_setting(value: str | None, name: str, expected: str | None = None, pattern: str | None = None) -> Verdict:
    """`value` equals `expected` (case-insensitively, trimmed) or matches the regular expression `pattern`."""
    want = f"{name} = {expected!r}" if pattern is None else f"{name} matching /{pattern}/"
    if value is None:
        return Verdict.check(False, want, "the setting unset")
    ok = (value.strip().casefold() == str(expected).strip().casefold() if pattern is None
          else re.search(pattern, value) is not None)
    return Verdict.check(ok, want, repr(value))


def check_typed_setting(value: tuple[str, Any] | None, name: str, expected: str, kind: str) -> Verdict:
    """`value` is of `kind` (what the settings dialog writes and the program reads) and equals `expected`."""
    kind = KINDS.get(kind, kind)
    want = f"{name} = {expected} ({kind}, as the settings dialog writes it)"
    if value is None:
        return Verdict.check(False, want, "the setting unset")
    if value[0] != kind:
        return Verdict.check(False, want, f"{show(value)}: a value of another type, which the program ignores")
    try:
        ok = value == typed(kind, expected)
    except ValueError:
        ok = False
    return Verdict.check(ok, want, show(value))


@evaluator("setting_is")
def setting_is(state: FinalState, channel: str, property: str, expected: str | None = None,
               pattern: str | None = None, type: str | None = None, unchanged: list[str] | None = None,
               platform: str | None = None) -> Verdict:
    """The xfconf property `channel` `property` equals `expected` (or matches `pattern`); with `type` (bool, int,
    string, ...), also of that type — the type the settings dialog writes (a string "false" where the window
    manager reads a boolean changes nothing); and the properties `unchanged` of the channel, which the task did
    not ask to change, still have their values from right after set-up (see `with_unchanged`)."""
    if (expected is None) == (pattern is None):
        return Verdict(False, "setting_is needs exactly one of `expected` and `pattern`")
    name = f"{channel}:{property}"
    if type is not None and expected is not None:
        verdict = check_typed_setting(live_channel(state, channel, platform).get(property), name, str(expected), type)
    else:
        verdict = check_setting(xfconf_value(state, channel, property, platform), name,
                                None if expected is None else str(expected), pattern)
    return with_unchanged(verdict, state, channel, unchanged, platform)


def check_unchanged(live: dict[str, tuple[str, Any]], base: dict[str, tuple[str, Any]] | None,
                    properties: list[str], channel: str) -> Verdict:
    """Each of `properties` has the value (and type) it had after set-up."""
    want = f"{channel} {', '.join(properties)} as after set-up"
    if base is None:
        return Verdict.check(False, want, f"no baseline of the {channel} channel (list its XML files under "
                                          "`baseline` in the template)")
    changed = [f"{p}: {show(base.get(p))} → {show(live.get(p))}" for p in properties if live.get(p) != base.get(p)]
    return Verdict.check(not changed, want, "changed " + "; ".join(changed) if changed else "all unchanged")


def combine(verdict: Verdict, unchanged: Verdict) -> Verdict:
    """The asked change's verdict and the unchanged-settings verdict as one: both must pass, the reason names
    each failure."""
    if verdict.passed and unchanged.passed:
        return Verdict(True, f"{verdict.reason}; {unchanged.reason}")
    return Verdict(False, "; and ".join(v.reason for v in (verdict, unchanged) if not v.passed))


def with_unchanged(verdict: Verdict, state: FinalState, channel: str, properties: list[str] | None,
                   platform: str | None = None) -> Verdict:
    """`verdict` of the asked change, combined with the check that the xfconf `properties` of `channel` (those the
    task did not ask to change) still have their values from right after set-up — from the channel's XML files,
    which the template lists under `baseline`. One evaluator checks both, so that it fails on the untouched
    device like every evaluator must."""
    if not properties:
        return verdict
    return combine(verdict, check_unchanged(live_channel(state, channel, platform),
                                            baseline_channel(state, channel, platform), properties, channel))


# -- dark theme ---------------------------------------------------------------------------------------------
# GTK's built-in stylesheets a theme may import instead of defining its colours (window background)
GTK_RESOURCES = {"gtk-contained-dark.css": "#353535", "gtk-contained.css": "#f6f5f4",
                 "HighContrastInverse": "#000000", "HighContrast": "#ffffff"}
NAMED_COLOURS = {"black": "#000000", "white": "#ffffff", "gray": "#bebebe", "grey": "#bebebe"}
DARK_LIGHTNESS = 50.0  # CIE L* of the window background below which a theme is dark (0 black … 100 white)


def theme_dirs(name: str) -> list[str]:
    """Where GTK looks for the theme `name`, in its order."""
    return [f"/home/user/.local/share/themes/{name}", f"/home/user/.themes/{name}", f"/usr/local/share/themes/{name}",
            f"/usr/share/themes/{name}"]


def parse_colour(text: str, defines: dict[str, str] | None = None, depth: int = 0) -> tuple[int, int, int] | None:
    """An sRGB colour from CSS/gtkrc text: #rgb, #rrggbb, #rrrrggggbbbb, rgb()/rgba(), a few names, or @name of a
    `@define-color`; None for what it cannot evaluate (shade(), mix(), ...)."""
    text = text.strip().rstrip(";").strip()
    if text.startswith("@") and defines is not None and depth < 8:
        ref = defines.get(text[1:])
        return None if ref is None else parse_colour(ref, defines, depth + 1)
    text = NAMED_COLOURS.get(text.lower(), text)
    m = re.fullmatch(r"#([0-9a-fA-F]+)", text)
    if m:
        h = m.group(1)
        if len(h) == 3:
            return tuple(int(c * 2, 16) for c in h)  # type: ignore[return-value]
        if len(h) in (6, 12):
            n = len(h) // 3
            return tuple(int(h[i * n:i * n + 2], 16) for i in range(3))  # type: ignore[return-value]
        return None
    m = re.fullmatch(r"rgba?\(\s*([\d.]+)(%?)\s*,\s*([\d.]+)(%?)\s*,\s*([\d.]+)(%?)\s*(?:,[^)]*)?\)", text)
    if m:
        vals = []
        for v, pct in ((m.group(1), m.group(2)), (m.group(3), m.group(4)), (m.group(5), m.group(6))):
            vals.append(round(float(v) * 2.55) if pct else round(float(v)))
        return tuple(vals)  # type: ignore[return-value]
    return None


def lightness(rgb: tuple[int, int, int]) -> float:
    """CIE L* (0 black … 100 white) of an sRGB colour."""
    def lin(c: int) -> float:
        c = c / 255
        return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4
    y = 0.2126 * lin(rgb[0]) + 0.7152 * lin(rgb[1]) + 0.0722 * lin(rgb[2])
    return 116 * y ** (1 / 3) - 16 if y > 216 / 24389 else y * 24389 / 27


def css_background(css: str) -> tuple[tuple[int, int, int] | None, str]:
    """The window background colour a GTK 3 stylesheet defines, and where it came from."""
    defines = dict(re.findall(r"@define-color\s+([\w-]+)\s+([^;]+);", css))
    for name in ("theme_bg_color", "bg_color", "window_bg_color"):
        if name in defines:
            rgb = parse_colour(defines[name], defines)
            if rgb:
                return rgb, f"@define-color {name}"
    for selector in (r"\.background", r"window"):
        m = re.search(r"(?:^|[}\s,])" + selector + r"\s*\{([^}]*)\}", css)
        if m:
            m2 = re.search(r"background-color\s*:\s*([^;}]+)", m.group(1))
            if m2:
                rgb = parse_colour(m2.group(1), defines)
                if rgb:
                    return rgb, f"{selector.strip(chr(92))} background-color"
    for resource, colour in GTK_RESOURCES.items():
        if re.search(r"@import\s+url\([\"']?resource://[^)]*" + re.escape(resource), css):
            return parse_colour(colour), f"GTK's built-in {resource}"
    return None, ""


def gtkrc_background(gtkrc: str) -> tuple[int, int, int] | None:
    """The `bg_color` of a GTK 2 theme's gtk-color-scheme."""
    text = gtkrc.replace("\\n", "\n")
    m = re.search(r"(?:^|[\s\"])bg_color\s*:\s*(#[0-9a-fA-F]+)", text, re.MULTILINE)
    return parse_colour(m.group(1)) if m else None


def check_theme_dark(name: str | None, files: dict[str, str | None], imports: dict[str, str] | None = None) -> Verdict:
    """The GTK theme `name` is dark: the window background of its GTK 3 stylesheet (else of its GTK 2 gtkrc) has a
    lightness L* below 50. `files` maps each candidate theme file (`theme_dirs(name)` + /gtk-3.0/gtk.css or
    /gtk-2.0/gtkrc) to its text, None when absent; `imports` holds stylesheets a gtk.css imports by file name.
    A theme whose colours cannot be read is judged by its name; one with no GTK part at all (a window-border-only
    theme) leaves applications in GTK's default light style."""
    want = f"a dark GTK theme (window background lightness L* < {DARK_LIGHTNESS:.0f})"
    if not name:
        return Verdict.check(False, want, "no theme set")
    css_path = next((p for p in files if p.endswith("/gtk-3.0/gtk.css") and files[p] is not None), None)
    rc_path = next((p for p in files if p.endswith("/gtk-2.0/gtkrc") and files[p] is not None), None)
    if css_path is None and rc_path is None:
        return Verdict.check(False, want, f"{name!r}, which has no GTK style installed (not an installed theme, or "
                                          "only a window-border theme): applications keep GTK's default light style")
    rgb, source = (None, "")
    if css_path is not None:
        css = files[css_path] or ""
        for imported in (imports or {}).values():  # a theme's own imported files, after its gtk.css
            css += "\n" + imported
        rgb, source = css_background(css)
        source = f"{css_path}: {source}" if rgb else ""
    if rgb is None and rc_path is not None:
        rgb = gtkrc_background(files[rc_path] or "")
        source = f"{rc_path}: bg_color" if rgb else ""
    if rgb is None:
        dark = "dark" in name.lower()
        return Verdict.check(dark, want, f"{name!r}, whose colours could not be read; judged by its name")
    lum = lightness(rgb)
    return Verdict.check(lum < DARK_LIGHTNESS, want, f"{name!r} with background #%02x%02x%02x (L* {lum:.0f}, from "
                         % rgb + f"{source})")


@evaluator("theme_is_dark")
def theme_is_dark(state: FinalState, unchanged: list[str] | None = None, platform: str | None = None) -> Verdict:
    """The desktop's GTK theme (xsettings /Net/ThemeName) is dark, judged from the theme's own colours: any
    installed dark theme passes whatever its name (Adwaita-dark, Greybird-dark, a dark theme in ~/.themes), a
    theme named "-dark" that does not exist or is light fails; and the xsettings `unchanged` keep their values
    from right after set-up."""
    name = xfconf_value(state, "xsettings", "/Net/ThemeName", platform)
    files: dict[str, str | None] = {}
    imports: dict[str, str] = {}
    if name:
        for d in theme_dirs(name):
            for part in ("gtk-3.0/gtk.css", "gtk-2.0/gtkrc"):
                files[f"{d}/{part}"] = state.pull_text(f"{d}/{part}", platform)
        css_path = next((p for p in files if p.endswith("/gtk-3.0/gtk.css") and files[p] is not None), None)
        if css_path:
            for rel in re.findall(r"@import\s+url\([\"']?(?!resource:)([^\"')]+)", files[css_path] or "")[:5]:
                path = posixpath.normpath(posixpath.join(posixpath.dirname(css_path), rel.removeprefix("file://")))
                text = state.pull_text(path, platform)
                if text is not None:
                    imports[path] = text
    return with_unchanged(check_theme_dark(name, files, imports), state, "xsettings", unchanged, platform)


# -- fonts -----------------------------------------------------------------------------------------------------
REGULAR_WORDS = {"regular", "normal", "book", "roman"}
STYLE_WORDS = REGULAR_WORDS | {"italic", "oblique", "bold", "light", "medium", "thin", "heavy", "black", "semi-bold",
                               "semibold", "demibold", "demi-bold", "ultra-bold", "extra-bold", "ultra-light",
                               "extra-light", "semi-light", "condensed", "expanded", "small-caps", "ultra-condensed",
                               "extra-condensed", "semi-condensed", "semi-expanded", "extra-expanded", "ultra-heavy"}


def parse_font(desc: str) -> tuple[str, frozenset[str], float | None]:
    """(family, style words other than "regular", size in points) of a Pango font description like
    "Sans Bold 10" or "DejaVu Sans Book 12"."""
    words = desc.split()
    size = None
    if words and re.fullmatch(r"\d+(\.\d+)?", words[-1]):
        size = float(words.pop())
    styles = []
    while words and words[-1].lower().rstrip(",") in STYLE_WORDS:
        styles.append(words.pop().lower().rstrip(","))
    family = " ".join(words).rstrip(",")
    return family, frozenset(s for s in styles if s not in REGULAR_WORDS), size


def check_font(value: str | None, size: float, before: str | None, resolved: str | None = None) -> Verdict:
    """The font description `value` keeps the family and style of `before` (the font after set-up; its
    fontconfig resolution `resolved` counts as the same family) and has the point size `size` (exactly)."""
    want = f"the default font kept ({before or 'as after set-up'}) at size {size:g}"
    if value is None:
        return Verdict.check(False, want, "the setting unset")
    family, styles, got_size = parse_font(value)
    problems = []
    if before is not None:
        b_family, b_styles, _ = parse_font(before)
        families = {b_family.casefold()} | ({resolved.casefold()} if resolved else set())
        if family.casefold() not in families:
            problems.append(f"family {family!r} instead of {b_family!r}")
        if styles != b_styles:
            problems.append(f"style {' '.join(sorted(styles)) or 'regular'} instead of "
                            f"{' '.join(sorted(b_styles)) or 'regular'}")
    if got_size is None or abs(got_size - float(size)) > 1e-6:
        problems.append(f"size {got_size:g}" if got_size is not None else "no size")
    return Verdict.check(not problems, want, repr(value) + (": " + "; ".join(problems) if problems else ""))


@evaluator("font_is")
def font_is(state: FinalState, size: float, property: str = "/Gtk/FontName", unchanged: list[str] | None = None,
            platform: str | None = None) -> Verdict:
    """The xsettings font `property` has the point size `size` and still the family and style it had after set-up
    (from the xsettings baseline; the family's fontconfig name, e.g. DejaVu Sans for Sans, counts as kept); and the
    xsettings `unchanged` keep their values from right after set-up."""
    base = baseline_channel(state, "xsettings", platform) or {}
    before = base.get(property, (None, None))[1]
    resolved = None
    if before:
        family = parse_font(str(before))[0]
        res = state.run(f"fc-match -f '%{{family[0]}}' {shlex.quote(family)}", platform)
        resolved = res.stdout.strip() if res.returncode == 0 else None
    verdict = check_font(xfconf_value(state, "xsettings", property, platform), float(size),
                         None if before is None else str(before), resolved)
    return with_unchanged(verdict, state, "xsettings", unchanged, platform)


# -- workspaces ------------------------------------------------------------------------------------------------
def check_workspaces(value: tuple[str, Any] | None, desktops: int | None, count: int,
                     names: list[str] | None = None, names_before: list[str] | None = None) -> Verdict:
    """xfwm4's workspace_count is the integer `count`, the window manager shows `desktops` = `count` workspaces,
    and the names of the workspaces kept (the first min(count, before) ones) are unchanged."""
    want = f"{count} workspaces (xfwm4 workspace_count, an integer, and the window manager's desktops)"
    problems = []
    if value != ("int", int(count)):
        problems.append(f"workspace_count {show(value)}")
    if desktops != int(count):
        problems.append(f"the window manager shows {desktops if desktops is not None else 'no'} workspaces")
    if names is not None and names_before is not None:
        keep = min(int(count), len(names_before))
        renamed = [f"{b!r} → {n!r}" for b, n in zip(names_before[:keep], (names + [None] * keep)[:keep]) if b != n]
        if renamed:
            problems.append("renamed " + ", ".join(renamed))
    return Verdict.check(not problems, want, "; ".join(problems) if problems else f"{count} workspaces, names kept")


def root_cardinal(state: FinalState, prop: str, platform: str | None = None) -> int | None:
    m = re.search(r"=\s*(\d+)", state.run(f"xprop -root {prop}", platform).stdout)
    return int(m.group(1)) if m else None


@evaluator("workspace_count_is")
def workspace_count_is(state: FinalState, count: int, platform: str | None = None) -> Verdict:
    """The window manager has `count` workspaces: xfwm4's workspace_count is that integer, the root window's
    _NET_NUMBER_OF_DESKTOPS says so (a value xfwm4 ignores, e.g. a string, leaves it unchanged), and the kept
    workspaces keep their names (against the xfwm4 baseline)."""
    deadline = time.monotonic() + 3.0
    while True:  # the window manager applies a change a moment after xfconf holds it
        live = live_channel(state, "xfwm4", platform)
        desktops = root_cardinal(state, "_NET_NUMBER_OF_DESKTOPS", platform)
        if desktops == int(count) or time.monotonic() > deadline:
            break
        time.sleep(0.5)
    base = baseline_channel(state, "xfwm4", platform)
    names_before = None
    if base is not None and "/general/workspace_names" in base:
        names_before = [v for _, v in base["/general/workspace_names"][1]]
    names_live = live.get("/general/workspace_names")
    names = None if names_live is None else [v for _, v in names_live[1]]
    return check_workspaces(live.get("/general/workspace_count"), desktops, int(count), names, names_before)


# -- wallpaper -------------------------------------------------------------------------------------------------
PIXEL_TOLERANCE = 3.0  # mean absolute difference per channel (0-255) for a picture to count as the same picture


def check_wallpaper(listing: dict[str, str], path: str) -> Verdict:
    """`listing` (xfconf backdrop property → value) shows `path` as the picture of the first workspace of some
    monitor, with an image style other than 0 ("none", which shows only the colour)."""
    shown = []
    for prop, value in listing.items():
        if WORKSPACE0_IMAGE.match(prop):
            style = listing.get(prop.rsplit("/", 1)[0] + "/image-style", "")
            shown.append((value, style))
            if value == path and style.strip() != "0":
                return Verdict.check(True, f"wallpaper {path}", f"{value} (style {style or 'default'})")
    found = ", ".join(f"{v} (style {s or 'default'}" + (": none, only the colour shows)" if s.strip() == "0" else ")")
                      for v, s in shown) or "no wallpaper set"
    return Verdict.check(False, f"wallpaper {path} shown (image style not 'none')", found)


def shown_wallpapers(listing: dict[str, str]) -> list[str]:
    """The pictures shown on the first workspace of each monitor (image style not 'none')."""
    out = []
    for prop, value in listing.items():
        if WORKSPACE0_IMAGE.match(prop):
            style = listing.get(prop.rsplit("/", 1)[0] + "/image-style", "")
            if style.strip() != "0" and value not in out:
                out.append(value)
    return out


def image_difference(data: bytes | None, reference: bytes) -> tuple[float | None, str]:
    """The mean absolute pixel difference (0-255) of two encoded pictures, or None and why they do not compare."""
    if data is None:
        return None, "no file"
    try:
        got, ref = Image.open(io.BytesIO(data)).convert("RGB"), Image.open(io.BytesIO(reference)).convert("RGB")
    except Exception:
        return None, f"no readable picture ({len(data)} bytes)"
    if got.size != ref.size:
        return None, f"a {got.size[0]}x{got.size[1]} picture, not the {ref.size[0]}x{ref.size[1]} one asked"
    diff = ImageStat.Stat(ImageChops.difference(got, ref)).mean
    return sum(diff) / 3, ""


def check_wallpaper_picture(listing: dict[str, str], path: str, files: dict[str, bytes | None],
                            reference: bytes | None) -> Verdict:
    """The desktop shows the asked picture: a wallpaper of `listing` (style not 'none') whose file (`files`: path →
    bytes now) has the pixels of `reference` (the picture at `path` as set up) within PIXEL_TOLERANCE — the
    picture at `path` itself, or a faithful copy of it. Without `reference` the wallpaper must be `path`."""
    by_path = check_wallpaper(listing, path)
    if reference is None:
        return by_path
    want = f"the picture {path} as wallpaper (pixels within {PIXEL_TOLERANCE:g}/255 of it as set up)"
    shown = shown_wallpapers(listing)
    if not shown:
        return Verdict.check(False, want, by_path.reason.split("found ", 1)[-1])
    notes = []
    for shown_path in shown:
        diff, why = image_difference(files.get(shown_path), reference)
        if diff is not None and diff <= PIXEL_TOLERANCE:
            return Verdict.check(True, want, f"{shown_path} (mean difference {diff:.1f})")
        notes.append(f"{shown_path}: " + (why or f"other pixels (mean difference {diff:.1f})"))
    return Verdict.check(False, want, "; ".join(notes))


@evaluator("wallpaper_is")
def wallpaper_is(state: FinalState, path: str, platform: str | None = None) -> Verdict:
    """The desktop shows the picture at `path` as its wallpaper: some monitor's first workspace shows a file whose
    pixels are those `path` had right after set-up (list `path` under `baseline`; a picture replaced at that path
    fails). In a composed task whose picture comes from an earlier subtask there is no baseline: then the
    wallpaper must be the file at `path` (its content cannot be compared)."""
    res = state.run(f"xfconf-query -c {BACKDROP} -lv", platform)
    listing = {}
    for line in res.stdout.splitlines():
        prop, _, value = line.partition(" ")
        listing[prop] = value.strip()
    reference = state.baseline(path, platform)
    files = {p: state.pull(p, platform) for p in shown_wallpapers(listing)} if reference is not None else {}
    return check_wallpaper_picture(listing, path, files, reference)
