"""Checks of desktop settings, read from XFCE's settings store (xfconf) on the device.

Settings made in the Settings applications (Appearance, Mouse, Workspaces, Desktop), by an image viewer's
"Set as wallpaper" or with `xfconf-query` all land in xfconf, so the checks read the values there.
"""

from __future__ import annotations

import re
import shlex

from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.state import FinalState

BACKDROP = "xfce4-desktop"
WORKSPACE0_IMAGE = re.compile(r"^/backdrop/screen0/monitor[^/]+/workspace0/last-image$")


def xfconf_value(state: FinalState, channel: str, prop: str, platform: str | None = None) -> str | None:
    """The value of an xfconf property as `xfconf-query` prints it, or None when it is not set."""
    res = state.run(f"xfconf-query -c {shlex.quote(channel)} -p {shlex.quote(prop)}", platform)
    return res.stdout.strip() if res.returncode == 0 else None


def check_setting(value: str | None, name: str, expected: str | None = None, pattern: str | None = None) -> Verdict:
    """`value` equals `expected` (case-insensitively, trimmed) or matches the regular expression `pattern`."""
    want = f"{name} = {expected!r}" if pattern is None else f"{name} matching /{pattern}/"
    if value is None:
        return Verdict.check(False, want, "the setting unset")
    ok = (value.strip().casefold() == str(expected).strip().casefold() if pattern is None
          else re.search(pattern, value) is not None)
    return Verdict.check(ok, want, repr(value))


@evaluator("setting_is")
def setting_is(state: FinalState, channel: str, property: str, expected: str | None = None,
               pattern: str | None = None, platform: str | None = None) -> Verdict:
    """The xfconf property `channel` `property` equals `expected` (or matches `pattern`)."""
    if (expected is None) == (pattern is None):
        return Verdict(False, "setting_is needs exactly one of `expected` and `pattern`")
    return check_setting(xfconf_value(state, channel, property, platform), f"{channel}:{property}",
                         None if expected is None else str(expected), pattern)


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
    found = ", ".join(f"{v} (style {s or 'default'})" for v, s in shown) or "no wallpaper set"
    return Verdict.check(False, f"wallpaper {path} shown (image style not 'none')", found)


@evaluator("wallpaper_is")
def wallpaper_is(state: FinalState, path: str, platform: str | None = None) -> Verdict:
    """The desktop shows the picture at `path` as its wallpaper."""
    res = state.run(f"xfconf-query -c {BACKDROP} -lv", platform)
    listing = {}
    for line in res.stdout.splitlines():
        prop, _, value = line.partition(" ")
        listing[prop] = value.strip()
    return check_wallpaper(listing, path)
