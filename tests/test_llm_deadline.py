"""Every model call ends by a wall-clock deadline, provoked for real with a loopback server that answers one byte
at a time (no single read ever waits long, so httpx's per-read timeouts never trip): the start-up check, a call
inside the step loop's deadline, its retries; an abandoned call gives its connection and its concurrency slot
back; SIGINT and SIGTERM stop a real `pytest tasks` process within seconds, during the start-up check too."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from jarvis_pytest.agents.protocol import AgentStep
from jarvis_pytest.errors import ConfigError, InfrastructureError
from jarvis_pytest.llm import transport
from jarvis_pytest.llm.client import ChatClient, user_message
from jarvis_pytest.llm.deadline import deadline_at, remaining
from jarvis_pytest.llm.fake_server import FakeChatServer, Reply, dribble
from jarvis_pytest.harness.loop import GRACE, decide

REPO = Path(__file__).resolve().parents[1]
#: an answer that takes hours to dribble: without a deadline, a call (and a run's start-up check) never ends
ENDLESS = "x" * 100_000


@pytest.fixture
def server():
    with FakeChatServer(models=("m",)) as srv:
        yield srv


def wait_for(predicate, timeout: float, what: str) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}")


# -- the client ---------------------------------------------------------------------------------------------------
def test_dribbling_start_up_check_ends_within_its_budget_with_one_clear_error(server):
    server.probe_reply = dribble(0.1, ENDLESS)
    client = ChatClient(server.url, "m", timeout=120)
    t0 = time.monotonic()
    with pytest.raises(ConfigError) as info:
        client.probe(timeout=1.5)
    took = time.monotonic() - t0
    assert took < 10, f"the start-up check took {took:.1f} s of its 1.5 s"  # hang or not: the answer takes hours
    assert info.value.field == "base_url" and "no complete answer" in str(info.value) and "1.5 s" in str(info.value)
    wait_for(lambda: server.hangups == 1 and server.dribbling == 0, 2, "the server to see the connection closed")
    print(f"dribbling start-up check: ended after {took:.2f} s (budget 1.5 s)")


def test_start_up_check_budget_is_the_endpoint_timeout_when_shorter(server):
    server.probe_reply = dribble(0.1, ENDLESS)
    with pytest.raises(ConfigError, match="within 1 s"):
        ChatClient(server.url, "m", timeout=1).probe()


def test_call_and_its_retries_end_by_the_deadline(server):
    """Each attempt is cut at `timeout` (wall clock) and no attempt, back-off or slot wait outlives the deadline
    around the call."""
    server.respond_with(lambda req: dribble(0.05, ENDLESS), model="m")
    client = ChatClient(server.url, "m", timeout=0.6, max_retries=10, backoff=0.01)
    before = transport.open_connections()  # other tests' clients may keep connections alive
    t0 = time.monotonic()
    with deadline_at(t0 + 2.0), pytest.raises(InfrastructureError) as info:
        client.chat([user_message("x")])
    took = time.monotonic() - t0
    assert took < 10, f"the call took {took:.2f} s for a 2 s deadline"
    assert "no complete answer within" in str(info.value) or "deadline passed" in str(info.value)
    attempts = len(server.requests_for("m"))
    assert 2 <= attempts <= 5, attempts  # ~0.6 s each within 2 s, not one stuck forever
    wait_for(lambda: server.hangups == attempts and server.dribbling == 0, 2, "every attempt's connection closed")
    assert transport.open_connections() <= before
    print(f"retries under a 2 s deadline: {attempts} attempts of 0.6 s, ended after {took:.2f} s")


def test_slow_but_timely_answer_still_arrives(server):
    """The deadline cuts only what is late: an answer dribbled in well within it is received whole."""
    server.script(dribble(0.002, text="fine"), model="m")
    result = ChatClient(server.url, "m", timeout=30).chat([user_message("x")])
    assert result.text == "fine" and server.hangups == 0


def test_an_endless_answer_is_cut_at_its_size_limit(server, monkeypatch):
    """A fast answer that does not end would fill the memory long before any deadline: it is read up to the size
    limit, then the call is the endpoint's error (not retried), and the start-up check says so too."""
    from jarvis_pytest.llm import client as client_module

    monkeypatch.setattr(client_module, "MAX_ANSWER_BYTES", 1 << 20)
    huge = Reply(body="x" * (4 << 20))
    server.respond_with(lambda req: huge, model="m")
    client = ChatClient(server.url, "m", max_retries=3, backoff=0.01)
    with pytest.raises(InfrastructureError, match="longer than 1 MiB"):
        client.chat([user_message("x")])
    assert len(server.requests_for("m")) == 1
    server.probe_reply = huge
    with pytest.raises(ConfigError, match="longer than 1 MiB"):
        client.probe()


