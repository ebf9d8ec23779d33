"""The result files of a run; every consumer (rollup, HTML report, dashboard, --resume) reads these models.

Layout of a run directory::

    <run dir>/run.json                       run id, agent configuration, options, start time
    <run dir>/tasks/<safe task id>/traj.jsonl  one `StepRecord` per line, appended as the task runs
    <run dir>/tasks/<safe task id>/step_0003_ubuntu.png
    <run dir>/tasks/<safe task id>/result.json  a `TaskResult`, written when the task ends (status "running" before)
    <run dir>/summary.json, summary.md, report.html
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, Field, model_validator

Status = Literal["running", "passed", "failed", "error", "timeout", "skipped"]


class EvaluatorVerdict(BaseModel):
    """One evaluator of one subtask on the final state."""

    func: str
    args: dict[str, Any] = Field(default_factory=dict)
    passed: bool
    reason: str


class SubtaskVerdict(BaseModel):
    """A subtask passes iff all its evaluators pass (paper eq. 1)."""

    index: int
    template: str
    platform: str
    passed: bool
    evaluators: list[EvaluatorVerdict] = Field(default_factory=list)

    @property
    def reasons(self) -> list[str]:
        return [f"{v.func}: {v.reason}" for v in self.evaluators if not v.passed]


class NegativeVerdict(BaseModel):
    """`jarvis qc`: one near-miss wrong state of a subtask, applied after set-up on fresh devices, then evaluated.
    `passed` True means the evaluators accepted the wrong state: a violation of the gate."""

    subtask: int
    index: int
    kind: str
    note: str
    passed: bool
    error: str | None = None  # the negative's steps could not be applied (a broken negative is a violation too)
    verdicts: list[SubtaskVerdict] = Field(default_factory=list)
    device_faults: list[str] = Field(default_factory=list)  # faults of the devices, each tried again on fresh ones
    # a composed task's broken chain (`harness/chain_negatives.py`): the subtasks that must fail on it, and the steps
    # that failed because the chain is broken (expected; the rest of the plan went on)
    expect: list[int] | None = None
    step_errors: list[str] = Field(default_factory=list)

    def violation(self) -> str | None:
        """Why this negative violates the gate (it could not be applied, or the evaluators accept it; a composed
        task's broken chain also when the subtask meant to catch it passes), or None."""
        if self.error:
            return f"negative {self.index} ({self.note}) could not be applied: {self.error.splitlines()[0]}"
        if not self.passed:
            return None
        if self.expect is None:
            return f"negative {self.index} passes ({self.kind}: {self.note}): the evaluators accept this wrong state"
        held = [f"{i} ({self.verdicts[i].template})" for i in self.expect if self.verdicts[i].passed]
        chain = self.kind.removeprefix("chain:")
        return (f"broken chain {chain} ({self.note}) passes at subtask {', '.join(held)}" if held
                else f"broken chain {chain} ({self.note}) passes the task")


class GuiCheck(BaseModel):
    """`jarvis qc`'s fourth check of one subtask: the task passes after its GUI solution (`gui-oracle`), run on
    fresh devices. `state`: `passed`/`failed`, `infeasible` (the template says the GUI cannot solve it on `backend`:
    `reason`), or `none` (no GUI solution yet)."""

    subtask: int
    template: str
    app: str = ""
    backend: str = ""
    state: Literal["passed", "failed", "infeasible", "none"]
    reason: str = ""  # why it failed, or why the GUI cannot solve it
    steps: int = 0
    verdicts: list[SubtaskVerdict] = Field(default_factory=list)
    device_faults: list[str] = Field(default_factory=list)
    seconds: float = 0.0


# The most characters of a model's text a step keeps (`StepRecord.raw_output`, `reasoning`): a model that streams
# megabytes would otherwise write them into traj.jsonl at every step (and the dashboard would send them to the
# browser). The first CUT_TEXT_CHARS are kept and `cut` says how long the text was.
CUT_TEXT_CHARS = 65536
CUT_FIELDS = ("raw_output", "reasoning")


class StepRecord(BaseModel):
    """One line of traj.jsonl. A model text longer than `CUT_TEXT_CHARS` keeps its first `CUT_TEXT_CHARS`
    characters, and `cut` maps the field to its original length (in characters)."""

    index: int
    platform: str | None
    action: dict[str, Any] | None
    reasoning: str = ""
    raw_output: str = ""
    cut: dict[str, int] = Field(default_factory=dict)  # field → its length before it was cut to CUT_TEXT_CHARS
    error: str | None = None
    screenshots: dict[str, str] = Field(default_factory=dict)  # platform → file name (observation before acting)
    agent_ms: float = 0.0
    exec_ms: float = 0.0
    observe_ms: float = 0.0
    usage: dict[str, int] = Field(default_factory=dict)
    extra: dict[str, Any] = Field(default_factory=dict)

    @model_validator(mode="before")
    @classmethod
    def _cut_long_texts(cls, data: Any) -> Any:
        """Keep the first CUT_TEXT_CHARS of each model text; `cut` records the length of each one cut."""
        if not isinstance(data, dict):
            return data
        long = {f: data[f] for f in CUT_FIELDS if isinstance(data.get(f), str) and len(data[f]) > CUT_TEXT_CHARS}
        if not long:
            return data
        data = dict(data)
        cut = dict(data.get("cut") or {})
        for name, text in long.items():
            data[name] = text[:CUT_TEXT_CHARS]
            cut[name] = len(text)
        data["cut"] = cut
        return data


class TaskResult(BaseModel):
    """result.json of one task."""

    task_id: str
    category: str  # atomic | sw | mi | md
    platforms: list[str]
    instruction: str
    status: Status
    agent: dict[str, Any] = Field(default_factory=dict)  # agent name + configuration (no secrets)
    agent_key: str = ""  # hash of the agent configuration, for --resume
    subtasks: list[SubtaskVerdict] = Field(default_factory=list)
    qc_initial: list[SubtaskVerdict] | None = None  # --qc: verdicts on the freshly set-up devices (must all fail)
    qc_negatives: list[NegativeVerdict] | None = None  # --qc: verdicts on each near-miss wrong state (must fail)
    qc_gui: list[GuiCheck] | None = None  # --qc: the task after its GUI solution, per subtask (atomic tasks)
    steps: int = 0
    end_reason: str = ""  # done | fail | max_steps | timeout | error
    error: str | None = None  # infrastructure error text when status == "error"; the reason when "skipped"
    egress: bool = False  # the devices could reach beyond their task network (--allow-egress)
    backends: dict[str, str] = Field(default_factory=dict)  # platform → the backend that ran it: "windows (wine)"
    stand_ins: list[str] = Field(default_factory=list)  # platforms that ran on a stand-in (Wine for Windows)
    # platform → what its device really is, read inside it: "Debian GNU/Linux 12 (bookworm), XFCE 4.18" for the
    # platform the paper calls ubuntu (`Backend.describe`)
    device_os: dict[str, str] = Field(default_factory=dict)
    # platform → what its device is made from where the container's image (`image_ids`) does not say it
    # (`Backend.provenance`): for a Windows VM the dockur image (its registry digest) that installed the golden,
    # the Windows it reported, and the memory snapshot the task's VM was restored from
    device_provenance: dict[str, dict[str, Any]] = Field(default_factory=dict)
    engine: str = ""  # the Docker engine the task's devices ran on: "local" or the --docker-host URL (with --ray:
                      # the node's engine, as `ray start` was given it)
    node: str = ""    # with --ray: the Ray node the devices ran on ("<host> <node id>"); "" without Ray
    worker: str = ""  # the xdist worker that ran it ("gw0", …; "main" without xdist)
    edges: list[tuple[int, int]] = Field(default_factory=list)  # (upstream, downstream) subtask indices
    failure_mode: str | None = None  # why a failed task failed (results/failure_modes.py)
    durations: dict[str, float] = Field(default_factory=dict)  # boot, setup, agent, evaluate, total (seconds)
    device_faults: list[str] = Field(default_factory=list)  # device faults (errors.DeviceFault) that made the task
    # run again on fresh devices before this result; the verdict is the last run's
    usage: dict[str, int] = Field(default_factory=dict)
    image_ids: dict[str, str] = Field(default_factory=dict)
    first_screenshot: str | None = None
    last_screenshot: str | None = None
    started: str = ""
    finished: str = ""
    trial: int = 1  # which of the run's `--trials` this is (1 to K); every trial runs on fresh devices
    seed: int | None = None  # the seed handed to the agent (`trial_seed`: from the task id and the trial)
    # "platform:path" → SHA-256 of each input file as set-up left it on the device, before the agent's first step
    # (`harness/inputs.py`): the same instance gives the same bytes on any machine at any time
    inputs: dict[str, str] = Field(default_factory=dict)

    @property
    def passed_subtasks(self) -> int:
        return sum(1 for s in self.subtasks if s.passed)

    @property
    def key(self) -> str:
        """The result's identity in its run: the task id, and `#trial<n>` after it from the second trial on."""
        return result_key(self.task_id, self.trial)


TRIAL_MARK = "#trial"


def result_key(task_id: str, trial: int = 1) -> str:
    """A result's identity in its run (`TaskResult.key`): `task_id` for the first trial (so a one-trial run can be
    given more trials by `--resume --trials K`), `task_id#trial<n>` for the n-th."""
    return task_id if trial == 1 else f"{task_id}{TRIAL_MARK}{trial}"


def trial_seed(task_id: str, trial: int) -> int:
    """The seed an agent is given for one trial of a task: a 31-bit number from a SHA-256 of the task id and the
    trial (the same on any machine; different for each trial, so sampling agents draw differently)."""
    import hashlib

    return int.from_bytes(hashlib.sha256(f"{task_id}{TRIAL_MARK}{trial}".encode()).digest()[:4], "big") >> 1
