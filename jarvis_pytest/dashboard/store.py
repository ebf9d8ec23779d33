"""The dashboard's view of the results directory: runs, their tasks, one task's trajectory, two runs side by side.

Everything comes from the files `jarvis_pytest.results` writes (no database). A run may be in progress
(no run.json yet, tasks "running"), interrupted or partly corrupted: what can be read is shown, and every file
that cannot be read becomes a problem entry naming the file, next to the data.
"""

from __future__ import annotations

import os
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from jarvis_pytest.dashboard import stats
from jarvis_pytest.dashboard.paths import resolve_under
from jarvis_pytest.dashboard.reading import FileCache, load_json, load_traj, load_traj_summary, screenshots
from jarvis_pytest.results import run_state
from jarvis_pytest.results.model import StepRecord, TaskResult
from jarvis_pytest.results.writer import safe_name

DONE = ("passed", "failed", "error", "timeout", "skipped")


class NotFound(LookupError):
    """No such run or task (answered with 404)."""


def _problem(where: str, message: str) -> dict[str, str]:
    return {"file": where, "message": message}


def _mtime_iso(path: Path) -> str:
    try:
        ts = path.stat().st_mtime
    except OSError:
        return ""
    return datetime.fromtimestamp(ts, timezone.utc).isoformat(timespec="seconds")


def _action_text(step: StepRecord) -> str:
    a = step.action or {}
    if not a:
        return "(no action)"
    args = ", ".join(f"{k}={v!r}" for k, v in a.items() if k != "type" and v is not None)
    return f"{a.get('type', '?')}({args})"


def _step_json(step: StepRecord) -> dict[str, Any]:
    data = step.model_dump(mode="json")
    data["action_text"] = _action_text(step)
    return data