def test_every_network_transport_of_the_client_honours_deadlines(server, monkeypatch):
    """An environment proxy gets a transport of its own in httpx: it is wrapped too (else calls through a proxy
    would have no wall-clock deadline)."""
    monkeypatch.setenv("HTTPS_PROXY", "http://127.0.0.1:9")
    client = ChatClient(server.url, "m")
    transports = [client._http._transport, *client._http._mounts.values()]
    assert len(transports) >= 2
    for t in transports:
        assert isinstance(t._pool._network_backend, transport._DeadlineBackend)


# -- mid-run: the step loop's decision ---------------------------------------------------------------------------
class OneCallAgent:
    """An agent whose decision is one model call (what a model adapter does)."""

    def __init__(self, client: ChatClient):
        self.client = client

    def act(self, observations, history) -> AgentStep:
        self.client.chat([user_message("next step?")])
        return AgentStep(platform=None, action=None)


def test_mid_run_call_ends_by_the_step_deadline_not_when_abandoned(server):
    """Within the step loop's `decide`, a dribbling endpoint: the call itself gives up at the step deadline (an
    infrastructure error), before the loop would abandon its thread, and the connection is closed."""
    server.respond_with(lambda req: dribble(0.1, ENDLESS), model="m")
    agent = OneCallAgent(ChatClient(server.url, "m", timeout=300, max_retries=0))
    t0 = time.monotonic()
    with pytest.raises(InfrastructureError, match="no complete answer"):  # not None: the thread ended itself
        decide(agent, {}, [], t0 + 1.5)
    took = time.monotonic() - t0
    wait_for(lambda: server.hangups == 1 and server.dribbling == 0, 2, "the connection closed")
    print(f"mid-run dribbling call: ended after {took:.2f} s (step deadline 1.5 s, loop grace {GRACE:g} s)")


def test_abandoned_calls_give_their_slots_back(server):
    """More calls than the endpoint's concurrency limit run out of time one after another; a later call still
    reaches the model at once (a slot kept by each abandoned call would block it forever)."""
    limit = 2
    server.respond_with(lambda req: dribble(0.2, ENDLESS), model="m")
    agent = OneCallAgent(ChatClient(server.url, "m", timeout=300, max_retries=0, max_concurrency=limit))
    for _ in range(limit + 2):
        try:
            decide(agent, {}, [], time.monotonic() + 0.5)
        except InfrastructureError:
            pass
    server.respond_with(lambda req: "here", model="m")
    t0 = time.monotonic()
    with deadline_at(t0 + 5):
        result = agent.client.chat([user_message("still there?")])
    assert result.text == "here", result
    assert len(server.requests_for("m")) == limit + 3
    print(f"after {limit + 2} abandoned calls (limit {limit}): the next call answered in "
          f"{time.monotonic() - t0:.3f} s")


def test_a_call_waiting_for_a_slot_ends_by_its_deadline(server):
    """When every slot is busy, waiting for one counts against the call's deadline too."""
    server.respond_with(lambda req: dribble(0.2, ENDLESS), model="m")
    client = ChatClient(server.url, "m", timeout=300, max_retries=0, max_concurrency=1)
    holder = threading.Thread(target=lambda: _quietly(client, 3.0), daemon=True)
    holder.start()
    wait_for(lambda: server.dribbling == 1, 2, "the first call to hold the slot")
    t0 = time.monotonic()
    with deadline_at(t0 + 0.5), pytest.raises(InfrastructureError, match="no free slot"):
        client.chat([user_message("x")])
    holder.join(5)


def _quietly(client: ChatClient, seconds: float) -> None:
    with deadline_at(time.monotonic() + seconds):
        try:
            client.chat([user_message("hold")])
        except InfrastructureError:
            pass


def test_nested_deadlines_keep_the_earlier():
    now = time.monotonic()
    with deadline_at(now + 1):
        with deadline_at(now + 100):
            assert remaining() <= 1
        with deadline_at(None):
            assert remaining() <= 1
    assert remaining() is None


