"""The browser checks behind the Chromium templates (no containers): the bookmarks check reads Chromium's
`Bookmarks` JSON in every folder, passes on the file a solved task leaves, fails on the fresh profile's state
saying what it expected and found, and its wrapper waits for Chromium's delayed write only while Chromium runs."""

from __future__ import annotations

import json
from types import SimpleNamespace

import pytest

from jarvis_pytest.evaluators import browser
from jarvis_pytest.evaluators.browser import bookmarks, check_bookmark

URL = "file:///home/user/site/status.html"


def chromium_bookmarks(*marks: tuple[str, str], folder: bool = False) -> str:
    """A `Bookmarks` file in the layout Chromium writes (checksum, roots, version), the marks on the bar or in a
    sub-folder of "Other bookmarks"."""
    nodes = [{"date_added": "13370000000000000", "guid": f"00000000-0000-4000-8000-00000000000{i}", "id": str(i + 4),
              "name": name, "type": "url", "url": url} for i, (name, url) in enumerate(marks)]
    bar = {"children": [] if folder else nodes, "id": "1", "name": "Bookmarks bar", "type": "folder"}
    sub = {"children": nodes, "id": "9", "name": "Work", "type": "folder"}
    other = {"children": [sub] if folder else [], "id": "2", "name": "Other bookmarks", "type": "folder"}
    synced = {"children": [], "id": "3", "name": "Mobile bookmarks", "type": "folder"}
    return json.dumps({"checksum": "0" * 32, "roots": {"bookmark_bar": bar, "other": other, "synced": synced},
                       "version": 1}, indent=3)


def test_bookmarks_are_listed_from_every_root_and_folder():
    text = chromium_bookmarks(("Daily check", URL), ("Menu", "file:///home/user/site/menu.html"), folder=True)
    assert bookmarks(text) == [("Daily check", URL), ("Menu", "file:///home/user/site/menu.html")]
    assert bookmarks(chromium_bookmarks()) == []


def test_bookmark_of_the_page_with_its_name_passes():
    assert check_bookmark(chromium_bookmarks(("Daily check", URL)), URL, "Daily check").passed
    assert check_bookmark(chromium_bookmarks(("Daily check ", URL), folder=True), URL, "Daily check").passed
    assert check_bookmark(chromium_bookmarks(("Service Status", URL)), URL).passed


@pytest.mark.parametrize("text, found", [
    (chromium_bookmarks(("Service Status", URL)), "'Service Status'"),       # the page's title kept as the name
    (chromium_bookmarks(("Daily check", "file:///home/user/site/menu.html")), "menu.html"),  # another page
    (chromium_bookmarks(), "no bookmarks"),                                   # the fresh profile
    (None, "no bookmarks file"),
    ("{not json", "unreadable bookmarks file"),
])
def test_a_missing_or_misnamed_bookmark_fails_naming_expected_and_found(text, found):
    verdict = check_bookmark(text, URL, "Daily check")
    assert not verdict.passed
    assert f"a bookmark of {URL} named 'Daily check'" in verdict.reason and found in verdict.reason


class FakeState:
    """A device whose `Bookmarks` file appears after `appears_after` reads (never when None)."""

    def __init__(self, text: str, appears_after: int | None, chromium_running: bool = True) -> None:
        self.text, self.appears_after, self.running, self.reads = text, appears_after, chromium_running, 0

    def run(self, command: str, platform: str | None = None):
        if command.startswith("pgrep"):
            return SimpleNamespace(returncode=0 if self.running else 1, stdout="42\n" if self.running else "")
        self.reads += 1
        there = self.appears_after is not None and self.reads > self.appears_after
        return SimpleNamespace(returncode=0 if there else 1, stdout=self.text if there else "")


def test_the_wrapper_waits_for_chromiums_delayed_write(monkeypatch):
    monkeypatch.setattr(browser.time, "sleep", lambda s: None)
    state = FakeState(chromium_bookmarks(("Daily check", URL)), appears_after=3)
    assert browser.bookmark_exists(state, URL, "Daily check").passed and state.reads == 4


def test_the_wrapper_gives_up_at_once_when_chromium_is_not_running(monkeypatch):
    monkeypatch.setattr(browser.time, "sleep", lambda s: None)
    state = FakeState("", appears_after=None, chromium_running=False)
    verdict = browser.bookmark_exists(state, URL, "Daily check")
    assert not verdict.passed and "no bookmarks file" in verdict.reason and state.reads == 1


def test_the_wrapper_gives_up_after_the_settle_time(monkeypatch):
    monkeypatch.setattr(browser.time, "sleep", lambda s: None)
    monkeypatch.setattr(browser, "SETTLE_SECONDS", 0.05)
    state = FakeState(chromium_bookmarks(), appears_after=0)
    verdict = browser.bookmark_exists(state, URL, "Daily check")
    assert not verdict.passed and "no bookmarks" in verdict.reason and state.reads >= 1
