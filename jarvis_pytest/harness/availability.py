"""Which tasks this machine can run: a task whose platform has no backend that runs here (Android without an
emulator or a phone), or whose template is written for another backend than the one that runs here (Paint
needs a real Windows, not Wine), is skipped — with the reason and what would run it — and counted apart.

With the built-in GUI oracle (`--agent gui-oracle`, a proof run rather than an agent under evaluation), a task
without a GUI solution on this machine's backends is skipped the same way, before its devices boot: there is
nothing to prove. No other agent can skip a task (an agent that could would take its failures out of the rates).
"""

from __future__ import annotations

from typing import Any

from jarvis_pytest.agents.gui_oracle import GuiOracleAgent, gui_plan
from jarvis_pytest.devices.backend import Backend, Backends, backends_of
from jarvis_pytest.errors import JarvisError
from jarvis_pytest.tasks.model import Task


def _how(platform: str) -> str:
    hints = [f"{b.name}: {b.how_to_run}" for b in backends_of(platform).values() if b.how_to_run]
    return "; ".join(hints) or f"a {platform} device backend"


def skip_reason(task: Task, backends: Backends, agent: Any = None) -> str | None:
    """Why this machine cannot run `task` with the run's backends (None: it can); with `agent` the built-in GUI
    oracle, also a task it has no GUI solution for."""
    chosen: dict[str, Backend] = {}
    for sub in task.formatted_subtasks:
        platform = sub.platform
        if platform not in chosen:
            try:
                chosen[platform] = backends.backend(platform)
            except JarvisError as exc:
                return f"no {platform} device on this machine ({exc}); to run it: {_how(platform)}"
        backend = chosen[platform]
        wanted = sub.backends or []
        if wanted and backend.name not in wanted:
            return (f"{sub.template} needs the {platform} backend {' or '.join(wanted)}; this machine runs "
                    f"{backend.label}; to run it: {_how(platform)}")
        missing = getattr(backend, "subtask_unavailable", None)  # e.g. an attached phone without the template's app
        if missing is not None and (why := missing(sub)):
            return why
    if type(agent) is GuiOracleAgent:  # exactly the built-in class: a subclass is an agent like any other
        _, why = gui_plan(task.formatted_subtasks, {p: b.name for p, b in chosen.items()})
        if why is not None:
            return f"the GUI oracle has nothing to run: {why} (jarvis qc --platform PLATFORM lists them)"
    return None