STOP_SCRIPT = """
import sys, threading, time
from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.llm.client import ChatClient, user_message
from jarvis_pytest.llm.fake_server import FakeChatServer, dribble, fail
from jarvis_pytest.llm import transport

with FakeChatServer(models=("m",)) as srv:
    srv.script(fail(503, retry_after=30), model="m")   # the first call waits 30 s before its retry
    srv.script(dribble(0.5), model="m")                 # the second is being dribbled
    errors = []
    def call():
        try:
            ChatClient(srv.url, "m", timeout=300, max_retries=2, max_backoff=60).chat([user_message("x")])
        except InfrastructureError as exc:
            errors.append(str(exc))
    threads = [threading.Thread(target=call) for _ in range(2)]
    for t in threads:
        t.start()
    while srv.received < 2 or srv.dribbling < 1:
        time.sleep(0.02)
    t0 = time.monotonic()
    cut = transport.stop_all()
    for t in threads:
        t.join(10)
    print(f"{time.monotonic() - t0:.3f} {cut} {sum(t.is_alive() for t in threads)}")
    print(*errors, sep="\\n")
"""


def test_stop_all_ends_calls_in_flight_and_in_back_off_at_once():
    """`stop_all` (what SIGINT and SIGTERM call) ends a call waiting out a 30 s back-off and a call being
    dribbled, in other threads, at once. In a process of its own: stopping is for the rest of the process."""
    proc = subprocess.run([sys.executable, "-c", STOP_SCRIPT], cwd=REPO, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr[-3000:]
    first, *errors = proc.stdout.strip().splitlines()
    seconds, cut, alive = first.split()
    assert alive == "0" and int(cut) >= 1 and float(seconds) < 5, proc.stdout
    assert len(errors) == 2 and all("the run is stopping" in e for e in errors), errors
    print(f"stop_all: 2 calls (one in a 30 s back-off, one dribbled) ended {float(seconds):.3f} s after it")


# -- signals: a real pytest process ------------------------------------------------------------------------------
def bench(fake: FakeChatServer, run_dir: Path, *args: str) -> list[str]:
    return [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist", str(REPO / "tasks"),
            "--results-dir", str(run_dir), "-k", "thunar-rename_file", "--agent", "holo2",
            "--planner-base-url", fake.url, "--planner-model", "planner",
            "--grounder-base-url", fake.url, "--grounder-model", "grounder", *args]


def start(cmd: list[str]) -> subprocess.Popen:
    # SIGINT back to its default in the child (a background job starts with it ignored; Python then installs
    # no KeyboardInterrupt handler), as a terminal's Ctrl-C would find it
    return subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            start_new_session=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def test_dribbling_endpoint_at_start_up_is_one_clear_error_within_the_budget(tmp_path):
    """A real run whose endpoints dribble the start-up check: the run stops with one usage error naming the
    endpoint, within the check's budget (here the endpoints' 3 s timeout), before any device boots."""
    with FakeChatServer(models=("planner", "grounder")) as fake:
        fake.probe_reply = dribble(0.2, ENDLESS)
        t0 = time.monotonic()
        proc = subprocess.run(bench(fake, tmp_path, "--agent-option", "planner_timeout=3",
                                    "--agent-option", "grounder_timeout=3"),
                              cwd=REPO, capture_output=True, text=True, timeout=120)
        took = time.monotonic() - t0
        wait_for(lambda: fake.dribbling == 0, 3, "both connections closed")
        hangups = fake.hangups
    out = proc.stdout + proc.stderr
    assert proc.returncode == 4, out[-3000:]
    assert "planner:" in out and "no complete answer to a one-token request within 3 s" in out, out[-3000:]
    assert "Traceback" not in out, out[-3000:]
    assert hangups == 2
    assert took < 60, f"start-up took {took:.0f} s"  # a hang was forever; the budget is 3 s plus start-up
    print(f"dribbling start-up check in a real run: exit {proc.returncode} after {took:.1f} s (budget 3 s)")


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=lambda s: s.name)
def test_signal_during_the_start_up_check_stops_the_run_in_seconds(tmp_path, sig):
    """The start-up check hangs on a dribbling endpoint (30 s budget): SIGTERM or SIGINT stops the run at once
    (it used to wait for the check, which never ended)."""
    with FakeChatServer(models=("planner", "grounder")) as fake:
        fake.probe_reply = dribble(0.5, ENDLESS)
        proc = start(bench(fake, tmp_path))
        try:
            wait_for(lambda: fake.dribbling == 2, 60, "both start-up checks in flight")
            t0 = time.monotonic()
            os.kill(proc.pid, sig)
            out, _ = proc.communicate(timeout=60)
            took = time.monotonic() - t0
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.communicate()
    assert proc.returncode == 2, out[-3000:]  # pytest's "interrupted"
    assert took < 15, f"{sig.name} stopped the run only after {took:.1f} s"
    print(f"{sig.name} during the start-up check: exit {proc.returncode} {took:.2f} s after the signal")


