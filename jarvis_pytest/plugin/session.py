"""The benchmark session: one object per pytest process, registered as a plugin (as pytest-xdist's `DSession`),
that owns the run's state and implements the plugin's hooks.

The controller (the only process without xdist, or the xdist controller) checks the options, the agent and its
model endpoints once, chooses the run directory, writes `run.json` (with a heartbeat) and, at the end, the
summary of everything the run holds on disk. Workers run tasks and attach a compact result to
`report.user_properties`. Whatever stops the session — the end, Ctrl-C, SIGTERM — it removes the run's devices
and says in `run.json` and the summary how far it got; the next run removes what killed runs left. The
controller holds the run's folder against other runs from its first moment (`results/run_lock.py`) and checks
that it can take the run's files (`results/storage.py`); a folder that stops taking them ends the run.
"""

from __future__ import annotations

import contextlib
import signal
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

from jarvis_pytest.errors import ConfigError, InfrastructureError, JarvisError
from jarvis_pytest.plugin import cases, conditions
from jarvis_pytest.harness.evaluation import failure_message, qc_message
from jarvis_pytest.plugin.options import REPO_ROOT, JarvisOptions, read_options
from jarvis_pytest.harness.runner import RunContext, agent_key, run_task, task_platforms
from jarvis_pytest.results import run_state, storage
from jarvis_pytest.results.run_state import new_run_id
from jarvis_pytest.results.model import TaskResult
from jarvis_pytest.results.run_lock import RunLock
from jarvis_pytest.harness.availability import skip_reason
from jarvis_pytest.results.writer import now_iso, read_result, task_dir, write_json_atomic
from jarvis_pytest.tasks.model import Task

if TYPE_CHECKING:
    from jarvis_pytest.devices.backend import Backends

PROPERTY = cases.PROPERTY
PLUGIN_NAME = "jarvis-session"
BACKENDS_INPUT = "jarvis_backends"  # the controller's choice of backends, handed to each xdist worker


def get(config: pytest.Config) -> "JarvisSession":
    """The session of this pytest process."""
    return config.pluginmanager.get_plugin(PLUGIN_NAME)


def _case_of(item: pytest.Item) -> cases.TaskCase | None:
    """The case of a task item (None for other items, and for an empty parameter set)."""
    case = getattr(getattr(item, "callspec", None), "params", {}).get("jarvis_task")
    return case if isinstance(case, cases.TaskCase) else None


def _task_of(item: pytest.Item) -> Task | None:
    """The task of a task item, made now if it was not yet (None for other items)."""
    case = _case_of(item)
    return case.task if case is not None else None


@contextlib.contextmanager
def _task_data_checked():
    """A bad task (its file, or an instance of it) stops the run with one clear usage error."""
    try:
        yield
    except ConfigError as exc:
        raise pytest.UsageError(f"bad task data: {exc}") from None


NO_AGENT = ("choose an agent with --agent NAME (e.g. --agent oracle to check the tasks, --agent holo2 with "
            "--planner-base-url/--grounder-base-url for a model)")
TASK_TESTS = ("test_atomic", "test_composed")  # the benchmark's test functions (tasks/test_*.py)

def _sigterm_as_interrupt() -> None:
    """SIGTERM stops the session like Ctrl-C (devices removed, results kept), unless someone else handles it.
    On both, every model call in flight in any thread is cut first, so that no slow endpoint holds up the stop
    (the start-up check included)."""
    from jarvis_pytest.llm.transport import stop_all

    def handler(signum, frame):
        stop_all()
        raise KeyboardInterrupt(f"signal {signum}")

    try:
        if signal.getsignal(signal.SIGTERM) in (signal.SIG_DFL, None):
            signal.signal(signal.SIGTERM, handler)
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            signal.signal(signal.SIGINT, handler)
    except ValueError:  # not the main thread
        pass


