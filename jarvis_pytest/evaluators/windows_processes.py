"""Windows programs, told apart by identity, not by window titles (Task Manager templates).

Right after set-up the processes and top-level windows are recorded (`snapshots.py`): which process showed each
window then. A program that must keep running must be that very process at the end (same process id, same
image, same start time: Windows — and Wine — reuse process ids), still showing its window; a program that must end
must be gone, with no window of its title left. So a program ended and started again, or another program showing
the right title, does not count. Processes and windows are read by the probe (`windows_probe.py`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.evaluators.folders import with_unchanged
from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.snapshots import setup_capture, setup_snapshot, snapshot_key
from jarvis_pytest.evaluators.state import FinalState
from jarvis_pytest.evaluators.windows_probe import probe

SNAPSHOT = "processes"


@dataclass(frozen=True)
class Programs:
    """Processes (pid, ppid, name, started, path) and top-level windows (title, pid, visible) at one moment."""

    processes: list[dict]
    windows: list[dict]

    @classmethod
    def read(cls, state: FinalState, platform: str | None = None) -> "Programs":
        out = probe(state, processes=True, windows=True, platform=platform)
        return cls(out["processes"], out["windows"])

    def process(self, pid: int) -> dict | None:
        return next((p for p in self.processes if p["pid"] == pid), None)

    def titled(self, title: str, visible_only: bool = False) -> list[dict]:
        """The windows titled `title` (compared without case)."""
        return [w for w in self.windows if w["title"].casefold() == title.casefold()
                and (w["visible"] or not visible_only)]

    def owners(self, title: str) -> list[dict]:
        """The processes that show a window titled `title`."""
        pids = {w["pid"] for w in self.titled(title, visible_only=True)}
        return [p for p in self.processes if p["pid"] in pids]


def same_process(then: dict, now: dict | None) -> bool:
    """Whether `now` is the process `then` was: same id and image, and the same start time where both are known
    (an id reused by a later process has a later start)."""
    if now is None or now["pid"] != then["pid"] or now["name"].casefold() != then["name"].casefold():
        return False
    return then.get("started") is None or now.get("started") is None or now["started"] == then["started"]


def alive(then: dict, now: Programs) -> bool:
    return same_process(then, now.process(then["pid"]))


def setup_owner(setup: Programs, title: str) -> dict:
    """The process that showed the window `title` right after set-up; an InfrastructureError when set-up showed
    none (the set-up failed to start it, not the agent)."""
    owners = setup.owners(title)
    if not owners:
        raise InfrastructureError(f"right after set-up no window was titled {title!r} (windows then: "
                                  f"{sorted({w['title'] for w in setup.windows if w['visible']})[:10]})")
    return owners[0]


def check_programs(setup: Programs, now: Programs, ended: list[str], running: list[str],
                   images: dict[str, int]) -> Verdict:
    """The processes that showed the windows `ended` at set-up are gone and no window of those titles is left
    (shown or hidden); the processes that showed the windows `running` at set-up still run and still show them;
    `images[name]` processes of each program image `name` (so an extra copy started fails)."""
    problems = []
    for title in ended:
        then = setup_owner(setup, title)
        if alive(then, now):
            shows = [w for w in now.windows if w["pid"] == then["pid"] and w["title"].casefold() == title.casefold()]
            hidden = " (its window hidden)" if shows and not any(w["visible"] for w in shows) else ""
            problems.append(f"{title!r} still running: process {then['pid']} ({then['name']}){hidden}")
        for w in now.titled(title):
            if w["pid"] != then["pid"]:
                problems.append(f"a window {title!r} open again, of process {w['pid']}")
    for title in running:
        then = setup_owner(setup, title)
        if not alive(then, now):
            again = now.owners(title)
            problems.append(f"{title!r} no longer running: set-up's process {then['pid']} ({then['name']}) is gone"
                            + (f"; process {again[0]['pid']} shows that title now (started again)" if again else ""))
        elif not any(w["pid"] == then["pid"] for w in now.titled(title, visible_only=True)):
            problems.append(f"{title!r}: process {then['pid']} runs but no longer shows that window")
    counts: dict[str, int] = {}
    for p in now.processes:
        counts[p["name"].casefold()] = counts.get(p["name"].casefold(), 0) + 1
    for name, n in images.items():
        if counts.get(name.casefold(), 0) != int(n):
            problems.append(f"{counts.get(name.casefold(), 0)} {name} process(es), expected {n}")
    want = f"{ended} ended, {running} still running (the processes set-up started)"
    return Verdict.check(not problems, want, "; ".join(problems) or "so")


@evaluator("windows_programs")
def windows_programs(state: FinalState, ended: list[str], running: list[str], images: dict[str, int] | None = None,
                     platform: str | None = None) -> Verdict:
    """The programs whose windows were titled `ended` right after set-up were ended (those processes gone, no
    window of those titles left, not even a hidden one), the programs titled `running` are the very processes
    set-up started (not started again) and still show their windows, and each program image of `images` has that
    many processes (see `check_programs`)."""
    setup = Programs(**setup_snapshot(state, SNAPSHOT, platform))
    return check_programs(setup, Programs.read(state, platform), list(ended), list(running), dict(images or {}))


def check_started_by(setup: Programs, now: Programs, titles: list[str], image: str, parent: str) -> Verdict:
    """A shown window titled as one of `titles` belongs to a process of `image` started after set-up (absent from
    its snapshot) whose parent is the `parent` process that set-up started (same id and start time: e.g. the Task
    Manager set-up opened, not a program merely named so, nor one started later)."""
    want = f"a window {titles[0]!r} of {image} started by the {parent} set-up started"
    wanted = {t.casefold() for t in titles}
    shows = [w for w in now.windows if w["visible"] and w["title"].casefold() in wanted]
    if not shows:
        near = sorted({w["title"] for w in now.windows if w["visible"]})[:8]
        return Verdict.check(False, want, f"no such window; windows {near}")
    found = []
    for w in shows:
        proc = now.process(w["pid"])
        if proc is None:
            found.append(f"a window of process {w['pid']} (gone)")
            continue
        if proc["name"].casefold() != image.casefold():
            found.append(f"a window of {proc['name']}")
            continue
        then = setup.process(proc["pid"])
        if then is not None and same_process(then, proc):
            found.append(f"{image} (pid {proc['pid']}) already running at set-up")
            continue
        dad_then = setup.process(proc["ppid"])
        dad_now = now.process(proc["ppid"])
        if dad_then is not None and dad_then["name"].casefold() == parent.casefold() and (
                dad_now is None or same_process(dad_then, dad_now)):
            return Verdict.check(True, want, f"{image} (pid {proc['pid']}) started by {dad_then['name']} "
                                             f"(pid {dad_then['pid']})")
        if dad_now is not None and dad_now["name"].casefold() == parent.casefold():
            found.append(f"{image} started by a {dad_now['name']} (pid {dad_now['pid']}, "
                         f"{dad_now.get('path') or 'unknown path'}) that set-up did not start")
        else:
            found.append(f"{image} started by {dad_now['name'] if dad_now else 'a process no longer running'}")
    return Verdict.check(False, want, "; ".join(found))


@evaluator("windows_started_by")
def windows_started_by(state: FinalState, titles: list[str], image: str, parent: str,
                       unchanged: list[str] | None = None, platform: str | None = None) -> Verdict:
    """A window titled as one of `titles` shows, its program is `image`, started after set-up by the `parent`
    program set-up started (see `check_started_by`), and the files of `unchanged` are as at set-up (opened, not
    edited)."""
    setup = Programs(**setup_snapshot(state, SNAPSHOT, platform))
    verdict = check_started_by(setup, Programs.read(state, platform), list(titles), image, parent)
    return with_unchanged(state, verdict, f"a window {titles[0]!r} of {image} started by {parent}", platform,
                          unchanged=list(unchanged or []))


def capture_programs(state: FinalState, platform: str | None = None, **_: Any) -> dict[str, Any]:
    """Set-up capture: the processes and windows right after set-up."""
    now = Programs.read(state, platform)
    return {snapshot_key(SNAPSHOT): {"processes": now.processes, "windows": now.windows}}


setup_capture("windows_programs")(capture_programs)
setup_capture("windows_started_by")(capture_programs)
