"""The state of one benchmark session (per process) and the logic behind the plugin's hooks.

The controller (the only process without xdist, or the xdist controller) chooses the run directory and passes
it to workers; workers run tasks and attach a compact result to `report.user_properties`; the controller
gathers those, writes `summary.json`/`summary.md`, prints the tables and feeds the HTML report.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from jarvis_pytest.errors import ConfigError, InfrastructureError, JarvisError
from jarvis_pytest.plugin import cases
from jarvis_pytest.plugin.evaluation import failure_message, qc_message
from jarvis_pytest.plugin.options import REPO_ROOT, JarvisOptions, new_run_id, read_options
from jarvis_pytest.plugin.runner import RunContext, agent_key, run_task, task_platforms
from jarvis_pytest.results.model import TaskResult
from jarvis_pytest.results.writer import now_iso, read_result, write_json_atomic

PROPERTY = "jarvis"


@dataclass
class JarvisSession:
    options: JarvisOptions
    run_dir: Path
    is_controller: bool
    worker: str
    agent: Any = None
    context: RunContext | None = None
    results: dict[str, TaskResult] = field(default_factory=dict)  # controller: task id → compact result
    _params: dict[str, list[Any]] = field(default_factory=dict)
    started: str = field(default_factory=now_iso)

    def ensure_agent(self):
        if self.agent is None:
            from jarvis_pytest.agents.registry import load_agent

            opts: dict[str, Any] = dict(self.options.agent_options)
            opts["planner"] = self.options.endpoints.get("planner", {})
            opts["grounder"] = self.options.endpoints.get("grounder", {})
            try:
                self.agent = load_agent(self.options.agent, opts)
            except JarvisError as exc:
                raise pytest.UsageError(f"--agent {self.options.agent}: {exc}") from None
        return self.agent

    def params(self, kind: str, config: pytest.Config) -> list[Any]:
        """The pytest params of the atomic or composed tasks (loaded once; a bad task file is a usage error)."""
        if kind not in self._params:
            try:
                self._params[kind] = cases.params(kind, self.options, config)
            except ConfigError as exc:
                raise pytest.UsageError(f"bad task data: {exc}") from None
        return self._params[kind]

    def ensure_context(self) -> RunContext:
        if self.context is None:
            from jarvis_pytest.plugin.environments import make_environments

            self.context = RunContext(
                run_dir=self.run_dir, agent=self.ensure_agent(),
                environments=make_environments(self.options, run_id=self.run_dir.name, worker=self.worker),
                limits=self.options.limits, keep_devices=self.options.keep_devices, on_keep=_print_kept,
                qc=self.options.qc,
            )
        return self.context

    def close(self) -> None:
        if self.context is not None:
            self.context.environments.close()
            self.context = None


SESSION_KEY = pytest.StashKey[JarvisSession]()
_CURRENT: JarvisSession | None = None  # this process's session, for hooks that get no config (logreport)


def get(config: pytest.Config) -> JarvisSession:
    return config.stash[SESSION_KEY]


class _XdistHooks:
    """Registered only when xdist is active: hand the controller's run directory to each worker."""

    def __init__(self, run_dir: Path):
        self.run_dir = run_dir

    def pytest_configure_node(self, node) -> None:
        node.workerinput["jarvis_run_dir"] = str(self.run_dir)


def _check_transfer_image(flavour: str) -> None:
    """A drive image that must be pulled is had (or pulled) once, at start-up: one clear error, not one per task."""
    from jarvis_pytest.infra.engine import client
    from jarvis_pytest.infra.transfer_server import transfer_server

    server = transfer_server(flavour)
    try:
        docker = client()
        try:
            docker.images.get(server.image)
        except Exception:
            docker.images.pull(server.image)
    except Exception as exc:
        first = str(exc).splitlines()[0][:300] if str(exc) else exc.__class__.__name__
        raise pytest.UsageError(
            f"--transfer {flavour}: the image {server.image} is not here and cannot be pulled ({first}); use "
            "--transfer copyparty (offline default), or load the image (`docker load`) or set JARVIS_ALIST_IMAGE "
            "to one you have") from None


