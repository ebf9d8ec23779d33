"""Why a composed task failed, from its subtask verdicts, its graph and its trajectory (the paper classified
failures by hand; here every failed task gets one mode, the first that applies):

- `step limit`: the agent ran out of steps (`end_reason` max_steps);
- `gave up`: the agent declared FAIL;
- `agent error`: the agent's own code ended the task (`end_reason` agent_error: it exited, or crashed steps in a
  row; `harness/blame.py`);
- `done early`: the agent declared DONE with a failed subtask on whose device it never acted;
- `transfer failed`: a file-transfer subtask failed (the file never got through the drive, or arrived wrong);
- `context lost`: a subtask fed by an upstream subtask failed although everything upstream of it passed — the
  agent did the first part and then did not carry its output on;
- `subtask failed`: a single-device subtask failed otherwise.
"""

from __future__ import annotations

from typing import Iterable

from jarvis_pytest.results.model import SubtaskVerdict

MODES = ("step limit", "gave up", "agent error", "done early", "transfer failed", "context lost", "subtask failed")


def classify(verdicts: list[SubtaskVerdict], edges: Iterable[tuple[int, int]], end_reason: str,
             acted_on: set[str]) -> str | None:
    """The failure mode of a task (None when every subtask passed). `edges` are (upstream, downstream)
    subtask indices; `acted_on` the platforms the agent sent at least one action to."""
    failed = [v for v in verdicts if not v.passed]
    if not failed and verdicts:
        return None
    if end_reason == "max_steps":
        return "step limit"
    if end_reason == "fail":
        return "gave up"
    if end_reason == "agent_error":
        return "agent error"
    if end_reason == "done" and any(v.platform not in acted_on for v in failed):
        return "done early"
    if any(v.template.startswith("transfer-") for v in failed):
        return "transfer failed"
    upstream: dict[int, set[int]] = {}
    for a, b in edges:
        upstream.setdefault(b, set()).add(a)
    passed = {v.index for v in verdicts if v.passed}
    if any(v.index in upstream and upstream[v.index] <= passed for v in failed):
        return "context lost"
    return "subtask failed"
