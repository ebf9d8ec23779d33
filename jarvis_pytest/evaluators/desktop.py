"""File checks of desktop tasks that compare the agent's result with what the task set up (image viewer, browser,
media player; a copy or a download is `folders.file_copied`, a deletion `folders.file_deleted`): originals come
from the template's `baseline` (the file right after set-up, captured on the host, so an agent that overwrites the
original cannot move the goalposts), never from the agent's own output alone.

Each check says in its docstring what it falls back to when there is no baseline (a file an earlier subtask of a
composed task made): then it compares with the file as the device holds it now.
"""

from __future__ import annotations

import re
import shlex
from html.parser import HTMLParser

from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.state import FinalState, as_text


def _short(text: str, limit: int = 120) -> str:
    return repr(text if len(text) <= limit else text[:limit] + "…")


# -- answers written into text files ----------------------------------------------------------------------------
SIZE_RE = re.compile(r"^\s*(\d+)\s*[x×X]\s*(\d+)\s*(?:px|pixels)?\s*$")


def check_size_report(text: str | None, width: int, height: int) -> Verdict:
    """`text` is the size WIDTHxHEIGHT (spaces around the x, a × sign and a trailing "px" accepted) and nothing
    else; the dimensions swapped fail as such."""
    want = f"the size {width}x{height} (WIDTHxHEIGHT) as the only content"
    if text is None:
        return Verdict.check(False, want, "no file")
    m = SIZE_RE.match(text.strip())
    if not m:
        return Verdict.check(False, want, f"{_short(text.strip())}, not WIDTHxHEIGHT alone")
    w, h = int(m.group(1)), int(m.group(2))
    if (w, h) == (int(width), int(height)):
        return Verdict.check(True, want, f"{w}x{h}")
    if (w, h) == (int(height), int(width)) and w != h:
        return Verdict.check(False, want, f"{w}x{h}: width and height swapped")
    return Verdict.check(False, want, f"{w}x{h}")


@evaluator("size_report_is")
def size_report_is(state: FinalState, path: str, width: int, height: int, platform: str | None = None) -> Verdict:
    """The text file `path` reports the picture's size `width`x`height` (known from the task's inputs)."""
    return check_size_report(state.pull_text(path, platform), int(width), int(height))


def check_answer(text: str | None, expected: str, prefix: str | None = None) -> Verdict:
    """`text` (trimmed) is exactly `expected`; with `prefix` (e.g. "TRK-"), also `expected` without that prefix —
    for instructions that do not say whether the prefix belongs to the value."""
    expected = str(expected).strip()
    accepted = [expected]
    if prefix and expected.startswith(prefix):
        accepted.append(expected[len(prefix):])
    want = " or ".join(_short(a) for a in accepted) + " as the only content"
    if text is None:
        return Verdict.check(False, want, "no file")
    got = text.strip()
    return Verdict.check(got in accepted, want, _short(got))


@evaluator("answer_text_is")
def answer_text_is(state: FinalState, path: str, expected: str, prefix: str | None = None,
                   platform: str | None = None) -> Verdict:
    """The text file `path` holds the value `expected` and nothing else (surrounding white space aside); with
    `prefix`, the value without its prefix is accepted too."""
    return check_answer(state.pull_text(path, platform), str(expected), prefix)