def configure(config: pytest.Config) -> None:
    try:
        options = read_options(config)
    except ConfigError as exc:
        raise pytest.UsageError(str(exc)) from None
    workerinput = getattr(config, "workerinput", None)
    if workerinput is not None:
        run_dir = Path(workerinput["jarvis_run_dir"])
        worker = workerinput.get("workerid", "gw?")
    else:
        run_dir = (options.resume or options.results_dir or REPO_ROOT / "reports" / new_run_id()).resolve()
        worker = "main"
    session = JarvisSession(options=options, run_dir=run_dir, is_controller=workerinput is None, worker=worker)
    config.stash[SESSION_KEY] = session
    global _CURRENT
    _CURRENT = session
    if session.is_controller and config.pluginmanager.hasplugin("xdist"):
        config.pluginmanager.register(_XdistHooks(run_dir), "jarvis-xdist")
    if session.is_controller and options.agent:
        agent = session.ensure_agent()  # an unknown agent or a bad option is one clear error, now
        session.params("atomic", config), session.params("composed", config)  # so is a malformed task file
        preflight = getattr(agent, "preflight", None)
        if preflight is not None:
            try:
                preflight()
            except JarvisError as exc:
                raise pytest.UsageError(f"--agent {options.agent}: {exc}") from None
        if options.transfer not in (None, "copyparty"):
            _check_transfer_image(options.transfer)
        if config.pluginmanager.hasplugin("html") and not getattr(config.option, "htmlpath", None):
            config.option.htmlpath = str(run_dir / "report.html")
    from jarvis_pytest.plugin import html

    html.register(config)


def parametrize(metafunc: pytest.Metafunc) -> None:
    kind = getattr(metafunc.module, "JARVIS_TASKS", "atomic")
    metafunc.parametrize("jarvis_task", get(metafunc.config).params(kind, metafunc.config))


def _task_of(item: pytest.Item) -> dict[str, Any] | None:
    """The task of a task case (None for other items, and for an empty parameter set)."""
    task = getattr(getattr(item, "callspec", None), "params", {}).get("jarvis_task")
    return task if isinstance(task, dict) else None


def check_collected(config: pytest.Config, items: list[pytest.Item]) -> None:
    jarvis_items = [i for i in items if _task_of(i) is not None]
    if not jarvis_items:
        return
    session = get(config)
    if not session.options.agent:
        raise pytest.UsageError("choose an agent with --agent NAME (e.g. --agent oracle to check the tasks, "
                                "--agent holo2 with --planner-base-url/--grounder-base-url for a model)")
    # Longest tasks first (more subtasks), ties by id: keeps xdist workers busy to the end, and is deterministic.
    order = {id(i): (-len(_task_of(i)["formatted_subtasks"]), i.nodeid) for i in jarvis_items}
    positions = [n for n, i in enumerate(items) if id(i) in order]
    for pos, item in zip(positions, sorted(jarvis_items, key=lambda i: order[id(i)])):
        items[pos] = item


def write_plan(session_: pytest.Session) -> None:
    """`plan.json`: the ids of the tasks this session will run (the dashboard shows those not started as
    pending). Every xdist worker collects the same items, so whichever writes it writes the same file."""
    ids = sorted(t["id"] for t in map(_task_of, session_.items) if t is not None)
    if ids:
        run_dir = get(session_.config).run_dir
        run_dir.mkdir(parents=True, exist_ok=True)
        write_json_atomic(run_dir / "plan.json", {"tasks": ids, "written": now_iso()})


def prewarm_next(item: pytest.Item, nextitem: pytest.Item | None) -> None:
    session = get(item.config)
    if not session.options.prewarm or session.context is None or nextitem is None:
        return
    task = _task_of(nextitem)
    if task is not None:
        session.context.environments.prewarm(task_platforms(task))


def _compact(result: TaskResult, run_dir: Path) -> dict[str, Any]:
    data = result.model_dump(mode="json", include={
        "task_id", "category", "platforms", "status", "steps", "end_reason", "error", "durations", "agent",
        "first_screenshot", "last_screenshot", "instruction"})
    data["subtasks"] = [{"index": s.index, "template": s.template, "platform": s.platform, "passed": s.passed}
                        for s in result.subtasks]
    data["dir"] = str((run_dir / "tasks").resolve())
    return data


