"""Checks of the browser's state: Chromium's bookmarks, read from its profile on the device.

Chromium writes its `Bookmarks` file a moment (about 2.5 s) after a change, so the check reads it again for a
few seconds before it decides that a bookmark is missing. Chromium stamps the file with an MD5 checksum of its
bookmarks; a file whose checksum does not match was not written by Chromium (edited by hand while Chromium keeps
its own bookmarks in memory, and overwrites the file at its next change), so it does not count.
"""

from __future__ import annotations

import hashlib
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


ROOT_ORDER = ("bookmark_bar", "other", "synced")  # the order Chromium encodes (and checksums) its roots in


def bookmarks_checksum(data: dict, roots_order: tuple[str, ...] | list[str] = ROOT_ORDER) -> str:
    """The checksum Chromium's bookmark codec computes over a parsed `Bookmarks` file: MD5 over each node, depth
    first through the roots in order (`roots_order`, those present) — its id, its title as UTF-16LE, then "url"
    and the URL, or "folder" and its children."""
    md5 = hashlib.md5()

    def walk(node: dict) -> None:
        md5.update(str(node.get("id", "")).encode())
        md5.update(str(node.get("name", "")).encode("utf-16-le"))
        if node.get("type") == "url":
            md5.update(b"url")
            md5.update(str(node.get("url", "")).encode())
        else:
            md5.update(b"folder")
            for child in node.get("children", []) or []:
                walk(child)

    roots = data.get("roots") or {}
    for key in roots_order:
        if isinstance(roots.get(key), dict):
            walk(roots[key])
    return md5.hexdigest()


def check_bookmark(text: str | None, url: str, name: str | None = None) -> Verdict:
    """A bookmark of `url` (named `name`, when given) is among the bookmarks of `text`, a file Chromium wrote (its
    checksum matches)."""
    want = f"a bookmark of {url}" + (f" named {name!r}" if name else "") + " in Chromium's bookmarks"
    if text is None:
        return Verdict.check(False, want, "no bookmarks file")
    try:
        marks = bookmarks(text)
        data = json.loads(text)
    except (ValueError, AttributeError) as exc:
        return Verdict.check(False, want, f"an unreadable bookmarks file ({exc})")
    ok = any(u == url and (name is None or n.strip() == name.strip()) for n, u in marks)
    if ok and data.get("checksum") != bookmarks_checksum(data):
        return Verdict.check(False, want, f"the bookmark in a file Chromium did not write (checksum "
                                          f"{data.get('checksum')!r} does not match its content): edited by hand")
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