class JarvisSession:
    """Options, run directory, agent and devices of this process, and the plugin hooks that use them."""

    def __init__(self, config: pytest.Config, options: JarvisOptions, run_dir: Path, worker: str | None,
                 decided: dict[str, dict[str, str]] | None = None):
        self.config = config
        self.options = options
        self.run_dir = run_dir
        self.is_controller = worker is None
        self.worker = worker or "main"
        self.agent: Any = None
        self.context: RunContext | None = None
        self.platforms: set[str] | None = None  # the platforms of the tasks this process may run (None: not known)
        self.state: run_state.RunState | None = None
        self.new_run = options.resume is None
        self.interrupted = False
        self.summary = None  # the controller's rollup, written at the end
        self.next_platforms: tuple[str, ...] | None = None  # this worker's next task's platforms
        self._params: dict[str, list[Any]] = {}
        self.lock: RunLock | None = None  # the controller's hold on the results folder (`results/run_lock.py`)
        self.storage_failure: str | None = None  # why the results folder stopped taking files, once it did
        self._end_unwritten = False  # the end of the run could not be written (said once)
        self._decided = decided  # an xdist worker: the backends its controller chose (`Backends.decided`)
        self._backends: Backends | None = None

    @property
    def backends(self) -> "Backends":
        """The run's backends, resolved once in this process from the options (a worker: as its controller chose
        them, so every process runs the same ones); everything that boots, skips or lists images uses these."""
        if self._backends is None:
            from jarvis_pytest.devices.backend import resolve_backends

            self._backends = resolve_backends(self.options.backends, self.options.backend_options,
                                              decided=self._decided)
        return self._backends

    # -- start-up (controller) ------------------------------------------------------------------------------
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

    def params(self, kind: str) -> list[Any]:
        """The pytest params of the atomic or composed tasks (loaded once; a bad task file is a usage error)."""
        if kind not in self._params:
            with _task_data_checked():
                self._params[kind] = cases.params(kind, self.options, self.config)
        return self._params[kind]

    def all_cases(self) -> list[cases.TaskCase]:
        return [p.values[0] for kind in ("atomic", "composed") for p in self.params(kind)]

    def start(self) -> None:
        """Everything that can be wrong is found now, once, before any device boots: the results folder (held
        against other runs, writable, not full), the task data, the agent, its model endpoints (one real request
        each), the drive image, a run directory to resume."""
        self.take_results_folder()
        try:
            self._start()
        except BaseException:
            self.release_results_folder()
            raise

    def take_results_folder(self) -> None:
        """Hold the run's folder against other runs (before anything is written into it), then check that it
        can take the run's files: ConfigError naming the folder (and the live run's pid) if not."""
        self.lock = RunLock(self.run_dir)
        self.lock.acquire(keep_devices=self.options.keep_devices)
        if self.options.resume is None or self.run_dir.is_dir():  # a missing run to resume: `_check_resume` says so
            storage.check(self.run_dir, "--resume" if self.options.resume is not None else "--results-dir")

    def release_results_folder(self) -> None:
        if self.lock is not None:
            self.lock.release()

    def _start(self) -> None:
        agent = self.ensure_agent()
        found = self.all_cases()
        preflight = getattr(agent, "preflight", None)
        if preflight is not None:
            try:
                preflight()
            except JarvisError as exc:
                raise pytest.UsageError(f"--agent {self.options.agent}: {exc}") from None
        if self.options.transfer not in (None, "copyparty"):
            _check_transfer_image(self.options.transfer)
        for platform in self.options.backends:  # a backend asked for by name must be able to run
            backend = self.backends[platform]
            why = backend.unavailable()
            if why:
                raise ConfigError(f"the {backend.label} device cannot run on this machine: {why}",
                                  field=f"--{platform}-backend", fix=backend.how_to_run or "choose another backend")
        key = agent_key(agent.config(), self.options.limits)
        if self.options.resume is not None:
            self._check_resume(key, agent.config(), found)
        _check_engines(self.options.docker_hosts)
        nodes = _check_cluster(self.options.ray)
        _remove_orphans(self.options.docker_hosts, self.options.ray)
        if self.lock is not None and not self.lock.was_kept:  # this folder's earlier, dead sessions' leftovers
            _remove_run_resources(run_state.resource_id(self.run_dir), self.options.docker_hosts,  # (none of ours yet)
                                  self.options.ray)
        argv = redacted_argv(sys.argv[1:])
        card = conditions.start_card(self.options, self.config, agent.config(), self.backends, argv)
        self.state = run_state.RunState(self.run_dir, argv, resumed=not self.new_run)
        self.state.start(agent=agent.config(), agent_key=key, egress=self.options.allow_egress,
                         backends=self.backends.record(),
                         options={"max_steps": self.options.limits.max_steps, "instances": self.options.instances,
                                  "trials": self.options.trials},
                         engines=list(dict.fromkeys([*(self.state.meta.get("engines") or []),
                                                     *self.options.docker_hosts])),  # every session's, for cleanup
                         card=card)
        if nodes is not None:  # the cluster as it was at the start (each result names the node it ran on)
            self.state.update(ray={"address": self.options.ray, "nodes": nodes})

    def pytest_report_header(self, config: pytest.Config) -> list[str] | None:
        """At the start of a run: the settings that change scores, and a warning for each unusual one."""
        card = (self.state.meta.get("card") if self.is_controller and self.state is not None else None)
        if not card:
            return None
        from jarvis_pytest.report.run_card import settings_lines, unusual

        return ([f"jarvis: {line}" for line in settings_lines(card)]
                + [f"jarvis: WARNING: {w}" for w in unusual(card)])

    def _check_resume(self, key: str, agent_config: dict[str, Any], found: list[cases.TaskCase]) -> None:
        run_dir = self.run_dir
        fix_new = "or start a new run (drop --resume)"
        meta, bad = run_state.read_run_meta(run_dir)
        if bad:
            raise ConfigError(f"run.json {bad}", path=run_dir / "run.json", field="--resume",
                              fix="restore it, or move it away (the run then resumes from its plan.json and "
                                  "tasks/), " + fix_new)
        bad = run_state.plan_problem(run_dir)
        if bad:
            raise ConfigError(f"plan.json {bad}", path=run_dir / "plan.json", field="--resume",
                              fix="restore it, or move it away (the summary then counts only the tasks with a "
                                  "result as planned), " + fix_new)
        if not run_state.is_run_dir(run_dir):
            raise ConfigError("not a run directory of jarvis-pytest (no run.json or plan.json)", path=run_dir,
                              field="--resume", fix="give a folder under reports/ written by an earlier run")
        meta = meta or {}
        if run_state.liveness(meta) == "running":
            raise ConfigError(f"this run is still going (pid {meta.get('pid')} on {meta.get('host')})", path=run_dir,
                              field="--resume", fix="wait for it to end, or stop it (Ctrl-C) first")
        from jarvis_pytest.report.rollup import load_results

        kept_results, unreadable = load_results(run_dir)
        for problem in unreadable:  # each named once; its task has no result to keep, so it runs again
            print(f"[jarvis] --resume: {problem}; that task runs again", file=sys.stderr, flush=True)
        stored_keys = {meta["agent_key"]} if meta.get("agent_key") else set()
        if not stored_keys:  # a run from before run.json kept the key: its results do
            stored_keys = {r.agent_key for r in kept_results if r.agent_key}
        if stored_keys and stored_keys != {key}:
            used = meta.get("agent") or "another configuration"
            raise ConfigError(f"the run was made with agent {used}, not {agent_config}", path=run_dir,
                              field="--resume", fix="resume with the same --agent, models and --max-steps, "
                              + fix_new)
        # A changed task is refused only where its kept result would be reused as if it were the new task's;
        # a task that errored, timed out or never ran is run again anyway, so fixing its setup is welcome.
        digests = run_state.read_plan(run_dir)["digests"]
        with _task_data_checked():  # only tasks with a kept result are made (and compared)
            changed = sorted({c.id for c in found if c.id in digests and _kept(read_result(run_dir, c.key), key)
                              and digests[c.id] != run_state.task_digest(c.task)})
        if changed:
            more = f" and {len(changed) - 3} more" if len(changed) > 3 else ""
            raise ConfigError(f"tasks with a result changed since the run was planned: "
                              f"{', '.join(changed[:3])}{more}",
                              path=run_dir, field="--resume", fix="resume with the same library, datasets and "
                              "options (--library, --dataset), " + fix_new)

    # -- collection -----------------------------------------------------------------------------------------
    def pytest_generate_tests(self, metafunc: pytest.Metafunc) -> None:
        if "jarvis_task" in metafunc.fixturenames:
            kind = getattr(metafunc.module, "JARVIS_TASKS", "atomic")
            metafunc.parametrize("jarvis_task", self.params(kind))

    @pytest.hookimpl(trylast=True)  # after -m/-k deselected: it sees, orders and asks an agent for what is left
    def pytest_collection_modifyitems(self, session: pytest.Session, config: pytest.Config,
                                      items: list[pytest.Item]) -> None:
        if self.options.reproduce is not None:
            self._keep_planned(config, items)
        jarvis_items = [i for i in items if _case_of(i) is not None]
        if not jarvis_items:
            return
        if not self.options.agent and not config.option.collectonly:  # listing the tasks needs no agent
            if not self.is_controller:  # an xdist worker: its controller stops the run (`_XdistHooks`)
                return
            raise pytest.UsageError(NO_AGENT)
        # Longest tasks first (more subtasks), ties by id: keeps xdist workers busy to the end, deterministic.
        order = {id(i): (-_case_of(i).size, i.nodeid) for i in jarvis_items}
        positions = [n for n, i in enumerate(items) if id(i) in order]
        for pos, item in zip(positions, sorted(jarvis_items, key=lambda i: order[id(i)])):
            items[pos] = item

    def _keep_planned(self, config: pytest.Config, items: list[pytest.Item]) -> None:
        """--reproduce RUN_DIR: deselect every task case its plan.json does not name; say which it names that
        are not here (a template or dataset that changed since)."""
        planned = set(run_state.read_plan(self.options.reproduce)["tasks"])
        keep = [i for i in items if _case_of(i) is None or _case_of(i).key in planned]
        dropped = [i for i in items if _case_of(i) is not None and _case_of(i).key not in planned]
        if dropped:
            config.hook.pytest_deselected(items=dropped)
            items[:] = keep
        missing = planned - {_case_of(i).key for i in keep if _case_of(i) is not None}
        if missing and self.is_controller:
            names = sorted(missing)
            more = f" and {len(names) - 3} more" if len(names) > 3 else ""
            print(f"[jarvis] --reproduce {self.options.reproduce}: {len(names)} planned task(s) not found "
                  f"here: {', '.join(names[:3])}{more} (not collected: check the test paths, --library, --dataset "
                  f"and --trials)", file=sys.stderr, flush=True)

    def pytest_collection_finish(self, session: pytest.Session) -> None:
        """plan.json gains the tasks this session will run (the dashboard shows those not started as pending;
        the summary counts those never run). Every xdist worker collects the same items: each writes the same."""
        if self.config.option.collectonly or not self.options.agent:
            return
        with _task_data_checked():  # the selected tasks are made now: a bad one is found before any device boots
            selected = [(c.key, c.task) for c in map(_case_of, session.items) if c is not None]
        tasks = list({id(t): t for _, t in selected}.values())  # each task once, whatever its trials
        if selected and (self.state is not None or not self.is_controller):
            run_state.merge_plan(self.run_dir, selected)
        if selected and self.state is not None and self.state.meta.get("card"):
            from jarvis_pytest.report.run_card import plan_digest

            plan = run_state.read_plan(self.run_dir)
            self.state.update(card={**self.state.meta["card"], "tasks": {
                **self.state.meta["card"]["tasks"], "planned": len(plan["tasks"]),
                "plan_digest": plan_digest(plan["tasks"], plan["digests"])}})
        if self.options.ray:  # the images its nodes need
            self.platforms = {p for t in tasks if skip_reason(t, self.backends) is None for p in task_platforms(t)}
        if tasks and self.options.docker_hosts:  # the images this process's tasks need, on its engine
            _copy_images_to_engine(self.options, self.backends, self.worker, tasks)
        if tasks and not self.is_controller:
            self._prewarm_first(tasks)

    def _prewarm_first(self, tasks: list[Task]) -> None:
        """An xdist worker learns its first task only when every worker has collected and the controller has
        scheduled: boot ahead, for the platforms most of the run's tasks need, so that wait hides the first boot
        too. A wrong guess costs one environment that waits for a later task of its platforms (or the end).
        Not with --resume (kept results make the guess poor) nor when some workers may get no task at all."""
        workers = int(getattr(self.config, "workerinput", {}).get("workercount", 1))
        runnable = [task_platforms(t) for t in tasks if skip_reason(t, self.backends) is None]
        if not self.options.prewarm or self.options.resume is not None or len(runnable) < workers:
            return
        from collections import Counter

        platforms = Counter(runnable).most_common(1)[0][0]
        try:
            self.ensure_context().environments.prewarm(platforms)
        except JarvisError:
            return  # the first task meets the same error, where it is reported

    # -- running --------------------------------------------------------------------------------------------
    def ensure_context(self) -> RunContext:
        if self.context is None:
            o = self.options
            settings = dict(keep_devices=o.keep_devices, device_memory=o.device_memory, device_cpus=o.device_cpus,
                            transfer=o.transfer, egress=o.allow_egress, prewarm=o.prewarm,
                            prewarm_reserve_mb=o.prewarm_reserve_mb)
            run_id = run_state.resource_id(self.run_dir)
            if o.ray:  # each task's devices on a Ray node (`cluster/`); the agent loop stays here
                from jarvis_pytest.cluster.environments import make_cluster_environments

                environments = make_cluster_environments(o.ray, self.backends, run_id=run_id, worker=self.worker,
                                                         platforms=self.platforms, **settings)
            else:
                from jarvis_pytest.harness.environments import make_environments

                environments = make_environments(self.backends, run_id=run_id, worker=self.worker,
                                                 docker_hosts=o.docker_hosts, **settings)
            self.context = RunContext(
                run_dir=self.run_dir, agent=self.ensure_agent(), environments=environments,
                limits=self.options.limits, keep_devices=self.options.keep_devices, on_keep=_print_kept,
                qc=self.options.qc, egress=self.options.allow_egress,
            )
        return self.context

    @pytest.hookimpl(hookwrapper=True)
    def pytest_runtest_protocol(self, item: pytest.Item, nextitem: pytest.Item | None):
        """Remember the next task of this worker: its devices boot while this one runs (`run_task` starts them
        once this task has its own)."""
        task = _task_of(nextitem) if nextitem is not None else None
        self.next_platforms = task_platforms(task) if task is not None and self.options.prewarm else None
        yield

    def run_case(self, request: pytest.FixtureRequest, case: cases.TaskCase) -> TaskResult:
        """The task's result (kept, skipped or run now). A results folder that stopped taking files (full,
        read-only, gone) ends the run instead: this task errors naming the folder, no later task starts, the
        devices are removed at the end and what was written stays."""
        why = self.storage_failure or storage.problem(self.run_dir, create=False)
        if why is None:
            try:
                return self._run_case(request, case)
            except OSError:
                why = storage.problem(self.run_dir, create=False)
                if why is None:
                    raise  # not the results folder: a harness bug, shown as one
        self.storage_failure = why  # outside the handler: pytest shows the message, not the chain behind it
        message = (f"{self.run_dir}: {why}; the run stops here: its devices are removed and what it wrote is kept "
                   f"(free space, then --resume {self.run_dir})")
        request.session.shouldstop = message
        pytest.fail(message, pytrace=False)

    def _run_case(self, request: pytest.FixtureRequest, case: cases.TaskCase) -> TaskResult:
        agent = self.ensure_agent()
        task = case.task
        reason = skip_reason(task, self.backends, agent)
        if reason is not None:  # a device this machine lacks: skipped with the reason, counted apart, never failed
            result = TaskResult(task_id=task.id, category=task.category,
                                platforms=list(task_platforms(task)), instruction=task.instruction,
                                status="skipped", error=reason, agent=agent.config(),
                                agent_key=agent_key(agent.config(), self.options.limits), started=now_iso(),
                                finished=now_iso(), trial=case.trial)
            folder = task_dir(self.run_dir, case.key)
            folder.mkdir(parents=True, exist_ok=True)
            write_json_atomic(folder / "result.json", result.model_dump(mode="json"))
            request.node.user_properties.append((PROPERTY, _compact(result, self.run_dir)))
            pytest.skip(reason)
        if self.options.resume:
            stored = read_result(self.run_dir, case.key)
            key = agent_key(agent.config(), self.options.limits)
            if _kept(stored, key):
                request.node.user_properties.append((PROPERTY, _compact(stored, self.run_dir) | {"resumed": True}))
                return stored
        ctx = self.ensure_context()
        ctx.prewarm_next = self.next_platforms
        failure = None
        try:
            result = run_task(task, ctx, trial=case.trial)
        except (InfrastructureError, ConfigError) as exc:
            stored = read_result(self.run_dir, case.key)
            if stored is not None:
                request.node.user_properties.append((PROPERTY, _compact(stored, self.run_dir)))
            failure = f"infrastructure error ({exc.__class__.__name__}): {exc}"
        if failure is not None:  # raised outside the handler: pytest prints it once, not chained to its cause
            pytest.fail(failure, pytrace=False)
        request.node.user_properties.append((PROPERTY, _compact(result, self.run_dir)))
        if result.status == "timeout":
            pytest.fail(f"timeout: the task's time limit ({self.options.limits.task_timeout:g} s) passed after "
                        f"{result.steps} steps (counted apart from the rates)", pytrace=False)
        return result

    def pytest_keyboard_interrupt(self, excinfo) -> None:
        self.interrupted = True

    # -- the end --------------------------------------------------------------------------------------------
    def close(self) -> None:
        if self.context is not None:
            self.context.environments.close()
            self.context = None

    @pytest.hookimpl(hookwrapper=True)
    def pytest_sessionfinish(self, session: pytest.Session, exitstatus):
        """First (before pytest-html writes its report): remove this process's devices; the controller marks the
        run finished or interrupted and writes the summary of everything the run holds. Last (after xdist stopped
        its workers): the controller removes whatever of the run is still there (a worker stopped in the middle
        of a task may leave its devices)."""
        self.close()
        run_id = run_state.resource_id(self.run_dir)
        if self.is_controller and self.state is not None:
            interrupted = self.interrupted or int(exitstatus) == int(pytest.ExitCode.INTERRUPTED)
            try:
                from jarvis_pytest.report.rollup import load_results

                results, _ = load_results(self.run_dir)  # read once: for the run card and the summary
                self.state.finish(interrupted or self.storage_failure is not None, int(exitstatus),
                                  **self._finished_card(results))
                if (self.new_run and not (self.run_dir / "plan.json").exists()
                        and not (self.run_dir / "tasks").exists()):
                    (self.run_dir / "run.json").unlink(missing_ok=True)  # nothing was selected: no empty run left
                    self.state = None
                else:
                    self.summary = self.write_summary(results)
            except OSError as exc:  # the folder filled or went read-only: say so once; the devices still go
                self._storage_failed(exc)
        outcome = yield
        if (isinstance(outcome.exception, OSError) and self.is_controller
                and storage.problem(self.run_dir, create=False)):
            self._storage_failed(outcome.exception)  # pytest-html's report.html in a folder that cannot take it
            outcome.force_result(None)
        # devices this session or an earlier one of the folder kept (--keep-devices) wait for `jarvis cleanup`
        keep = self.options.keep_devices or (self.lock is not None and self.lock.keep_devices)
        if self.is_controller and (self.state is not None or self.interrupted) and not keep:
            _remove_run_resources(run_id, self.options.docker_hosts, self.options.ray)
        self.release_results_folder()

    def _finished_card(self, results: list[TaskResult]) -> dict[str, Any]:
        """{"card": the run card with what the devices of `results` turned out to be} (nothing for a run without a
        card)."""
        card = self.state.meta.get("card") if self.state is not None else None
        if not card:
            return {}
        from jarvis_pytest.report.run_card import with_results

        return {"card": with_results(card, results)}

    def _storage_failed(self, exc: OSError) -> None:
        """One line on stderr, once, when the end of the run (run.json, the summary, report.html) could not be
        written into the results folder."""
        if self._end_unwritten:
            return
        self._end_unwritten = True
        why = storage.problem(self.run_dir, create=False) or f"{exc.strerror or exc}"
        self.storage_failure = self.storage_failure or why
        print(f"[jarvis] {self.run_dir}: {why}: the end of the run (run.json, the summary, report.html) was not "
              "written; what was written before is kept", file=sys.stderr, flush=True)

    def pytest_unconfigure(self, config: pytest.Config) -> None:
        self.release_results_folder()  # a session that ended before its finish (the lock also dies with us)

    def write_summary(self, results: list[TaskResult]):
        """summary.json and summary.md over `results` (every result of the run on disk) and every task it planned."""
        from jarvis_pytest.report.rollup import write_summary

        planned = run_state.read_plan(self.run_dir)["categories"]
        agent = (self.state.meta.get("agent") if self.state else None) or (results[0].agent if results else {})
        return write_summary(self.run_dir, results, agent, planned=planned)

    def pytest_terminal_summary(self, terminalreporter, exitstatus, config: pytest.Config) -> None:
        if not self.is_controller or self.summary is None:
            return
        from jarvis_pytest.report.rollup import render_terminal

        terminalreporter.section("jarvis: task success rates")
        terminalreporter.write_line(render_terminal(self.summary))
        terminalreporter.write_line(f"results: {self.run_dir}")
        html = getattr(config.option, "htmlpath", None)
        if html:
            terminalreporter.write_line(f"report:  {Path(html).resolve()}")


