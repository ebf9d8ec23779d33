"""Map the path segments of a request onto a file under the results root, refusing anything that escapes it."""

from __future__ import annotations

from pathlib import Path
from urllib.parse import unquote


class PathRefused(Exception):
    """A request path that tries to leave the results root (answered with 403)."""


def check_segment(seg: str) -> str:
    """`seg` if it names one entry of a directory; refuses dot segments, separators, NUL and drive letters."""
    if seg in ("", ".", "..") or any(c in seg for c in "/\\\0:"):
        raise PathRefused(f"refused path segment {seg!r}")
    return seg


def split_segments(raw_path: str) -> list[str]:
    """The checked, percent-decoded segments of a raw URL path (decoded first, so `%2e%2e` and `%2F` are caught)."""
    parts = raw_path.split("/")[1:] if raw_path.startswith("/") else raw_path.split("/")
    if parts and parts[-1] == "":  # a trailing slash
        parts.pop()
    try:
        return [check_segment(unquote(part, errors="strict")) for part in parts]
    except UnicodeDecodeError:
        raise PathRefused("path is not valid UTF-8") from None


def resolve_under(root: Path, segments: list[str]) -> Path:
    """`root/segments...`, resolved (symlinks followed); raises PathRefused unless the result is inside `root`."""
    root = root.resolve()
    target = root.joinpath(*(check_segment(s) for s in segments)).resolve()
    if not target.is_relative_to(root):
        raise PathRefused("path leaves the results directory")
    return target
