"""The browser checks behind the Chromium templates (no containers): the bookmarks check reads Chromium's
`Bookmarks` JSON in every folder, passes on the file a solved task leaves, fails on the fresh profile's state
saying what it expected and found, rejects a file Chromium did not write (its checksum), and its wrapper waits for
Chromium's delayed write only while Chromium runs; Edge's favourites are the same file, judged by the same check.
Then the file checks of the other Chromium templates: a download, a value read off a page, a saved page."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import pytest

from jarvis_pytest.evaluators import browser
from jarvis_pytest.evaluators.browser import bookmarks, bookmarks_checksum, check_bookmark
from jarvis_pytest.evaluators import get_evaluator
from jarvis_pytest.evaluators.desktop import check_answer, check_saved_page
from jarvis_pytest.tasks.instances import materialise
from jarvis_pytest.tasks.model import TaskTemplate
from tests.file_state import state_with

TASKS = Path(__file__).resolve().parents[1] / "tasks"

URL = "file:///home/user/site/status.html"


def chromium_bookmarks(*marks: tuple[str, str], folder: bool = False, checksum: str | None = None) -> str:
    """A `Bookmarks` file in the layout Chromium writes (checksum, roots, version), the marks on the bar or in a
    sub-folder of "Other bookmarks", with Chromium's checksum (or `checksum`)."""
    nodes = [{"date_added": "13370000000000000", "guid": f"00000000-0000-4000-8000-00000000000{i}", "id": str(i + 4),
              "name": name, "type": "url", "url": url} for i, (name, url) in enumerate(marks)]
    bar = {"children": [] if folder else nodes, "id": "1", "name": "Bookmarks bar", "type": "folder"}
    sub = {"children": nodes, "id": "9", "name": "Work", "type": "folder"}
    other = {"children": [sub] if folder else [], "id": "2", "name": "Other bookmarks", "type": "folder"}
    synced = {"children": [], "id": "3", "name": "Mobile bookmarks", "type": "folder"}
    data = {"checksum": "", "roots": {"bookmark_bar": bar, "other": other, "synced": synced}, "version": 1}
    data["checksum"] = bookmarks_checksum(data) if checksum is None else checksum
    return json.dumps(data, indent=3)


# The file Chromium 150 wrote in the device after the oracle's Ctrl+D (ids, names and URL as it wrote them).
CHROMIUM_WRITTEN = {
    "checksum": "95a9a3cca9246c8eb47ace953dfe89d9",
    "roots": {
        "bookmark_bar": {"children": [], "date_added": "13439968302560326", "date_last_used": "0",
                         "date_modified": "0", "guid": "0bc5d13f-2cba-5d74-951f-3f233fe6c908", "id": "1",
                         "name": "Bookmarks bar", "type": "folder"},
        "other": {"children": [{"date_added": "13439968311080374", "date_last_used": "0",
                                "guid": "d7751673-0176-4ca0-969b-ca8d8bfb4f8d", "id": "5",
                                "meta_info": {"power_bookmark_meta": ""}, "name": "Daily check", "type": "url",
                                "url": URL}],
                  "date_added": "13439968302560326", "date_last_used": "0", "date_modified": "13439968311080374",
                  "guid": "82b081ec-3dd3-529c-8475-ab6c344590dd", "id": "2", "name": "Other bookmarks",
                  "type": "folder"},
        "synced": {"children": [], "date_added": "13439968302560326", "date_last_used": "0", "date_modified": "0",
                   "guid": "4cf2e351-0e85-532b-bb37-df045d8f8d0f", "id": "3", "name": "Mobile bookmarks",
                   "type": "folder"}},
    "version": 1,
}


def test_the_checksum_is_chromiums():
    assert bookmarks_checksum(CHROMIUM_WRITTEN) == CHROMIUM_WRITTEN["checksum"]
    assert check_bookmark(json.dumps(CHROMIUM_WRITTEN, indent=3), URL, "Daily check").passed