class _XdistHooks:
    """Registered only when xdist is active: hand the controller's run directory and, in a run, its backends to
    each worker; stop a run whose workers collected tasks when no agent was chosen (a worker's usage error would be
    xdist's INTERNALERROR)."""

    def __init__(self, session: JarvisSession, needs_agent: bool):
        self.session = session
        self.run_dir = session.run_dir
        self.needs_agent = needs_agent

    def pytest_configure_node(self, node) -> None:
        node.workerinput["jarvis_run_dir"] = str(self.run_dir)
        if self.session.state is not None:  # a run that started: its workers run the backends it chose
            node.workerinput[BACKENDS_INPUT] = self.session.backends.decided()

    def pytest_xdist_node_collection_finished(self, node, ids: list[str]) -> None:
        if self.needs_agent and any(f"::{name}[" in i for i in ids for name in TASK_TESTS):
            pytest.exit(f"ERROR: {NO_AGENT}", returncode=pytest.ExitCode.USAGE_ERROR)


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


def _check_engines(hosts: tuple[str, ...]) -> None:
    """Every engine of the run answers and runs on this machine: one start-up error naming the engine if not."""
    from jarvis_pytest.infra import engines

    try:
        for host in hosts:
            engines.check_on_this_machine(host)
    except JarvisError as exc:
        raise pytest.UsageError(f"--docker-host: {exc}") from None


