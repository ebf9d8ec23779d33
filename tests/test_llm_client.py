"""The OpenAI-compatible client against the loopback fake server (real HTTP on 127.0.0.1): answers and usage,
images as data URLs, the key as a bearer token and nowhere else, retries with backoff on 429/5xx/timeouts,
InfrastructureError after the retries, no retry on other 4xx, and bounded concurrency across threads."""

from __future__ import annotations

import threading
import time

import pytest

from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.llm.client import ChatClient, image_part, user_message
from jarvis_pytest.llm.fake_server import FakeChatServer, Reply, fail, stall
from screens import screenshot

KEY = "sk-test-very-secret"


@pytest.fixture
def server():
    with FakeChatServer(api_key=KEY, models=("m1", "m2")) as srv:
        yield srv


def client(server, model="m1", **kw) -> ChatClient:
    kw.setdefault("backoff", 0.01)
    return ChatClient(server.url, model, api_key=KEY, **kw)


def test_a_server_that_records_nothing_answers_the_same():
    """`record=False` (the throughput bench's: a long run would hold every screenshot sent) keeps no request and
    answers as a recording server does, its usage estimate counting the images without decoding them."""
    png = screenshot(64, 48)
    messages = [user_message("what is this?", image_part(png), image_part(png))]
    usages = []
    for record in (True, False):
        with FakeChatServer(api_key=KEY, models=("m1",), record=record) as srv:
            srv.respond_with(lambda req: "seen", model="m1")
            result = ChatClient(srv.url, "m1", api_key=KEY).chat(messages)
            assert result.text == "seen" and srv.received == 1 and len(srv.requests) == (1 if record else 0)
            usages.append(result.usage)
    assert usages[0] == usages[1] and usages[0]["prompt_tokens"] == len("what is this?") // 4 + 200


def test_answer_usage_and_request_shape(server):
    png = screenshot(64, 48)
    server.script(Reply("hello", usage={"prompt_tokens": 11, "completion_tokens": 2}), model="m1")
    result = client(server).chat([user_message("what is this?", image_part(png))], temperature=0)
    assert result.text == "hello"
    assert result.usage == {"prompt_tokens": 11, "completion_tokens": 2, "total_tokens": 13}
    assert result.attempts == 1
    (req,) = server.requests
    assert req.path == "/v1/chat/completions" and req.model == "m1"
    assert req.headers["Authorization"] == f"Bearer {KEY}"
    assert req.body["temperature"] == 0
    assert req.text() == "what is this?"
    assert req.images() == [png] and req.image_sizes() == [(64, 48)]
    url = req.parts()[1]["image_url"]["url"]
    assert url.startswith("data:image/png;base64,")


def test_default_params_and_reasoning(server):
    server.script(Reply("ok", reasoning="thinking..."), model="m1")
    result = client(server, params={"max_tokens": 7}).chat([user_message("hi")], max_tokens=9, top_p=0.5)
    assert result.reasoning == "thinking..."
    assert server.requests[-1].body["max_tokens"] == 9 and server.requests[-1].body["top_p"] == 0.5


@pytest.mark.parametrize("failure", [fail(429, retry_after=0), fail(500), fail(502), fail(503), stall(2.0)],
                         ids=["429", "500", "502", "503", "timeout"])
def test_retries_then_succeeds(server, failure):
    server.script(failure, failure, "finally", model="m1")
    result = client(server, timeout=0.3, max_retries=3).chat([user_message("x")])
    assert result.text == "finally" and result.attempts == 3
    assert len(server.requests_for("m1")) == 3


def test_retry_after_is_honoured(server):
    server.script(fail(429, retry_after=0.3), "ok", model="m1")
    t0 = time.monotonic()
    client(server, backoff=5.0).chat([user_message("x")])
    assert 0.25 <= time.monotonic() - t0 < 3


def test_gives_up_with_infrastructure_error(server):
    server.script(*[fail(503)] * 5, model="m1")
    with pytest.raises(InfrastructureError, match=r"failed after 3 attempt\(s\).*HTTP 503") as info:
        client(server, max_retries=2).chat([user_message("x")])
    assert KEY not in str(info.value)
    assert len(server.requests_for("m1")) == 3


def test_unreachable_endpoint_is_an_infrastructure_error():
    with FakeChatServer() as srv:
        url = srv.url  # the port is closed after the block
    with pytest.raises(InfrastructureError, match="connection error"):
        ChatClient(url, "m", max_retries=1, backoff=0.01, timeout=1).chat([user_message("x")])


@pytest.mark.parametrize("status", [400, 401, 404])
def test_other_client_errors_are_not_retried(server, status):
    server.script(fail(status, message="bad thing"), "never", model="m1")
    with pytest.raises(InfrastructureError, match=f"HTTP {status}.*bad thing"):
        client(server, max_retries=3).chat([user_message("x")])
    assert len(server.requests_for("m1")) == 1


def test_wrong_key_is_rejected_without_leaking_it(server):
    bad = ChatClient(server.url, "m1", api_key="sk-wrong-key", max_retries=3, backoff=0.01)
    with pytest.raises(InfrastructureError, match="401.*check the API key") as info:
        bad.chat([user_message("x")])
    assert "sk-wrong-key" not in str(info.value) and "sk-wrong-key" not in repr(bad)
    assert "***" in repr(bad) and "sk-" not in str(bad.config())


def test_malformed_answers(server):
    server.script(Reply(body="<html>gateway</html>"), Reply(body={"id": "x"}), model="m1")
    c = client(server, max_retries=0)
    with pytest.raises(InfrastructureError, match="not JSON"):
        c.chat([user_message("x")])
    with pytest.raises(InfrastructureError, match="without choices"):
        c.chat([user_message("x")])


def test_unscripted_model_is_a_clear_400(server):
    with pytest.raises(InfrastructureError, match="nothing scripted for model 'm2'"):
        client(server, model="m2").chat([user_message("x")])


def test_bounded_concurrency_across_threads():
    """Six threads, four clients of one endpoint, limit 2: never more than two requests in flight."""
    active = peak = 0
    lock = threading.Lock()

    def slow(req):
        nonlocal active, peak
        with lock:
            active += 1
            peak = max(peak, active)
        time.sleep(0.15)
        with lock:
            active -= 1
        return "done"

    with FakeChatServer(slow) as srv:
        clients = [ChatClient(srv.url, "m", max_concurrency=2) for _ in range(4)]
        results: list[str] = []
        threads = [threading.Thread(target=lambda c=c: results.append(c.chat([user_message("x")]).text))
                   for c in clients + clients[:2]]
        t0 = time.monotonic()
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        elapsed = time.monotonic() - t0
    assert results == ["done"] * 6
    assert peak == 2
    assert elapsed >= 0.4  # three waves of two


def test_models_endpoint_and_auth(server):
    import httpx

    assert httpx.get(f"{server.url}/models").status_code == 401
    data = httpx.get(f"{server.url}/models", headers={"Authorization": f"Bearer {KEY}"}).json()
    assert [m["id"] for m in data["data"]] == ["m1", "m2"]


def test_queue_order_model_then_any_then_responder():
    with FakeChatServer(lambda req: "default") as srv:
        srv.script("for-a", model="a").script("for-anyone").respond_with(lambda req: "b-responder", model="b")
        answers = [ChatClient(srv.url, m).chat([user_message("x")]).text for m in ("b", "a", "a", "b", "c")]
        assert answers == ["for-anyone", "for-a", "default", "b-responder", "default"]
        assert srv.pending("a") == 0