class ResultsStore:
    """Read-only access to one results directory (`reports/` by default)."""

    def __init__(self, root: Path):
        self.root = Path(root).resolve()
        self.cache = FileCache()

    # -- locating -------------------------------------------------------------------------------------------
    def _rel(self, path: Path) -> str:
        try:
            return path.relative_to(self.root).as_posix()
        except ValueError:
            return str(path)

    def run_dir(self, run_id: str) -> Path:
        path = resolve_under(self.root, [run_id])
        if not _is_run(path):
            raise NotFound(f"no run {run_id!r}")
        return path

    def task_dir(self, run_id: str, name: str) -> Path:
        """A task's folder by its folder name or by its task id (`ubuntu-calc-sum_total[seed0]`)."""
        run = self.run_dir(run_id)
        for candidate in dict.fromkeys((name, safe_name(name))):
            path = resolve_under(run, ["tasks", candidate])
            if path.is_dir():
                return path
        raise NotFound(f"no task {name!r} in run {run_id!r}")

    def _subdirs(self, path: Path) -> list[Path]:
        """Sub-directories of `path` (resolved, inside the root) by name, without hidden ones and symlinks that
        lead out of the root."""
        try:
            entries = [e for e in os.scandir(path) if e.is_dir() and not e.name.startswith(".")]
        except OSError:
            return []
        inside = (Path(e.path) for e in entries if not e.is_symlink() or Path(e.path).resolve().is_relative_to(self.root))
        return sorted(inside, key=lambda p: p.name)

    def run_ids(self) -> list[str]:
        return [p.name for p in reversed(self._subdirs(self.root)) if _is_run(p)]

    # -- tasks ----------------------------------------------------------------------------------------------
    def _task_summary(self, tdir: Path, ended: str | None, shots: bool = True) -> tuple[dict[str, Any], TaskResult | None]:
        """A task's row: status, progress, latest step, its problems and (with `shots`, for a running or unreadable
        task) its latest screenshots.
        `ended` is when the run's last session ended (run.json), None if it never did: a task still "running"
        that started before then was interrupted."""
        result, bad = load_json(self.cache, tdir / "result.json", TaskResult)
        traj = load_traj_summary(self.cache, tdir / "traj.jsonl")
        problems = [_problem(self._rel(tdir / "traj.jsonl"), p) for p in traj.problems]
        if bad:
            problems.insert(0, _problem(self._rel(tdir / "result.json"), bad))
        elif result is None:
            problems.insert(0, _problem(self._rel(tdir / "result.json"), "missing"))
        status = result.status if result else "unknown"
        if status == "running" and ended is not None and result.started <= ended:
            status = "interrupted"
            problems.append(_problem(self._rel(tdir / "result.json"), "still 'running' although its session ended"))
        found = screenshots(tdir) if shots and status in ("running", "unknown") else {}
        latest_shots = found[max(found)] if found else {}
        entry: dict[str, Any] = {
            "name": tdir.name,
            "task_id": result.task_id if result else tdir.name,
            "status": status,
            "category": result.category if result else "",
            "platforms": result.platforms if result else sorted(latest_shots),
            "instruction": result.instruction if result else "",
            "subtasks_passed": result.passed_subtasks if result else 0,
            "subtasks_total": len(result.subtasks) if result else 0,
            "steps": result.steps if result and status in DONE else traj.count,
            "end_reason": result.end_reason if result else "",
            "failure_mode": result.failure_mode if result else None,
            "backends": result.backends if result else {},
            "stand_ins": result.stand_ins if result else [],
            "error": result.error if result else None,
            "started": result.started if result else "",
            "finished": result.finished if result else "",
            "duration": (result.durations or {}).get("total") if result else None,
            **_times(result),
            "latest_screenshots": latest_shots,
            "latest_step": _step_json(traj.last) if traj.last else None,
            "updated": _mtime_iso(tdir / "traj.jsonl") or _mtime_iso(tdir),
            "problems": problems,
        }
        return entry, result

    def _tasks(self, run_dir: Path, ended: str | None, shots: bool) -> tuple[list[dict[str, Any]], list[TaskResult]]:
        entries, finished = [], []
        for tdir in self._subdirs(run_dir / "tasks"):
            entry, result = self._task_summary(tdir, ended, shots)
            entries.append(entry)
            if result is not None and result.status in DONE:
                finished.append(result)
        return entries, finished

    # -- runs -----------------------------------------------------------------------------------------------
    def _run(self, run_id: str, with_tasks: bool) -> dict[str, Any]:
        run_dir = self.run_dir(run_id)
        problems: list[dict[str, str]] = []
        meta, bad = load_json(self.cache, run_dir / "run.json")
        if meta is not None and not bad:
            bad = run_state.meta_problem(meta)
        meta_unreadable = bool(bad)  # its state cannot be told: shown as "unreadable", never as "in progress"
        if bad:
            problems.append(_problem(self._rel(run_dir / "run.json"), bad))
            meta = None
        plan, bad = load_json(self.cache, run_dir / "plan.json")
        planned: list[str] | None = None
        if plan is not None and not (isinstance(plan, dict) and isinstance(plan.get("tasks"), list)):
            bad = 'not {"tasks": [task ids...]}'
        if bad:
            problems.append(_problem(self._rel(run_dir / "plan.json"), bad))
        elif plan is not None:
            planned = [str(t) for t in plan["tasks"]]
        ended = _session_end(run_dir, meta)
        tasks, results = self._tasks(run_dir, ended, shots=with_tasks)
        for t in tasks:
            problems.extend(t["problems"])
        started_names = {t["name"] for t in tasks}
        pending = [t for t in (planned or []) if safe_name(t) not in started_names]
        counts = {k: 0 for k in ("passed", "failed", "error", "timeout", "skipped", "running", "interrupted",
                                 "unknown")}
        for t in tasks:
            counts[t["status"]] = counts.get(t["status"], 0) + 1
        counts["pending"] = len(pending)
        counts["done"] = sum(counts[k] for k in DONE)
        counts["total"] = len(tasks) + len(pending)
        agent = (meta or {}).get("agent") or next((r.agent for r in results if r.agent), {})
        started = (meta or {}).get("started") or min((t["started"] for t in tasks if t["started"]), default="")
        data: dict[str, Any] = {
            "id": run_dir.name,
            "state": "unreadable" if meta_unreadable else _state(run_dir, meta, ended, counts),
            "agent": agent,
            "agent_name": agent.get("name", "") if isinstance(agent, dict) else str(agent),
            "started": started,
            "finished": (meta or {}).get("finished", ""),
            "updated": max((t["updated"] for t in tasks), default="") or _mtime_iso(run_dir),
            "has_plan": planned is not None,
            "counts": counts,
            "stats": stats.headline(results),
            "problems": problems,
        }
        if with_tasks:
            data["tasks"] = tasks
            data["pending"] = pending
            data["summary"] = stats.summary(results)
            data["files"] = [n for n in ("summary.md", "summary.json", "report.html") if (run_dir / n).is_file()]
        return data

    def runs(self) -> dict[str, Any]:
        """Every run in the results directory, newest first, with progress and headline rates."""
        runs = []
        for run_id in self.run_ids():
            try:
                runs.append(self._run(run_id, with_tasks=False))
            except (NotFound, OSError) as exc:  # removed while we looked
                runs.append({"id": run_id, "state": "unreadable", "problems": [_problem(run_id, str(exc))]})
            except Exception as exc:  # one run this reader cannot make sense of never hides the others
                runs.append({"id": run_id, "state": "unreadable", "problems": [
                    _problem(f"{run_id}/run.json", f"cannot be shown ({exc.__class__.__name__}: {exc})")]})
        return {"root": str(self.root), "runs": runs}

    def run(self, run_id: str) -> dict[str, Any]:
        """One run: its tasks (done, running, pending), the latest step of each, the summary tables."""
        return self._run(run_id, with_tasks=True)

    def task(self, run_id: str, name: str) -> dict[str, Any]:
        """One task: its result, every step of its trajectory with the screenshots of every device."""
        run_dir = self.run_dir(run_id)
        tdir = self.task_dir(run_id, name)
        meta, _ = load_json(self.cache, run_dir / "run.json")
        entry, result = self._task_summary(tdir, _session_end(run_dir, meta if isinstance(meta, dict) else None))
        steps, _ = load_traj(tdir / "traj.jsonl")
        shots = screenshots(tdir)
        recorded = {s.index for s in steps}
        entry["steps_detail"] = [_step_json(s) for s in steps]
        # screenshots no step refers to: the final state (taken after the loop) or a step still being decided
        entry["extra_screenshots"] = [{"index": i, "screenshots": p} for i, p in shots.items() if i not in recorded]
        entry["subtasks"] = [s.model_dump(mode="json") for s in result.subtasks] if result else []
        entry["durations"] = result.durations if result else {}
        entry["usage"] = result.usage if result else {}
        entry["agent"] = result.agent if result else {}
        entry["run"] = run_dir.name
        return entry

    def compare(self, a: str, b: str) -> dict[str, Any]:
        """Two runs task by task: each side's status, subtasks and steps, and what changed."""
        sides = [self.run(a), self.run(b)]
        # matched by directory name (the safe form of the task id), which survives an unreadable result.json
        by_name = [{t["name"]: t for t in side["tasks"]} for side in sides]
        rows = []
        for name in sorted(set(by_name[0]) | set(by_name[1])):
            ta, tb = by_name[0].get(name), by_name[1].get(name)
            readable = [t for t in (ta, tb) if t is not None and t["status"] != "unknown"] or [t for t in (ta, tb) if t]
            task_id = readable[0]["task_id"]
            rows.append({"task_id": task_id, "a": _side(ta), "b": _side(tb), "change": _change(ta, tb)})
        return {"a": _brief(sides[0]), "b": _brief(sides[1]), "rows": rows}