def _copy_images_to_engine(options: JarvisOptions, backends: "Backends", worker: str, tasks: list[Task]) -> None:
    """Copy the images of the selected tasks this machine can run to this process's engine, where missing (one
    copier per engine at a time: the workers sharing an engine wait for the first)."""
    import hashlib
    import tempfile

    from filelock import FileLock

    from jarvis_pytest.infra import engines
    from jarvis_pytest.infra.transfer_server import transfer_server

    host = engines.for_worker(options.docker_hosts, worker)
    images = {transfer_server(options.transfer).image}
    for task in tasks:
        if skip_reason(task, backends) is None:
            images |= {backends[p].image_ref for p in task_platforms(task)}
    lock = Path(tempfile.gettempdir()) / f"jarvis-engine-{hashlib.sha256(str(host).encode()).hexdigest()[:12]}.lock"
    try:
        with FileLock(str(lock)):
            engines.copy_images([host] if host else [], sorted(images))
    except JarvisError as exc:
        raise pytest.UsageError(f"--docker-host: {exc}") from None


def _check_cluster(address: str | None) -> list[dict[str, Any]] | None:
    """With --ray: the cluster answers and has nodes that offer devices (one start-up error if not); its nodes."""
    if not address:
        return None
    from jarvis_pytest.cluster.connect import connect, require_nodes

    try:
        nodes = require_nodes(connect(address), address)
    except JarvisError as exc:
        raise pytest.UsageError(str(exc)) from None
    return [{"node": n.node_id, "address": n.address, "slots": n.slots, "kvm": n.kvm} for n in nodes]


