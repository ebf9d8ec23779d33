"""Checks of the browser's state: the bookmarks of a Chromium-based browser (Chromium on Ubuntu, Microsoft Edge's
favourites on Windows, Chrome on Android: `android.py`), read from its profile on the device.

Chromium writes its `Bookmarks` file a moment (about 2.5 s) after a change, so the check reads it again for a
few seconds before it decides that a bookmark is missing. Chromium stamps the file with an MD5 checksum of its
bookmarks; a file whose checksum does not match was not written by the browser (edited by hand while the browser
keeps its own bookmarks in memory, and overwrites the file at its next change), so it does not count.
"""

from __future__ import annotations

import hashlib
import json
import time

from jarvis_pytest.devices.platforms import PLATFORMS
from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.state import FinalState

BOOKMARKS = "/home/user/.config/chromium/Default/Bookmarks"
EDGE_BOOKMARKS = PLATFORMS["windows"].home + "\\AppData\\Local\\Microsoft\\Edge\\User Data\\Default\\Bookmarks"
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


def chromium_checksums(data: dict) -> set[str]:
    """The checksums a Chromium-based browser may stamp on a parsed `Bookmarks` file: Chromium's (`bookmarks_checksum`
    over bookmark_bar, other and synced), and the same walk going on through the roots a browser adds of its own
    (Edge's `workspaces`) in the file's order, since its codec may count them too."""
    sums = {bookmarks_checksum(data)}
    roots = data.get("roots") or {}
    extra = [k for k in roots if k not in ROOT_ORDER and isinstance(roots[k], dict)]
    if extra:
        sums.add(bookmarks_checksum(data, [*ROOT_ORDER, *extra]))
    return sums


def check_bookmark(text: str | None, url: str, name: str | None = None, browser: str = "Chromium",
                   kind: str = "bookmark") -> Verdict:
    """A bookmark of `url` (named `name`, when given) is among the bookmarks of `text`, a file the browser wrote (its
    checksum is one it computes: `chromium_checksums`). `browser` and `kind` name them in the reason (Edge calls
    bookmarks favourites)."""
    want = f"a {kind} of {url}" + (f" named {name!r}" if name else "") + f" in {browser}'s {kind}s"
    if text is None:
        return Verdict.check(False, want, f"no {kind}s file")
    try:
        marks = bookmarks(text)
        data = json.loads(text)
    except (ValueError, AttributeError) as exc:
        return Verdict.check(False, want, f"an unreadable {kind}s file ({exc})")
    ok = any(u == url and (name is None or n.strip() == name.strip()) for n, u in marks)
    if ok and data.get("checksum") not in chromium_checksums(data):
        return Verdict.check(False, want, f"the {kind} in a file {browser} did not write (checksum "
                                          f"{data.get('checksum')!r} does not match its content): edited by hand")
    return Verdict.check(ok, want, repr(marks[:10]) if marks else f"no {kind}s")


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


@evaluator("edge_favorite_exists")
def edge_favorite_exists(state: FinalState, url: str, name: str | None = None, path: str = EDGE_BOOKMARKS,
                         platform: str | None = None) -> Verdict:
    """Microsoft Edge has a favourite of `url` (named `name`, when given) in any folder, in the `Bookmarks` file of
    its profile (Edge is Chromium: the same JSON and checksum, `check_bookmark`, so a file edited by hand while Edge
    keeps its favourites in memory does not count). Edge writes the file a moment after a change: it is read again
    for a few seconds before a missing favourite is reported."""
    deadline = time.monotonic() + SETTLE_SECONDS
    while True:
        data = state.device(platform).download(path) if state.exists(path, platform) else None
        verdict = check_bookmark(None if data is None else data.decode("utf-8-sig", errors="replace"), url, name,
                                 browser="Edge", kind="favourite")
        if verdict.passed or time.monotonic() > deadline:
            return verdict
        time.sleep(0.5)