def test_a_bookmarks_file_written_by_hand_fails():
    verdict = check_bookmark(chromium_bookmarks(("Daily check", URL), checksum="0" * 32), URL, "Daily check")
    assert not verdict.passed and "did not write" in verdict.reason
    # Chromium's bookmark kept under the page title, renamed in the file by hand
    as_chromium_wrote = json.loads(json.dumps(CHROMIUM_WRITTEN))
    as_chromium_wrote["roots"]["other"]["children"][0]["name"] = "Service Status"
    as_chromium_wrote["checksum"] = bookmarks_checksum(as_chromium_wrote)
    assert check_bookmark(json.dumps(as_chromium_wrote), URL).passed
    as_chromium_wrote["roots"]["other"]["children"][0]["name"] = "Daily check"
    verdict = check_bookmark(json.dumps(as_chromium_wrote), URL, "Daily check")
    assert not verdict.passed and "edited by hand" in verdict.reason


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
    (chromium_bookmarks(("Daily check", "file:///home/user/site/index.html")), "index.html"),  # the right title
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


# -- Edge's favourites: the same file, with roots of Edge's own -----------------------------------------------------
def edge_bookmarks(marks: list[tuple[str, str]], extra_root: bool = False, checksum: str | None = None) -> bytes:
    folder = lambda name, kids, i: {"children": kids, "id": str(i), "name": name, "type": "folder"}  # noqa: E731
    kids = [{"id": str(10 + i), "name": n, "type": "url", "url": u} for i, (n, u) in enumerate(marks)]
    data = {"roots": {"bookmark_bar": folder("Favorites bar", kids, 1), "other": folder("Other favorites", [], 2),
                      "synced": folder("Mobile favorites", [], 3)}, "version": 1}
    if extra_root:
        data["roots"]["workspaces"] = folder("Workspaces", [{"id": "50", "name": "w", "type": "url",
                                                              "url": "https://example.com/"}], 4)
    if checksum is None:
        checksum = bookmarks_checksum(data, [*browser.ROOT_ORDER, "workspaces"]) if extra_root \
            else bookmarks_checksum(data)
    data["checksum"] = checksum
    return json.dumps(data, indent=3).encode()


def test_edge_favourite():
    url = "file:///C:/Users/user/Documents/recipes.html"

    def edge(data: bytes | None, name: str | None = "Read later"):
        return check_bookmark(None if data is None else data.decode(), url, name, browser="Edge", kind="favourite")

    assert edge(edge_bookmarks([("Read later", url)])).passed
    assert edge(edge_bookmarks([("Read later", url)], extra_root=True)).passed  # Edge's own roots in its checksum
    assert "edited by hand" in edge(edge_bookmarks([("Read later", url)], checksum="0" * 32)).reason
    assert not edge(edge_bookmarks([("Weekly Recipes", url)])).passed
    assert "no favourites file" in edge(None, None).reason
    tpl = TaskTemplate.model_validate(json.loads((TASKS / "windows" / "edge_add_favorite.json").read_text()))
    sub = materialise(tpl, {"page": "recipes", "title": "Weekly Recipes", "mark": "Read later"})
    bookmarks_file = r"C:\Users\user\AppData\Local\Microsoft\Edge\User Data\Default\Bookmarks"
    state = state_with({bookmarks_file: b"\xef\xbb\xbf" + edge_bookmarks([("Read later", url)])}, "windows")
    assert all(get_evaluator(spec.func)(state, **spec.args).passed for spec in sub.evaluate)


# -- download, value read off a page, saved page ----------------------------------------------------------------------
CSV = b"name,team,score\nAda,red,7\nBo,blue,9\n"