def _remove_orphans(hosts: tuple[str, ...] = (), ray: str | None = None) -> None:
    """What runs whose process is gone left on the run's engines (containers, networks); live runs are safe."""
    from jarvis_pytest.cluster.cleanup import cleanup_everywhere
    from jarvis_pytest.results.run_lock import prune

    prune()
    try:
        counts = cleanup_everywhere(hosts, ray, orphans_only=True)
    except Exception as exc:  # never a reason not to run; say it
        print(f"[jarvis] could not remove what earlier runs left: {exc}", file=sys.stderr, flush=True)
        return
    if any(counts.values()):
        print("[jarvis] removed what killed runs left: " + ", ".join(f"{v} {k}" for k, v in counts.items()),
              file=sys.stderr, flush=True)


def _remove_run_resources(run_id: str, hosts: tuple[str, ...] = (), ray: str | None = None) -> None:
    from jarvis_pytest.cluster.cleanup import cleanup_everywhere

    try:
        counts = cleanup_everywhere(hosts, ray, run_id=run_id)
    except Exception as exc:
        hint = "".join(f" --docker-host {h}" for h in hosts) + (f" --ray {ray}" if ray else "")
        print(f"[jarvis] {exc}; run `jarvis cleanup --run {run_id}{hint}`", file=sys.stderr, flush=True)
        return
    if any(counts.values()):
        print("[jarvis] removed what the stopped tasks left: " + ", ".join(f"{v} {k}" for k, v in counts.items()),
              file=sys.stderr, flush=True)


