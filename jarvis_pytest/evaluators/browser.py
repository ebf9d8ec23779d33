"""Checks of the browser's state: Chromium's bookmarks, read from its profile on the device.

Chromium writes its `Bookmarks` file a moment (about 2.5 s) after a change, so the check reads it again for a
few seconds before it decides that a bookmark is missing.
"""

from __future__ import annotations

import json
import time

from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.state import FinalState

BOOKMARKS = "/home/user/.config/chromium/Default/Bookmarks"
SETTLE_SECONDS = 6.0


def bookmarks(data: str) -> list[tuple[str, str]]:
    """(name, url) of every bookmark in a Chromium `Bookmarks` JSON text, in every folder."""
    found: list[tuple[str, str]] = []

    def walk(node: dict) -> None:
        if node.get("type") == "url":
            found.append((str(node.get("name", "")), str(node.get("url", ""))))
        for child in node.get("children", []) or []:
            walk(child)

    for root in (json.loads(data).get("roots") or {}).values():
        if isinstance(root, dict):
            walk(root)
    return found


def check_bookmark(text: str | None, url: str, name: str | None = None) -> Verdict:
    """A bookmark of `url` (named `name`, when given) is among the bookmarks of `text`."""
    want = f"a bookmark of {url}" + (f" named {name!r}" if name else "")
    if text is None:
        return Verdict.check(False, want, "no bookmarks file")
    try:
        marks = bookmarks(text)
    except (ValueError, AttributeError) as exc:
        return Verdict.check(False, want, f"an unreadable bookmarks file ({exc})")
    ok = any(u == url and (name is None or n.strip() == name.strip()) for n, u in marks)
    return Verdict.check(ok, want, repr(marks[:10]) if marks else "no bookmarks")


@evaluator("bookmark_exists")
def bookmark_exists(state: FinalState, url: str, name: str | None = None, platform: str | None = None) -> Verdict:
    """Chromium has a bookmark of `url` (with the title `name`, when given), in any folder."""
    deadline = time.monotonic() + SETTLE_SECONDS
    while True:
        res = state.run(f"cat {BOOKMARKS}", platform)
        verdict = check_bookmark(res.stdout if res.returncode == 0 else None, url, name)
        if verdict.passed or time.monotonic() > deadline or not state.run("pgrep -x chromium", platform).stdout:
            return verdict
        time.sleep(0.5)