def test_the_downloaded_file_must_be_the_file_offered_as_set_up():
    served, download = "/home/user/site/files/contacts.csv", "/home/user/Downloads/contacts.csv"

    def copied(files: dict[str, bytes]):
        return get_evaluator("file_copied")(state_with(files, baselines={served: CSV}), path=download, source=served)

    assert copied({served: CSV, download: CSV}).passed
    junk = b"name,value\n1,1\n"  # written over the served file and into Downloads alike
    verdict = copied({served: junk, download: junk})
    assert not verdict.passed and "the original changed" in verdict.reason
    half = copied({served: CSV, download: CSV[:20]})
    assert not half.passed and "copy holds other content (20 bytes)" in half.reason
    assert "no copy" in copied({served: CSV}).reason


def test_the_tracking_number_exactly_as_shown_passes():
    assert check_answer("TRK-123456\n", "TRK-123456").passed
    assert check_answer("  TRK-123456  ", "TRK-123456").passed


def test_without_its_prefix_the_number_fails_when_the_instruction_asks_for_it_as_shown():
    verdict = check_answer("123456\n", "TRK-123456")
    assert not verdict.passed and "'123456'" in verdict.reason


def test_with_and_without_the_prefix_pass_when_the_prefix_is_optional():
    assert check_answer("TRK-123456", "TRK-123456", prefix="TRK-").passed
    assert check_answer("123456", "TRK-123456", prefix="TRK-").passed
    assert not check_answer("654321", "TRK-123456", prefix="TRK-").passed


@pytest.mark.parametrize("text", ["Lena Fischer\tTRK-123456", "TRK-654321", "TRK-123456 TRK-654321", None])
def test_a_row_the_decoy_or_extra_text_fails(text):
    assert not check_answer(text, "TRK-123456").passed


PAGE = ('<!doctype html><html><head><meta charset="utf-8"><title>Travel Policy</title></head><body><h1>Travel '
        'Policy</h1><p>Document ref lamp-4821. Keep a copy for offline reading.</p></body></html>')
SAVED = "/home/user/Documents/saved_page.html"


def test_the_page_saved_as_html_passes():
    # Webpage, HTML only: the page's own bytes
    assert check_saved_page(PAGE.encode(), PAGE.encode(), SAVED, "Travel Policy").passed
    # Webpage, Complete: the page re-serialised by Chromium, with its comment and extra markup
    complete = ('<!DOCTYPE html>\n<!-- saved from url=(0034)file:///home/user/site/page.html -->\n<html><head>'
                '<meta http-equiv="Content-Type" content="text/html; charset=UTF-8"><title>Travel Policy</title>'
                '</head>\n<body><h1>Travel Policy</h1><p>Document ref lamp-4821. Keep a copy for offline reading.'
                '</p>\n\n</body></html>')
    assert check_saved_page(complete.encode(), PAGE.encode(), SAVED, "Travel Policy").passed


MHTML = ('From: <Saved by Blink>\r\nSnapshot-Content-Location: file:///home/user/site/page.html\r\n'
         'Subject: Travel Policy\r\nMIME-Version: 1.0\r\nContent-Type: multipart/related;\r\n\ttype="text/html"\r\n\r\n'
         + PAGE.replace("=", "=3D"))


@pytest.mark.parametrize("saved, found", [
    (b"<title>Travel Policy</title>\nDocument ref lamp-4821.\n", "no HTML document"),  # only the expected strings
    (b"<html><title>Travel Policy</title>Document ref lamp-4821.</html>", "text"),  # the same, wrapped in <html>
    (MHTML.encode(), "MHTML"),                                                   # Webpage, Single File
    (b"Travel Policy\nDocument ref lamp-4821. Keep a copy for offline reading.\n", "no HTML document"),
    (b"", "no HTML document"),
    (PAGE.replace("lamp-4821", "lamp-1111").encode(), "text"),
    (None, "no file"),
])
def test_strings_alone_an_archive_or_plain_text_fail(saved, found):
    verdict = check_saved_page(saved, PAGE.encode(), SAVED, "Travel Policy")
    assert not verdict.passed and found in verdict.reason, verdict.reason