def _session_end(run_dir: Path, meta: dict[str, Any] | None) -> str | None:
    """When the run's last session ended, or None while it runs. A session whose process is gone ended at its
    last heartbeat; run.json files of older runs were written only when a session ended."""
    if meta is None:
        return None
    live = run_state.liveness(meta)
    if live == "running":
        return None
    if live == "interrupted" and not meta.get("finished"):
        return str(meta.get("heartbeat") or _mtime_iso(run_dir / "run.json"))
    return str(meta.get("finished") or _mtime_iso(run_dir / "run.json"))


def _state(run_dir: Path, meta: dict[str, Any] | None, ended: str | None, counts: dict[str, int]) -> str:
    """`in progress`, `interrupted` (its process is gone, or it was stopped, before every planned task ran) or
    `finished`."""
    if meta is not None and meta.get("format") == run_state.RUN_FORMAT:
        live = run_state.liveness(meta)
        if live == "running":
            return "in progress"
        return "interrupted" if live == "interrupted" or counts["interrupted"] else "finished"
    return "in progress" if _in_progress(run_dir, ended, counts) else "finished"


def _in_progress(run_dir: Path, ended: str | None, counts: dict[str, int]) -> bool:
    """No session has ended yet, a task is running, or a new session (plan.json rewritten, e.g. --resume) began."""
    if ended is None or counts["running"]:
        return True
    try:
        return (run_dir / "plan.json").stat().st_mtime > (run_dir / "run.json").stat().st_mtime
    except OSError:
        return False


def _is_run(path: Path) -> bool:
    return path.is_dir() and any((path / n).exists() for n in ("run.json", "plan.json", "tasks"))


def _times(result: TaskResult | None) -> dict[str, float | None]:
    """A task's time (its loop's wall time), the agent's decision time (for `human`, the time the person took) and
    that per step, in seconds; None where the task has none."""
    d = (result.durations or {}) if result else {}
    agent = d.get("agent")
    steps = result.steps if result else 0
    return {"loop_seconds": d.get("loop"), "agent_seconds": agent,
            "step_seconds": agent / steps if agent is not None and steps else None}


def _side(task: dict[str, Any] | None) -> dict[str, Any] | None:
    if task is None:
        return None
    return {k: task[k] for k in ("name", "status", "subtasks_passed", "subtasks_total", "steps", "end_reason",
                                 "loop_seconds", "step_seconds")}


def _change(a: dict[str, Any] | None, b: dict[str, Any] | None) -> str:
    if a is None or b is None:
        return "only in A" if b is None else "only in B"
    if a["status"] == b["status"]:
        return "same"
    if a["status"] not in DONE or b["status"] not in DONE:
        return "incomplete"
    if b["status"] == "passed":
        return "fixed"
    if a["status"] == "passed":
        return "broken"
    return "changed"


def _brief(run: dict[str, Any]) -> dict[str, Any]:
    return {k: run[k] for k in ("id", "agent_name", "state", "started", "counts", "stats", "summary")}