def run_case(request: pytest.FixtureRequest, task: dict[str, Any]) -> TaskResult:
    session = get(request.config)
    agent = session.ensure_agent()
    if session.options.resume:
        stored = read_result(session.run_dir, task["id"])
        key = agent_key(agent.config(), session.options.limits)
        if stored is not None and stored.status in ("passed", "failed") and stored.agent_key == key:
            request.node.user_properties.append((PROPERTY, _compact(stored, session.run_dir) | {"resumed": True}))
            return stored
    ctx = session.ensure_context()
    try:
        result = run_task(task, ctx)
    except (InfrastructureError, ConfigError) as exc:
        stored = read_result(session.run_dir, task["id"])
        if stored is not None:
            request.node.user_properties.append((PROPERTY, _compact(stored, session.run_dir)))
        pytest.fail(f"infrastructure error ({exc.__class__.__name__}): {exc}", pytrace=False)
    request.node.user_properties.append((PROPERTY, _compact(result, session.run_dir)))
    return result


def assert_task_passed(result: TaskResult) -> None:
    """The test body of every task case: fail with each failed subtask and its evaluators' reasons."""
    if result.status == "passed":
        return
    if result.qc_initial is not None:
        pytest.fail(qc_message(result), pytrace=False)
    pytest.fail(failure_message(result.subtasks, result.end_reason, result.steps), pytrace=False)


def collect_report(report: pytest.TestReport) -> None:
    for name, value in report.user_properties:
        if name != PROPERTY:
            continue
        if _CURRENT is not None and (report.when == "call" or (report.when == "setup" and report.failed)):
            _CURRENT.results[value["task_id"]] = TaskResult.model_validate(value)


SECRET_OPTION = ("key", "token", "secret", "password")


def redacted_argv(argv: list[str]) -> list[str]:
    """The command line with the values of secret options (`--planner-api-key K`, `--x-token=K`) hidden."""
    out: list[str] = []
    hide_next = False
    for arg in argv:
        name, eq, _ = arg.partition("=")
        secret = arg.startswith("--") and any(w in name.lower() for w in SECRET_OPTION)
        if hide_next:
            out.append("***")
        elif secret and eq:
            out.append(f"{name}=***")
        else:
            out.append(arg)
        hide_next = secret and not eq
    return out


def _write_run_files(session: JarvisSession) -> None:
    from jarvis_pytest.report.rollup import write_summary

    session.run_dir.mkdir(parents=True, exist_ok=True)
    results = [session.results[k] for k in sorted(session.results)]
    agent = results[0].agent if results else {}
    write_json_atomic(session.run_dir / "run.json", {
        "run_id": session.run_dir.name, "agent": agent, "started": session.started, "finished": now_iso(),
        "argv": redacted_argv(sys.argv[1:]), "tasks": len(results),
        "options": {"max_steps": session.options.limits.max_steps, "instances": session.options.instances},
    })
    write_summary(session.run_dir, results, agent)


def finish(session_: pytest.Session) -> None:
    session = get(session_.config)
    session.close()
    if session.is_controller and session.results:
        _write_run_files(session)


def terminal_summary(terminalreporter, config: pytest.Config) -> None:
    session = get(config)
    if not (session.is_controller and session.results):
        return
    from jarvis_pytest.report.rollup import render_terminal, rollup

    results = [session.results[k] for k in sorted(session.results)]
    terminalreporter.section("jarvis: task success rates")
    terminalreporter.write_line(render_terminal(rollup(results)))
    terminalreporter.write_line(f"results: {session.run_dir}")
    html = getattr(config.option, "htmlpath", None)
    if html:
        terminalreporter.write_line(f"report:  {Path(html).resolve()}")


def _print_kept(env: Any) -> None:
    # the process's real stderr: pytest captures sys.stderr while a test runs
    print(f"\n[jarvis] --keep-devices: {env.describe()}", file=sys.__stderr__, flush=True)
