"""The state of a run, on disk: `run.json` (who runs it, since when, every session, a heartbeat) and `plan.json`
(every task the run meant to run). Readers — the dashboard, `jarvis runs`, `--resume` — tell a live run from
one whose process is gone ("interrupted") without trusting a state that a killed process could not update.

`run.json`::

    {"format": "jarvis-pytest run", "run_id", "state": "running" | "finished" | "interrupted",
     "started" (the first session's start, kept by --resume), "finished", "heartbeat", "pid", "host",
     "agent", "agent_key", "egress", "sessions": [{"started", "finished", "argv", "pid", "exit", "resumed"}],
     "card": the run card, every condition its results depend on (`report/run_card.py`)}

`plan.json`: ``{"tasks": [keys], "categories": {key: category}, "digests": {task id: hash of the task's
definition}}``, the union over the run's sessions (a resumed run never forgets a planned task). A key is the task
id, with `#trial<n>` after it from a task's second trial on (`results.model.result_key`).
"""

from __future__ import annotations

import hashlib
import json
import os
import socket
import threading
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from jarvis_pytest.results.writer import now_iso, write_json_atomic

RUN_FORMAT = "jarvis-pytest run"
HEARTBEAT_SECONDS = 10.0
STALE_SECONDS = 60.0  # a heartbeat older than this from another host means its process is gone


def new_run_id() -> str:
    """A new run's id (its folder's name under reports/): UTC time of the start and six random hex digits."""
    import uuid

    return datetime.now(timezone.utc).strftime("%Y%m%d-%H%M%S-") + uuid.uuid4().hex[:6]