def configure(config: pytest.Config) -> None:
    """Create this process's session and register it; the controller of a benchmark run starts the run."""
    try:
        options = read_options(config)
    except ConfigError as exc:
        raise pytest.UsageError(str(exc)) from None
    workerinput = getattr(config, "workerinput", None)
    if workerinput is not None:
        session = JarvisSession(config, options, Path(workerinput["jarvis_run_dir"]), workerinput.get("workerid", "gw?"),
                                decided=workerinput.get(BACKENDS_INPUT))
    else:
        given = options.resume or options.results_dir or REPO_ROOT / "reports" / new_run_id()
        try:
            run_dir = given.resolve()
        except (OSError, RuntimeError) as exc:  # a symlink loop, a path too long
            option = "--resume" if options.resume else "--results-dir"
            raise pytest.UsageError(str(ConfigError(f"cannot resolve the results folder ({exc})", path=given,
                                                    field=option, fix=f"give another {option}"))) from None
        session = JarvisSession(config, options, run_dir, None)
    config.pluginmanager.register(session, PLUGIN_NAME)
    _sigterm_as_interrupt()
    from jarvis_pytest.plugin import html

    html.register(config, session)  # xdist workers too: the screenshots are attached where the report is made
    if not session.is_controller:
        return
    if config.pluginmanager.hasplugin("xdist"):
        config.pluginmanager.register(_XdistHooks(session, not options.agent and not config.option.collectonly),
                                      "jarvis-xdist")
    if options.agent and not config.option.collectonly:
        try:
            session.start()
        except ConfigError as exc:
            raise pytest.UsageError(str(exc)) from None
        if config.pluginmanager.hasplugin("html") and not getattr(config.option, "htmlpath", None):
            config.option.htmlpath = str(session.run_dir / "report.html")