# -- a real run mid-task (real devices) ---------------------------------------------------------------------------
def planner_dribbles(fake: FakeChatServer, interval: float) -> None:
    fake.respond_with(lambda req: dribble(interval, ENDLESS), model="planner")


@pytest.mark.containers
def test_too_slow_endpoint_mid_run_is_an_error_by_the_step_deadline(device_images, tmp_path):
    """The planner dribbles its answer: the step's call ends at the step deadline and the task is an
    infrastructure `error` (the endpoint's fault, not the agent's), counted apart from the rates."""
    from jarvis_pytest.report.rollup import load_results

    with FakeChatServer(models=("planner", "grounder")) as fake:
        planner_dribbles(fake, 0.2)
        proc = subprocess.run(bench(fake, tmp_path, "--step-timeout", "5"), cwd=REPO, capture_output=True,
                              text=True, timeout=300)
        wait_for(lambda: fake.dribbling == 0, 3, "the dribbled call's connection closed")
        hangups = fake.hangups
    out = proc.stdout + proc.stderr
    results = load_results(tmp_path)[0]
    assert proc.returncode == 1 and f"{len(results)} error" in out and results, out[-3000:]
    for result in results:
        assert result.status == "error" and "step time limit (5 s)" in result.error, result.error
        assert "no complete answer" in result.error and result.steps == 1, result.error
    assert hangups == len(results)


@pytest.mark.containers
def test_after_a_too_slow_call_the_next_task_still_reaches_the_model(device_images, tmp_path):
    """One slot for the planner: the first task's call is dribbled past its step deadline (that task is an
    `error`); every later task of the same process still gets the slot and the model's answer (a FAIL: an agent
    failure, `failed`), where a slot kept by the abandoned call left each of them an `error` too."""
    from jarvis_pytest.agents.planner import render_step
    from jarvis_pytest.report.rollup import load_results

    give_up = render_step("ubuntu", "Give up", {"action": "terminate", "status": "failure"})
    with FakeChatServer(models=("planner", "grounder")) as fake:
        fake.script(dribble(0.2, ENDLESS), model="planner")
        fake.respond_with(lambda req: give_up, model="planner")
        proc = subprocess.run(bench(fake, tmp_path, "--step-timeout", "5", "--agent-option",
                                    "planner_max_concurrency=1"),
                              cwd=REPO, capture_output=True, text=True, timeout=600)
    out = proc.stdout + proc.stderr
    results = load_results(tmp_path)[0]
    statuses = sorted(r.status for r in results)
    assert len(results) >= 2 and statuses.count("error") == 1, (statuses, out[-3000:])
    assert set(statuses) == {"error", "failed"}, (statuses, out[-3000:])


@pytest.mark.containers
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=lambda s: s.name)
def test_signal_mid_run_stops_the_run_in_seconds(device_images, tmp_path, sig):
    """A task's model call is being dribbled (a 300 s step deadline): SIGTERM or SIGINT stops the run within
    seconds, the devices removed and the run marked interrupted; the call's connection is cut at the signal,
    while the run is still removing its devices, not only when the process ends."""
    import json

    with FakeChatServer(models=("planner", "grounder")) as fake:
        planner_dribbles(fake, 0.5)
        proc = start(bench(fake, tmp_path, "--step-timeout", "300"))
        box: dict[str, str] = {}
        reader = threading.Thread(target=lambda: box.update(out=proc.communicate()[0]), daemon=True)
        reader.start()
        cut_while_running = False
        try:
            wait_for(lambda: fake.dribbling == 1, 300, "the first step's model call in flight")
            t0 = time.monotonic()
            os.kill(proc.pid, sig)
            while proc.poll() is None and time.monotonic() - t0 < 120:
                cut_while_running = cut_while_running or fake.hangups == 1
                time.sleep(0.02)
            took = time.monotonic() - t0
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
            reader.join(10)
        hangups = fake.hangups
    out = box.get("out", "")
    assert proc.returncode == 2, out[-3000:]
    assert json.loads((tmp_path / "run.json").read_text())["state"] == "interrupted"
    assert hangups == 1 and cut_while_running, "the model call was not cut before the process ended"
    assert took < 60, f"{sig.name} stopped the run only after {took:.1f} s"
    print(f"{sig.name} mid-run: exit {proc.returncode} {took:.2f} s after the signal (devices removed)")
