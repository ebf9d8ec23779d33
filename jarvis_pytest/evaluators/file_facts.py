"""File facts, the same on every platform: whether a path exists and what it is (file, folder, link), whether the
platform hides it, its size and SHA-256, how many names the file has (hard links), a folder's whole content,
what the desktop's trash holds, and the files of given sizes anywhere under given folders (a search for copies of
known bytes: only files of a size asked are hashed). Evaluators judge these facts; how they are read is this
module's business.

One implementation per platform, chosen by `PlatformSpec.file_facts`: a POSIX shell command run with `state.run`
(Ubuntu; Android's toybox has the same `stat`, `find`, `sha256sum`, `sed` and `head`), or the Windows probe
(`windows_probe.py`). What hides an entry, where the trash is and which files the desktop itself writes into
folders come from `PlatformSpec` (`hidden_by`, `trash`, `shell_files`), never from a branch in an evaluator.
Hidden and system entries are reported like any other: a folder's content is all of it.
"""

from __future__ import annotations

import hashlib
import posixpath
import shlex
from dataclasses import dataclass, replace
from typing import Callable
from urllib.parse import unquote

from jarvis_pytest.devices.platforms import PlatformSpec, spec
from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.evaluators.state import FinalState


@dataclass(frozen=True)
class Entry:
    """What is at one path."""

    exists: bool
    kind: str = "none"          # "file", "dir", "link" (a symbolic link or another reparse point), "other", "none"
    size: int | None = None
    sha256: str | None = None   # regular files
    links: int = 1              # how many names the file has (more than one: hard links)
    hidden: bool = False        # hidden by the platform's convention (`PlatformSpec.hidden_by`)
    system: bool = False        # Windows' system attribute
    head: bytes = b""           # the first bytes of a file named as one of `PlatformSpec.shell_files`
    volume: int | None = None   # the file system it is on (Windows' volume serial number), where it is read

    def describe(self) -> str:
        """'nothing', 'a folder', 'a link', 'a file of N bytes', with ' (hidden)' / ' (hidden, system)'."""
        if not self.exists:
            return "nothing"
        what = {"dir": "a folder", "link": "a link", "file": f"a file of {self.size} bytes"}.get(self.kind,
                                                                                               "something else")
        marks = [m for m, on in (("hidden", self.hidden), ("system", self.system)) if on]
        return what + (f" ({', '.join(marks)})" if marks else "")


NOTHING = Entry(exists=False)


@dataclass
class Facts:
    """What one reading found: `entries` by the path asked; `trees[folder]` its content at every depth by path
    inside it (platform separators; None: no folder there); `trash` (original path, the trashed data) per entry of
    the trash, when asked; `found` the files a search found, by full path, when asked."""

    entries: dict[str, Entry]
    trees: dict[str, dict[str, Entry] | None]
    trash: list[tuple[str, Entry]] | None = None
    found: dict[str, Entry] | None = None


@dataclass(frozen=True)
class Search:
    """Where to look for files and which sizes they must have."""

    roots: tuple[str, ...]
    sizes: tuple[int, ...]


def read_facts(state: FinalState, *, entries: list[str] | tuple[str, ...] = (),
               trees: list[str] | tuple[str, ...] = (), depth: int | None = None, trash: bool = False,
               search: list[str] | tuple[str, ...] = (), sizes: list[int] | tuple[int, ...] = (),
               platform: str | None = None) -> Facts:
    """The facts of `entries` (paths), the content of `trees` (folders; `depth` levels deep, None: all), with
    `trash` the trash's entries, and with `search` (folders) and `sizes` every regular file under those folders,
    at any depth, hidden or not, whose size is one of `sizes` (`Facts.found`; links below a folder are not
    followed, a folder that is no folder is skipped), read on the device in one go."""
    plat = spec(platform or state.platform)
    wanted = Search(tuple(search), tuple(sorted({int(n) for n in sizes}))) if search and sizes else None
    return READERS[plat.file_facts](state, list(entries), list(trees), depth, trash, plat, wanted)


