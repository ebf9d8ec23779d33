"""The Windows Recycle Bin's records, as the probe brings them back: which original path each entry names.

Windows keeps, per deleted file, a record `\\$Recycle.Bin\\<SID>\\$I<id><ext>` (the original path, size and time)
beside the data `$R<id><ext>`. Wine's Explorer uses the Unix user's freedesktop.org trash instead (when
`~/.local/share/Trash` exists), whose `.trashinfo` names a Unix path under the Wine prefix.
"""

from __future__ import annotations

import base64

from jarvis_pytest.evaluators.file_facts import trashinfo_original


def recycle_record_path(record: bytes) -> str | None:
    """The original path a Windows Recycle Bin record (`$I…`) names: version 1 (Vista to 8.1: a fixed 260-character
    field) or version 2 (Windows 10 and later: a length, then the path), both after the size and deletion time."""
    if len(record) < 24:
        return None
    version = int.from_bytes(record[:8], "little")
    if version == 1:
        raw = record[24:24 + 520]
    elif version == 2 and len(record) >= 28:
        n = int.from_bytes(record[24:28], "little")
        raw = record[28:28 + 2 * n]
    else:
        return None
    return raw.decode("utf-16-le", errors="replace").split("\0")[0]


def trashinfo_path(text: str, prefix: str) -> str | None:
    """The Windows path a freedesktop.org `.trashinfo` (Wine's Recycle Bin) names: `Path=` is the Unix path, under
    the Wine prefix's `dosdevices/c:/…` for a drive letter, else reached through `Z:`."""
    unix = trashinfo_original(text)
    if unix is None:
        return None
    marker = (prefix.rstrip("/") + "/dosdevices/") if prefix else "/dosdevices/"
    at = unix.find(marker)
    if at >= 0:
        rest = unix[at + len(marker):]
        return rest[:1].upper() + rest[1:].replace("/", "\\")
    return "Z:" + unix.replace("/", "\\")


def recycled_entries(trash: dict) -> list[tuple[str, dict]]:
    """(the original Windows path, the probe's facts of the recycled data) of every Recycle Bin entry the probe
    found."""
    out = []
    for item in trash.get("xdg", []):
        path = trashinfo_path(item.get("info", ""), trash.get("prefix", ""))
        if path:
            out.append((path, item.get("data") or {}))
    for item in trash.get("recycle", []):
        path = recycle_record_path(base64.b64decode(item.get("info_b64", "")))
        if path:
            out.append((path, item.get("data") or {}))
    return out