# -- saved web pages ---------------------------------------------------------------------------------------------
class _PageText(HTMLParser):
    """The title, the visible text and the elements of an HTML document."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.title, self.text, self.tags, self._in = [], [], set(), []

    def handle_starttag(self, tag, attrs):
        self.tags.add(tag)
        if tag in ("title", "script", "style"):
            self._in.append(tag)

    def handle_endtag(self, tag):
        if self._in and self._in[-1] == tag:
            self._in.pop()

    def handle_data(self, data):
        if not self._in:
            self.text.append(data)
        elif self._in[-1] == "title":
            self.title.append(data)


def page_text(html: str) -> tuple[str, str, set[str]]:
    """(title, visible text, element names) of an HTML document, white space collapsed."""
    p = _PageText()
    p.feed(html)
    p.close()
    norm = lambda parts: " ".join(" ".join(parts).split())  # noqa: E731
    return norm(p.title), norm(p.text), p.tags


MHTML_RE = re.compile(r"^\s*(From: <Saved by|MIME-Version:|Content-Type: multipart/related)", re.IGNORECASE)


def check_saved_page(saved: bytes | None, original: bytes | None, path: str, title: str | None = None) -> Verdict:
    """`saved` is an HTML document (not an MHTML archive or plain text) with the title and the visible text of
    `original` (white space collapsed) — what Chromium's "Webpage, HTML only" (the page's own bytes) or
    "Webpage, Complete" (the page re-serialised) writes."""
    want = f"{path} an HTML copy of the page" + (f" {title!r}" if title else "")
    if saved is None:
        return Verdict.check(False, want, "no file")
    if original is None:
        return Verdict.check(False, want, "no original page to compare with")
    text = as_text(saved)
    if MHTML_RE.match(text):
        return Verdict.check(False, want, "an MHTML archive (Webpage, Single File), not HTML")
    got_title, got_text, tags = page_text(text)
    ref_title, ref_text, _ = page_text(as_text(original))
    if "html" not in tags and "body" not in tags:
        return Verdict.check(False, want, f"no HTML document ({_short(text.strip())})")
    problems = []
    if got_title != ref_title or (title and got_title != " ".join(str(title).split())):
        problems.append(f"title {got_title!r}")
    if got_text != ref_text:
        problems.append(f"text {_short(got_text)} instead of {_short(ref_text)}")
    return Verdict.check(not problems, want, "; ".join(problems) if problems else f"the page ({len(saved)} bytes)")


@evaluator("page_saved")
def page_saved(state: FinalState, path: str, original: str, title: str | None = None,
               platform: str | None = None) -> Verdict:
    """`path` is the web page `original` saved as HTML: the same title and visible text as the page had right after
    set-up (list `original` under `baseline`; without a baseline, the page as it is now)."""
    base = state.baseline(original, platform)
    return check_saved_page(state.pull(path, platform), base if base is not None else state.pull(original, platform),
                            path, title)


# -- VLC preferences ------------------------------------------------------------------------------------------------
def vlcrc_values(text: str | None) -> tuple[dict[str, str], list[str]]:
    """The options VLC reads from a vlcrc text, as VLC reads them: lines `name=value`, no space around the name,
    the value verbatim, sections and comments ignored, the last line of a name winning; and the lines that look
    like options but that VLC does not read (e.g. `name = value`)."""
    values: dict[str, str] = {}
    unread: list[str] = []
    for line in (text or "").lstrip("\ufeff").splitlines():
        if not line or line[0] in "#[":
            continue
        name, sep, value = line.partition("=")
        if not sep:
            continue
        if name != name.strip() or not name:
            unread.append(line)
            continue
        values[name] = value
    return values, unread


def check_vlc_option(text: str | None, key: str, expected: str, before: str | None = None,
                     unchanged: list[str] | None = None, folder_exists: bool | None = None) -> Verdict:
    """VLC reads `key` = `expected` from the vlcrc `text` (a path may end in "/"); the options of `unchanged`
    have the values they had in `before` (the vlcrc after set-up; unset when there was none); and, for a folder
    option, the folder exists (`folder_exists`, None when not checked)."""
    want = f"{key}={expected} in VLC's preferences" + (f" and {', '.join(unchanged)} unchanged" if unchanged else "")
    if text is None:
        return Verdict.check(False, want, "no preferences file")
    values, unread = vlcrc_values(text)
    got = values.get(key)
    norm = (lambda v: v.rstrip("/") or v) if str(expected).startswith("/") else (lambda v: v)
    problems = []
    if got is None:
        near = [line for line in unread if line.split("=", 1)[0].strip() == key]
        problems.append(f"{key} unset" + (f" (VLC does not read the line {near[-1]!r})" if near else ""))
    elif norm(got) != norm(str(expected)):
        problems.append(f"{key}={got}")
    if folder_exists is False:
        problems.append(f"the folder {expected} does not exist")
    old, _ = vlcrc_values(before)
    changed = [f"{k}: {old.get(k, 'default')} → {values.get(k, 'default')}" for k in unchanged or []
               if old.get(k) != values.get(k)]
    if changed:
        problems.append("also changed " + "; ".join(changed))
    return Verdict.check(not problems, want, "; ".join(problems) if problems else f"{key}={got}")


@evaluator("vlc_option_is")
def vlc_option_is(state: FinalState, key: str, expected: str, unchanged: list[str] | None = None,
                  folder: bool = False, path: str = "/home/user/.config/vlc/vlcrc",
                  platform: str | None = None) -> Verdict:
    """VLC's preferences file sets `key` to `expected` in a line VLC reads; the options `unchanged` (the other
    settings of the same panel) keep their values from right after set-up (list `path` under `baseline`; a
    missing baseline file means all were at their defaults); with `folder`, the folder named exists."""
    exists = state.run(f"test -d {shlex.quote(str(expected))}", platform).returncode == 0 if folder else None
    return check_vlc_option(state.pull_text(path, platform), key, str(expected),
                            None if state.baseline(path, platform) is None else as_text(state.baseline(path, platform)),
                            unchanged, exists)