# -- shared conventions ----------------------------------------------------------------------------------------
def shell_made(plat: PlatformSpec, rel: str, entry: Entry) -> bool:
    """Whether `entry` (at `rel` in a folder) is a file the desktop itself writes into folders and nothing else: one
    of `plat.shell_files` by name, hidden and system as Explorer marks them, in that file's format (desktop.ini: an
    INI text of sections and keys only; Thumbs.db: an OLE compound file). A file of that name the agent made, or
    one that holds anything else, counts like any other."""
    name = basename(plat, rel).casefold()
    if name not in plat.shell_files or entry.kind != "file" or not (entry.hidden and entry.system):
        return False
    check = SHELL_FORMATS.get(name)
    return bool(check and check(entry.head, entry.size or 0))


def _is_desktop_ini(head: bytes, size: int) -> bool:
    if size > len(head) or not head:
        return False  # larger than a desktop.ini Explorer writes
    text = head.decode("utf-16") if head.startswith((b"\xff\xfe", b"\xfe\xff")) else head.decode("cp1252")
    lines = [line.strip() for line in text.lstrip("\ufeff").splitlines() if line.strip()]
    return bool(lines) and lines[0].startswith("[") and all(
        (line.startswith("[") and line.endswith("]")) or "=" in line or line.startswith(";") for line in lines)


