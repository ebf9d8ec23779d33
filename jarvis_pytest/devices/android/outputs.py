"""Parsers of what Android's shell tools print: `content query` rows, the focused window in `dumpsys window`,
`cmd package resolve-activity --brief`, `am start -W`, `wm size` and `settings get`.

`content query` (AOSP `cmds/content/.../Content.java`, QueryCommand) prints one line per row,
`Row: <n> <col>=<value>, <col>=<value>, ...`, with `NULL` for SQL NULL and `BLOB` for blobs, and the values as
they are: a value may itself contain `, ` or `=` or newlines. Rows are therefore split on the column names: with
the projection given, only `, <one of those columns>=` starts a new column (exact); without it, any
`, <identifier>=` does (best effort), and a line not starting with `Row: ` continues the previous value.
A string that is literally `NULL` is indistinguishable from SQL NULL in this format.
"""

from __future__ import annotations

import re

_ROW = re.compile(r"^Row: (\d+) (.*)$")
_FOCUS_WINDOW = re.compile(r"Window\{[0-9a-f]+ (?:u\d+ )?([\w.]+)/([\w.$]+)")
_FOCUS_RECORD = re.compile(r"ActivityRecord\{[0-9a-f]+ (?:u\d+ )?([\w.]+)/([\w.$]+)")


def parse_content_rows(text: str, projection: list[str] | None = None) -> list[dict[str, str | None]]:
    """`content query` output → one dict per row (`NULL` → None). Empty for `No result found.`"""
    rows: list[str] = []
    for line in text.splitlines():
        m = _ROW.match(line)
        if m:
            rows.append(m.group(2))
        elif rows:
            rows[-1] += "\n" + line
    if projection:
        names = "|".join(re.escape(c) for c in projection)
        splitter = re.compile(rf", (?=(?:{names})=)")
    else:
        splitter = re.compile(r", (?=[A-Za-z_][A-Za-z0-9_]*=)")
    out: list[dict[str, str | None]] = []
    for body in rows:
        row: dict[str, str | None] = {}
        parts = splitter.split(body)
        for part in parts:
            key, sep, value = part.partition("=")
            if not sep:  # cannot happen for well-formed output: glue it to the previous value
                if row:
                    last = next(reversed(row))
                    row[last] = f"{row[last]}, {part}"
                continue
            row[key] = None if value == "NULL" else value
        out.append(row)
    return out


def focused_activity(dumpsys_window: str) -> tuple[str, str] | None:
    """(package, activity) of the focused window (`mCurrentFocus`), else of the focused app (`mFocusedApp`),
    from `dumpsys window` output; None when no application window has focus (e.g. the keyguard)."""
    for key in ("mCurrentFocus=", "mFocusedApp="):
        for line in dumpsys_window.splitlines():
            if key not in line:
                continue
            m = _FOCUS_WINDOW.search(line) or _FOCUS_RECORD.search(line)
            if m:
                pkg, act = m.group(1), m.group(2)
                return pkg, (pkg + act if act.startswith(".") else act)
    return None


def resolved_activity(text: str) -> str | None:
    """`cmd package resolve-activity --brief ...` → `package/activity`, or None (`No activity found`)."""
    for line in reversed(text.strip().splitlines()):
        line = line.strip()
        if re.fullmatch(r"[\w.]+/[\w.$]+", line):
            return line
    return None


def am_start_error(text: str) -> str | None:
    """The error `am start` reported (it exits 0 on many of them), or None when it started the activity."""
    for line in text.splitlines():
        s = line.strip()
        if s.startswith(("Error:", "Error type", "Exception", "java.lang.")) or "Exception occurred" in s:
            return s
        if s.startswith("Warning: Activity not started"):
            return None  # already in front: not an error
    return None


def wm_size(text: str) -> tuple[int, int] | None:
    """`wm size` → (width, height) in the natural orientation; the override size when one is set."""
    found = {}
    for line in text.splitlines():
        m = re.search(r"(Physical|Override) size: (\d+)x(\d+)", line)
        if m:
            found[m.group(1)] = (int(m.group(2)), int(m.group(3)))
    return found.get("Override") or found.get("Physical")


def settings_value(text: str) -> str | None:
    """`settings get` output → the value, None when unset (`null`)."""
    value = text.rstrip("\n")
    return None if value == "null" else value
