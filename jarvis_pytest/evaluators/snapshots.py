"""What evaluators record right after set-up besides the files a template lists under `baseline`: state that is
no file, or a whole folder — which processes the set-up started, what a folder held. An evaluator that needs one
registers a capture under its own name (`@setup_capture("name")`); right after set-up the harness runs it with the
evaluator's rendered arguments (`capture_setup_snapshots`) and keeps what it returns on the host, beside the file
baselines, under keys no device path can take (`snapshot_key`). The evaluator reads it back with
`state.baseline(snapshot_key(...))`; nothing the agent does can change it.
"""

from __future__ import annotations

import json
from typing import Any, Callable, Iterable

from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.evaluators.state import FinalState
from jarvis_pytest.naming import Registry

SETUP_CAPTURES: Registry = Registry("set-up capture")
setup_capture = SETUP_CAPTURES.register  # @setup_capture("evaluator name") def capture(state, **args) -> dict
_PREFIX = "<set-up snapshot> "


def snapshot_key(what: str) -> str:
    """The baseline key of one snapshot (e.g. `snapshot_key("processes")`, `snapshot_key("tree " + folder)`)."""
    return _PREFIX + what


def is_snapshot_key(key: str) -> bool:
    return key.startswith(_PREFIX)


def capture_setup_snapshots(state: FinalState, specs: Iterable[Any]) -> dict[str, bytes]:
    """The snapshots the evaluators of `specs` (EvaluatorSpec: `func`, `args`) ask for, taken now (right after
    set-up): snapshot key → bytes (JSON)."""
    out: dict[str, bytes] = {}
    for spec in specs:
        capture: Callable[..., dict[str, Any]] | None = SETUP_CAPTURES.get(spec.func)
        if capture is not None:
            out.update({key: json.dumps(value).encode("utf-8") for key, value in capture(state, **spec.args).items()})
    return out


def setup_snapshot(state: FinalState, what: str, platform: str | None = None) -> Any:
    """The snapshot `what` taken right after set-up. Its absence is the harness's fault (the capture did not run),
    never the agent's: an InfrastructureError."""
    data = state.baseline(snapshot_key(what), platform)
    if data is None:
        raise InfrastructureError(f"no set-up snapshot of {what}: the harness did not capture it after set-up")
    return json.loads(data.decode("utf-8"))