def _is_ole_file(head: bytes, size: int) -> bool:
    return head.startswith(b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1")


SHELL_FORMATS: dict[str, Callable[[bytes, int], bool]] = {"desktop.ini": _is_desktop_ini, "thumbs.db": _is_ole_file}


def hides_name(plat: PlatformSpec, name: str) -> bool:
    """Whether the platform hides an entry for its name alone (a leading dot where `hidden_by` is the name)."""
    return plat.hidden_by == "dot_name" and basename(plat, name).startswith(".")


def basename(plat: PlatformSpec, path: str) -> str:
    return path.replace("\\", "/").rstrip("/").rsplit("/", 1)[-1] if plat.path_style == "windows" else \
        posixpath.basename(path.rstrip("/"))


def trashinfo_original(text: str) -> str | None:
    """The original path a freedesktop.org `.trashinfo` names (its `Path=`, percent-decoded)."""
    for line in text.splitlines():
        key, _, value = line.partition("=")
        if key.strip() == "Path":
            return unquote(value.strip())
    return None


# -- POSIX: one shell command --------------------------------------------------------------------------------
# f PATH TAG prints "TAG <stat %F>|<links>|<size>|<sha256>|PATH", the path last and as it is (a name with a line
# break is listed by `find` as two lines, each of which stats as nothing: the tree then still holds entries there,
# so they still count; a line that is no such record is skipped).
_POSIX_FUNCTION = r"""f() {
  if s=$(stat -c '%F|%h|%s' -- "$1" 2>/dev/null); then
    case "$s" in regular*) h=$(sha256sum < "$1" 2>/dev/null | cut -c1-64);; *) h=;; esac
  else s='none||'; h=; fi
  printf '%s %s|%s|%s\n' "$2" "$s" "$h" "$1"
}
"""
_KINDS = {"regular file": "file", "regular empty file": "file", "directory": "dir", "symbolic link": "link"}


def posix_script(entries: list[str], trees: list[str], depth: int | None, trash: str | None,
                 search: Search | None = None) -> str:
    """The shell command that prints the facts of `entries`, the content of `trees` (`depth` levels deep), the
    trash at `trash` and the files `search` asks for (`find -H`: a folder given as a link, such as Android's
    /sdcard, is searched; links below it are not followed)."""
    q = shlex.quote
    limit = "" if depth is None else f" -maxdepth {int(depth)}"
    lines = [_POSIX_FUNCTION]
    lines += [f"f {q(p)} E" for p in entries]
    for i, root in enumerate(trees):
        r = q(root.rstrip("/") or "/")
        lines.append(f"if [ -d {r} ] && [ ! -L {r} ]; then echo 'R{i} '; find {r} -mindepth 1{limit} | "
                     f"while IFS= read -r p; do f \"$p\" T{i}; done; fi")
    if trash:
        t = q(trash)
        lines.append(f'for i in {t}/info/*.trashinfo; do [ -f "$i" ] || continue; n=${{i##*/}}; '
                     f'printf "I %s\\n" "$(sed -n "s/^Path=//p" "$i" | head -n 1)"; f {t}/files/"${{n%.trashinfo}}" D; '
                     'done')
    if search:
        sizes = " -o ".join(f"-size {n}c" for n in search.sizes)
        for root in search.roots:
            r = q(root.rstrip("/") or "/")
            lines.append(f"if [ -d {r} ]; then find -H {r} -xdev -type f \\( {sizes} \\) 2>/dev/null | "
                         'while IFS= read -r p; do f "$p" S; done; fi')
    lines.append("true")
    return "\n".join(lines)


def _posix_entry(fields: list[str], hidden: bool) -> Entry:
    kind_text, links, size, sha = (fields + ["", "", "", ""])[:4]
    if kind_text == "none":
        return NOTHING
    kind = _KINDS.get(kind_text, "other")
    return Entry(exists=True, kind=kind, size=int(size) if size.isdigit() else None, sha256=sha or None,
                 links=int(links) if links.isdigit() and kind == "file" else 1, hidden=hidden)


def _read_posix(state: FinalState, entries: list[str], trees: list[str], depth: int | None, trash: bool,
                plat: PlatformSpec, search: Search | None = None) -> Facts:
    res = state.run(posix_script(entries, trees, depth, plat.trash if trash else None, search), plat.name)
    if res.returncode != 0:
        raise InfrastructureError(f"reading file facts failed on the {plat.name} device (exit {res.returncode}): "
                                  f"{(res.stdout + res.stderr)[-500:]}")
    facts = Facts(entries={}, trees={root: None for root in trees}, trash=[] if trash else None,
                  found={} if search else None)
    info: str | None = None
    for line in res.stdout.splitlines():
        tag, _, rest = line.partition(" ")
        if tag.startswith("R") and tag[1:].isdigit():
            facts.trees[trees[int(tag[1:])]] = {}
            continue
        if tag == "I":
            info = unquote(rest.strip())
            continue
        fields = rest.split("|", 4)
        if len(fields) < 5:
            continue
        path = fields[4]
        if tag == "E":
            facts.entries[path] = _hashed(state, path, _posix_entry(fields, hides_name(plat, path)), plat)
        elif tag.startswith("T") and tag[1:].isdigit():
            root = trees[int(tag[1:])].rstrip("/") or "/"
            rel = path[len(root):].lstrip("/") if path.startswith(root + "/") else path
            entry = _posix_entry(fields, hides_name(plat, path))
            # listed but not there: a name `find` printed in two lines; something is there all the same
            tree = facts.trees[trees[int(tag[1:])]]
            if tree is not None:
                tree[rel] = entry if entry.exists else Entry(exists=True, kind="other")
        elif tag == "S" and facts.found is not None:
            entry = _posix_entry(fields, hides_name(plat, path))
            if entry.kind == "file":
                facts.found[path] = _hashed(state, path, entry, plat)
        elif tag == "D" and facts.trash is not None and info:
            facts.trash.append((info, _hashed(state, path, _posix_entry(fields, False), plat)))
            info = None
    for path in entries:
        facts.entries.setdefault(path, NOTHING)
    return facts


def _hashed(state: FinalState, path: str, entry: Entry, plat: PlatformSpec) -> Entry:
    """`entry` with its SHA-256 taken from the pulled bytes where the device's shell had no `sha256sum`."""
    if entry.kind != "file" or entry.sha256:
        return entry
    data = state.pull(path, plat.name)
    if data is None:
        return entry
    return replace(entry, sha256=hashlib.sha256(data).hexdigest())


def _read_windows(state: FinalState, entries: list[str], trees: list[str], depth: int | None, trash: bool,
                  plat: PlatformSpec, search: Search | None = None) -> Facts:
    from jarvis_pytest.evaluators.windows_probe import read_facts as windows_facts

    return windows_facts(state, entries, trees, depth, trash, plat, search)


READERS: dict[str, Callable[[FinalState, list[str], list[str], int | None, bool, PlatformSpec, Search | None],
                            Facts]] = {
    "posix_shell": _read_posix, "windows_probe": _read_windows}