def _kept(stored: TaskResult | None, key: str) -> bool:
    """Whether --resume reuses a stored result: a verdict (passed or failed) made by the same agent setup."""
    return stored is not None and stored.status in ("passed", "failed") and stored.agent_key == key

def _compact(result: TaskResult, run_dir: Path) -> dict[str, Any]:
    data = result.model_dump(mode="json", include={
        "task_id", "category", "platforms", "status", "steps", "end_reason", "error", "durations", "agent",
        "first_screenshot", "last_screenshot", "instruction", "trial"})
    data["subtasks"] = [{"index": s.index, "template": s.template, "platform": s.platform, "passed": s.passed}
                        for s in result.subtasks]
    data["dir"] = str((run_dir / "tasks").resolve())
    return data


def assert_task_passed(result: TaskResult) -> None:
    """The test body of every task case: fail with each failed subtask and its evaluators' reasons."""
    if result.status == "passed":
        return
    if result.qc_initial is not None:
        pytest.fail(qc_message(result), pytrace=False)
    pytest.fail(failure_message(result.subtasks, result.end_reason, result.steps), pytrace=False)


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


def _print_kept(env: Any) -> None:
    # the process's real stderr: pytest captures sys.stderr while a test runs
    print(f"\n[jarvis] --keep-devices: {env.describe()}", file=sys.__stderr__, flush=True)