def read_json(path: Path) -> dict[str, Any] | None:
    """A JSON object from `path`, or None when missing or unreadable."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def task_digest(task: Any) -> str:
    """A short hash of a task's definition (a `Task` or its dataset dict): a resumed run refuses a task whose
    definition changed."""
    data = task.to_json() if hasattr(task, "to_json") else task
    return hashlib.sha256(json.dumps(data, sort_keys=True, default=str).encode()).hexdigest()[:16]


def resource_id(run_dir: Path) -> str:
    """The run id its Docker resources carry (label `org.jarvis.run`, container names): the folder's name and a
    digest of its absolute path, so two runs in folders of the same name (`a/qc`, `b/qc`) never share one (the
    end of one would remove the other's devices) while a resumed run keeps its own."""
    import hashlib

    digest = hashlib.sha256(str(Path(run_dir).resolve()).encode()).hexdigest()[:6]
    return f"{Path(run_dir).name}-{digest}"


def process_alive(pid: int) -> bool:
    """Whether process `pid` of this host still runs (a zombie does not; nor does a pid no process can have)."""
    if isinstance(pid, bool) or not isinstance(pid, int) or not 0 < pid < 2**31:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return True


def _age_seconds(iso: str) -> float:
    try:
        return (datetime.now(timezone.utc) - datetime.fromisoformat(iso)).total_seconds()
    except (TypeError, ValueError, OverflowError):
        return float("inf")


def liveness(meta: dict[str, Any] | None) -> str:
    """`running`, `finished` or `interrupted` from a run.json: a run marked running whose process is gone (same
    host) or whose heartbeat went stale (another host) was interrupted. `unknown` without a run.json."""
    if not isinstance(meta, dict) or not meta:
        return "unknown"
    state = meta.get("state")
    if state in ("finished", "interrupted"):
        return state
    if state != "running":  # a run.json written before run states existed: it is written when a session ends
        return "finished"
    pid = meta.get("pid")
    if meta.get("host") == socket.gethostname() and isinstance(pid, int):
        return "running" if process_alive(pid) else "interrupted"
    return "running" if heartbeat_fresh(meta) else "interrupted"


def heartbeat_fresh(meta: dict[str, Any]) -> bool:
    """Whether run.json's heartbeat is younger than STALE_SECONDS (a live run beats every HEARTBEAT_SECONDS)."""
    return _age_seconds(meta.get("heartbeat", "")) < STALE_SECONDS


def read_run_meta(run_dir: Path) -> tuple[dict[str, Any] | None, str | None]:
    """run.json of `run_dir` as (meta, None); (None, None) when absent; (None, why) when it cannot be read or is
    not a run.json (its problem, for a message naming the file)."""
    path = Path(run_dir) / "run.json"
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        return None, None
    except OSError as exc:
        return None, f"cannot be read ({exc.strerror or exc})"
    try:
        data = json.loads(raw)
    except (ValueError, UnicodeDecodeError) as exc:
        return None, f"is not valid JSON ({exc})"
    why = meta_problem(data)
    return (None, why) if why else (data, None)


_KINDS = {list: "a list", dict: "an object", str: "a string"}


def meta_problem(data: Any) -> str | None:
    """What makes parsed run.json content unusable (worded to follow the file's name), or None."""
    if not isinstance(data, dict):
        return "is not a JSON object"
    for key, kind in (("sessions", list), ("engines", list), ("agent", dict), ("card", dict), ("state", str),
                      ("agent_key", str),
                      ("started", str), ("finished", str), ("heartbeat", str), ("host", str)):
        if data.get(key) is not None and not isinstance(data[key], kind):
            return f"has a {key!r} that is not {_KINDS[kind]}"
    pid = data.get("pid")
    if pid is not None and (isinstance(pid, bool) or not isinstance(pid, int) or not 0 < pid < 2**31):
        return f"has a 'pid' no process can have ({str(pid)[:20]})"
    if not all(isinstance(s, dict) for s in data.get("sessions") or []):
        return "has a 'sessions' entry that is not an object"
    if not all(isinstance(e, str) for e in data.get("engines") or []):
        return "has an 'engines' entry that is not a URL"
    return None


def is_run_dir(path: Path) -> bool:
    """Whether `path` holds a run of this project (its run.json, or an older run's plan.json and tasks/)."""
    meta = read_json(path / "run.json")
    if meta is not None:
        return meta.get("format") == RUN_FORMAT or "run_id" in meta
    plan = read_json(path / "plan.json")
    return plan is not None and isinstance(plan.get("tasks"), list) and (path / "tasks").is_dir()


class RunState:
    """The controller's handle on run.json: start (or resume) a session, beat, finish. Thread-safe."""

    def __init__(self, run_dir: Path, argv: list[str], resumed: bool):
        self.run_dir = run_dir
        self.path = run_dir / "run.json"
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        old = read_json(self.path) if resumed else None
        now = now_iso()
        self.meta: dict[str, Any] = dict(old or {})
        self.meta.update({"format": RUN_FORMAT, "run_id": run_dir.name, "resources": resource_id(run_dir),
                          "state": "running", "finished": "",
                          "heartbeat": now, "pid": os.getpid(), "host": socket.gethostname()})
        self.meta.setdefault("started", now)
        sessions = list(self.meta.get("sessions") or [])
        sessions.append({"started": now, "finished": "", "argv": argv, "pid": os.getpid(), "exit": None,
                         "resumed": bool(old)})
        self.meta["sessions"] = sessions

    def start(self, **fields: Any) -> None:
        """Write run.json (creating the run directory) and start the heartbeat."""
        with self._lock:
            self.meta.update(fields)
            self.run_dir.mkdir(parents=True, exist_ok=True)
            write_json_atomic(self.path, self.meta)
        self._thread = threading.Thread(target=self._beat, name="jarvis-heartbeat", daemon=True)
        self._thread.start()

    def update(self, **fields: Any) -> None:
        with self._lock:
            self.meta.update(fields)
            write_json_atomic(self.path, self.meta)

    def _beat(self) -> None:
        while not self._stop.wait(HEARTBEAT_SECONDS):
            try:
                self.update(heartbeat=now_iso())
            except OSError:
                pass  # the run directory went away; the session ends on its own

    def finish(self, interrupted: bool, exit_status: int, **fields: Any) -> None:
        """Mark the session ended (`interrupted` when it was stopped before its tasks were done)."""
        self._stop.set()
        now = now_iso()
        with self._lock:
            self.meta["sessions"][-1].update(finished=now, exit=exit_status)
            self.meta.update(fields, state="interrupted" if interrupted else "finished", finished=now, heartbeat=now)
            write_json_atomic(self.path, self.meta)


def read_plan(run_dir: Path) -> dict[str, Any]:
    """plan.json as {"tasks", "categories", "digests"} (empty parts when missing or not of their type:
    `plan_problem` names those)."""
    plan = read_json(run_dir / "plan.json") or {}
    tasks = plan.get("tasks") if isinstance(plan.get("tasks"), list) else []
    categories = plan.get("categories") if isinstance(plan.get("categories"), dict) else {}
    digests = plan.get("digests") if isinstance(plan.get("digests"), dict) else {}
    return {"tasks": [str(t) for t in tasks], "categories": {str(k): str(v) for k, v in categories.items()},
            "digests": {str(k): str(v) for k, v in digests.items()}}


def plan_problem(run_dir: Path) -> str | None:
    """What makes `run_dir`'s plan.json unusable (worded to follow the file's name), or None (also when absent)."""
    path = Path(run_dir) / "plan.json"
    try:
        data = json.loads(path.read_bytes())
    except FileNotFoundError:
        return None
    except OSError as exc:
        return f"cannot be read ({exc.strerror or exc})"
    except (ValueError, UnicodeDecodeError) as exc:
        return f"is not valid JSON ({exc})"
    if not isinstance(data, dict):
        return "is not a JSON object"
    for key, kind in (("tasks", list), ("categories", dict), ("digests", dict)):
        if data.get(key) is not None and not isinstance(data[key], kind):
            return f"has a {key!r} that is not {_KINDS[kind]}"
    return None


def merge_plan(run_dir: Path, cases: list[tuple[str, Any]]) -> None:
    """Add `cases` ((result key, `Task`) pairs: the key is the task id, with `#trial<n>` from the second trial on)
    to plan.json: the plan is the union over the run's sessions. Categories are kept per key, digests per task."""
    plan = read_plan(run_dir)
    ids = set(plan["tasks"])
    for key, t in cases:
        ids.add(key)
        plan["categories"][key] = t.category
        plan["digests"][t.id] = task_digest(t)
    run_dir.mkdir(parents=True, exist_ok=True)
    write_json_atomic(run_dir / "plan.json", {"tasks": sorted(ids), "categories": plan["categories"],
                                              "digests": plan["digests"], "written": now_iso()})
