"""A small client for OpenAI-compatible chat endpoints (vLLM, DashScope compatible mode, Kimi, OpenAI, ...).

Usage::

    client = ChatClient("http://127.0.0.1:8000/v1", "Qwen/Qwen3-VL-30B-A3B-Instruct", api_key=None)
    result = client.chat([user_message("Describe the screen.", image_part(png_bytes))], temperature=0)
    result.text    # the assistant's answer ("" when it sent none)
    result.usage   # {"prompt_tokens": ..., "completion_tokens": ..., "total_tokens": ...}

What it does for you: images travel as base64 ``data:`` URLs; every attempt has a wall-clock deadline (``timeout``
seconds for the whole attempt, however slowly the server sends, and never past the deadline of the step that
made the call, see :mod:`jarvis_pytest.llm.deadline`); 429, 5xx, timeouts and connection errors are retried with
exponential backoff (``Retry-After`` is honoured) while the deadline allows; at most ``max_concurrency`` requests
per endpoint are in flight across all threads of the process, and a request that runs out of time gives its slot
back as it ends, at its deadline. When the endpoint still fails after the retries, or answers something that is
not a chat completion, it raises
:class:`jarvis_pytest.errors.InfrastructureError` (the harness counts that as an infrastructure error, not as an
agent failure). The API key is sent as ``Authorization: Bearer`` and appears in no message, repr or log.
"""

from __future__ import annotations

import base64
import contextlib
import random
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Iterator

import httpx

from jarvis_pytest.errors import ConfigError, InfrastructureError
from jarvis_pytest.http_client import http_client
from jarvis_pytest.llm.deadline import deadline_at, remaining
from jarvis_pytest.llm.transport import install as transport_install, pause, stopping

#: HTTP statuses worth another try: rate limits, overload, gateway trouble.
RETRY_STATUSES = frozenset({408, 425, 429, 500, 502, 503, 504, 520, 521, 522, 524, 529})
USAGE_KEYS = ("prompt_tokens", "completion_tokens", "total_tokens")
PROBE_SECONDS = 30.0  # the start-up check's budget (or the endpoint's timeout, when shorter)
MAX_ANSWER_BYTES = 32 * 1024 * 1024  # an answer longer than this is the endpoint's fault (an endless body)

_SEMAPHORES: dict[tuple[str, int], threading.BoundedSemaphore] = {}
_SEMAPHORES_LOCK = threading.Lock()


def endpoint_semaphore(base_url: str, limit: int) -> threading.BoundedSemaphore:
    """The process-wide semaphore of one endpoint and limit: all clients of `base_url` created with the same
    `max_concurrency` share it, whichever thread uses them."""
    key = (base_url.rstrip("/"), max(1, int(limit)))
    with _SEMAPHORES_LOCK:
        sem = _SEMAPHORES.get(key)
        if sem is None:
            sem = _SEMAPHORES[key] = threading.BoundedSemaphore(key[1])
        return sem


def image_part(png: bytes, mime: str = "image/png") -> dict[str, Any]:
    """An OpenAI ``image_url`` content part carrying the image as a base64 data URL."""
    data = base64.b64encode(png).decode("ascii")
    return {"type": "image_url", "image_url": {"url": f"data:{mime};base64,{data}"}}


def text_part(text: str) -> dict[str, Any]:
    """An OpenAI ``text`` content part."""
    return {"type": "text", "text": text}


def user_message(*parts: str | dict[str, Any]) -> dict[str, Any]:
    """A user message from strings (text parts) and ready-made parts such as :func:`image_part`."""
    return {"role": "user", "content": [text_part(p) if isinstance(p, str) else p for p in parts]}


def system_message(text: str) -> dict[str, Any]:
    return {"role": "system", "content": text}


@dataclass
class ChatResult:
    """One chat completion: the answer text, token usage and the endpoint's JSON as received."""

    text: str
    usage: dict[str, int] = field(default_factory=dict)
    raw: dict[str, Any] = field(default_factory=dict)
    attempts: int = 1
    seconds: float = 0.0

    @property
    def reasoning(self) -> str:
        """The separate reasoning text some servers return (vLLM ``reasoning_content``), or ""."""
        try:
            msg = self.raw["choices"][0]["message"]
        except (KeyError, IndexError, TypeError):
            return ""
        return msg.get("reasoning_content") or msg.get("reasoning") or ""


class _Retry(Exception):
    def __init__(self, reason: str, wait: float | None = None):
        super().__init__(reason)
        self.reason = reason
        self.wait = wait


class ChatClient:
    """A chat-completions client for one endpoint and model. Thread-safe; reuse one per endpoint.

    ``base_url`` is the API root that ends in ``/v1`` (or DashScope's ``.../compatible-mode/v1``); requests go to
    ``{base_url}/chat/completions``. ``timeout`` is the wall-clock budget of one attempt, in seconds (waiting for
    a free slot, connecting, sending and receiving the whole answer). ``max_retries`` counts the extra
    attempts after the first. ``backoff`` is the first wait (doubled each retry, with jitter, capped at
    ``max_backoff``). ``params`` are default request parameters (e.g. ``temperature``) merged under each call's.
    """

    def __init__(self, base_url: str, model: str, api_key: str | None = None, timeout: float = 60.0,
                 max_retries: int = 4, max_concurrency: int = 4, *, backoff: float = 1.0, max_backoff: float = 30.0,
                 params: dict[str, Any] | None = None, transport: httpx.BaseTransport | None = None):
        if not base_url or not base_url.startswith(("http://", "https://")):
            raise ValueError(f"base_url must be an http(s) URL, got {base_url!r}")
        self.base_url = base_url.rstrip("/")
        self.model = model
        self.timeout = float(timeout)
        self.max_retries = max(0, int(max_retries))
        self.max_concurrency = max(1, int(max_concurrency))
        self.backoff = float(backoff)
        self.max_backoff = float(max_backoff)
        self.params = dict(params or {})
        self._api_key = api_key or None
        headers = {"Content-Type": "application/json"}
        if self._api_key:
            headers["Authorization"] = f"Bearer {self._api_key}"
        self._http = transport_install(http_client(headers=headers, timeout=httpx.Timeout(self.timeout),
                                                   transport=transport))
        self._semaphore = endpoint_semaphore(self.base_url, self.max_concurrency)

    def __repr__(self) -> str:
        key = "***" if self._api_key else None
        return f"ChatClient(base_url={self.base_url!r}, model={self.model!r}, api_key={key!r})"

    def config(self) -> dict[str, Any]:
        """What identifies this client in results: endpoint and model, never the key."""
        return {"base_url": self.base_url, "model": self.model}

    def close(self) -> None:
        self._http.close()

    def __enter__(self) -> ChatClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def chat(self, messages: list[dict[str, Any]], **params: Any) -> ChatResult:
        """Send one chat completion request; returns the first choice. Raises InfrastructureError after retries,
        when the deadline of the calling thread passes, or when the process is stopping."""
        body = {"model": self.model, "messages": messages, **self.params, **params}
        url = f"{self.base_url}/chat/completions"
        started = time.monotonic()
        last = ""
        for attempt in range(1, self.max_retries + 2):
            left = remaining()
            if stopping():
                raise InfrastructureError(f"{url} (model {self.model}): the run is stopping; the call was cancelled")
            if left is not None and left <= 0:
                last = last or "no attempt made"
                raise InfrastructureError(f"{url} (model {self.model}): the step's deadline passed after "
                                          f"{attempt - 1} attempt(s); last error: {last}")
            budget = self.timeout if left is None else min(self.timeout, left)
            try:
                with deadline_at(time.monotonic() + budget), self._slot(budget):
                    raw = self._once(url, body, budget)
                return self._result(raw, attempt, time.monotonic() - started)
            except _Retry as exc:
                last = exc.reason
                if attempt > self.max_retries:
                    break
                wait = self._wait(attempt, exc.wait)
                left = remaining()
                if left is not None and wait >= left:
                    break
                if not pause(wait):
                    raise InfrastructureError(f"{url} (model {self.model}): the run is stopping; the call was "
                                              f"cancelled after {attempt} attempt(s)") from None
        raise InfrastructureError(f"{url} (model {self.model}) failed after {attempt} attempt(s); "
                                  f"last error: {last}")

    @contextlib.contextmanager
    def _slot(self, budget: float) -> Iterator[None]:
        """One of the endpoint's `max_concurrency` slots, waited for at most `budget` seconds."""
        if not self._semaphore.acquire(timeout=max(0.0, budget)):
            raise _Retry(f"no free slot within {budget:g} s ({self.max_concurrency} calls to this endpoint in "
                         "flight)")
        try:
            yield
        finally:
            self._semaphore.release()

    def probe(self, timeout: float | None = None, extra: dict[str, Any] | None = None) -> None:
        """One minimal real request (a one-token completion) proving the endpoint, the model name and the key;
        a ConfigError that says which is wrong otherwise. Run once at start-up, before any device boots. It
        ends within `timeout` seconds of wall-clock time (default: PROBE_SECONDS, or the endpoint's timeout when
        shorter), however slowly the server answers. `extra` are request fields every later call sends (a
        `seed`): a server that refuses one of them says so now, named in the error."""
        timeout = min(PROBE_SECONDS, self.timeout) if timeout is None else float(timeout)
        url = f"{self.base_url}/chat/completions"
        body = {"model": self.model, "max_tokens": 1, "temperature": 0,
                "messages": [{"role": "user", "content": "Reply with OK."}], **(extra or {})}
        try:
            with deadline_at(time.monotonic() + timeout):
                resp = self._post(url, body, timeout)
        except InfrastructureError as exc:
            raise ConfigError(f"{exc} (to a one-token request)", field="base_url",
                              fix="give the API root of an OpenAI-compatible server (ending in /v1)") from None
        except httpx.TimeoutException:
            raise ConfigError(f"{url} sent no complete answer to a one-token request within {timeout:g} s",
                              field="base_url", fix="check that the model server is up, not stuck and not "
                              f"overloaded (the start-up check allows {PROBE_SECONDS:g} s, or the endpoint's "
                              "timeout when shorter)") from None
        except httpx.HTTPError as exc:
            if stopping():
                raise ConfigError(f"{url}: the start-up check was cancelled (the run is stopping)",
                                  field="base_url") from None
            raise ConfigError(f"{url} is unreachable ({exc.__class__.__name__})", field="base_url",
                              fix="start the server or correct the base URL (--planner-base-url / "
                              "--grounder-base-url or JARVIS_*_BASE_URL)") from None
        if resp.status_code < 400:
            try:
                self._result(resp.json(), 1, 0.0)
            except (ValueError, InfrastructureError):
                raise ConfigError(f"{url} answered HTTP {resp.status_code} but not with a chat completion: "
                                  f"{_snippet(resp)}", field="base_url",
                                  fix="give the API root of an OpenAI-compatible server (ending in /v1)") from None
            return
        text = _snippet(resp).lower()
        if resp.status_code in (401, 403) or "api key" in text or "api_key" in text or "unauthor" in text:
            raise ConfigError(f"{url} refused the API key (HTTP {resp.status_code}: {_snippet(resp)})",
                              field="api_key", fix="check the key (--planner-api-key / --grounder-api-key or "
                              "JARVIS_*_API_KEY) and that it may use this model")
        refused = [k for k in extra or {} if k in text] if resp.status_code in (400, 422) else []
        if refused:
            raise ConfigError(f"{url} refused the request field {refused[0]!r} (HTTP {resp.status_code}: "
                              f"{_snippet(resp)})", field=refused[0],
                              fix=f"pass --agent-option {refused[0]}=none (the run then sends no {refused[0]})")
        if resp.status_code == 404 or "model" in text:
            raise ConfigError(f"{url} does not serve model {self.model!r} (HTTP {resp.status_code}: "
                              f"{_snippet(resp)})", field="model", fix="check the model name (--planner-model / "
                              "--grounder-model) against the server's /models list, and the base URL")
        raise ConfigError(f"{url} answered HTTP {resp.status_code} to a minimal request: {_snippet(resp)}",
                          field="base_url", fix="check the base URL, the model name and the API key")

    def _post(self, url: str, body: dict[str, Any], timeout: float) -> httpx.Response:
        """POST `body` and read the whole answer (at most MAX_ANSWER_BYTES; an InfrastructureError beyond)."""
        with self._http.stream("POST", url, json=body, timeout=timeout) as resp:
            data = bytearray()
            for chunk in resp.iter_bytes():
                data += chunk
                if len(data) > MAX_ANSWER_BYTES:
                    raise InfrastructureError(f"{url} (model {self.model}) sent an answer longer than "
                                              f"{MAX_ANSWER_BYTES // 2**20} MiB; the rest was not read")
        headers = [(k, v) for k, v in resp.headers.raw
                   if k.lower() not in (b"content-encoding", b"content-length", b"transfer-encoding")]
        return httpx.Response(resp.status_code, headers=headers, content=bytes(data), request=resp.request)

    def _once(self, url: str, body: dict[str, Any], timeout: float | None = None) -> dict[str, Any]:
        timeout = self.timeout if timeout is None else timeout
        try:
            resp = self._post(url, body, timeout)
        except httpx.TimeoutException as exc:
            raise _Retry(f"no complete answer within {timeout:.3g} s ({type(exc).__name__})") from None
        except httpx.TransportError as exc:
            raise _Retry(f"connection error: {type(exc).__name__}: {exc}") from None
        if resp.status_code in RETRY_STATUSES:
            raise _Retry(f"HTTP {resp.status_code}: {_snippet(resp)}", _retry_after(resp))
        if resp.status_code >= 400:
            text = resp.text.lower()
            hint = (" (check the API key)" if resp.status_code in (401, 403) or "api key" in text or "api_key" in text
                    else " (check the model name)" if resp.status_code == 404 or "model" in text else "")
            raise InfrastructureError(f"{url} (model {self.model}) answered HTTP {resp.status_code}{hint}: "
                                      f"{_snippet(resp)}")
        try:
            data = resp.json()
        except ValueError:
            raise _Retry(f"HTTP {resp.status_code} with a body that is not JSON: {_snippet(resp)}") from None
        if not isinstance(data, dict):
            raise _Retry(f"a JSON body that is not an object: {_snippet(resp)}")
        return data

    def _result(self, raw: dict[str, Any], attempts: int, seconds: float) -> ChatResult:
        try:
            message = raw["choices"][0]["message"]
        except (KeyError, IndexError, TypeError):
            raise InfrastructureError(f"{self.base_url} (model {self.model}) answered without choices[0].message: "
                                      f"{str(raw)[:300]}") from None
        content = message.get("content")
        if isinstance(content, list):  # some servers return content parts
            content = "".join(p.get("text", "") for p in content if isinstance(p, dict))
        usage_in = raw.get("usage") or {}
        usage = {k: int(usage_in.get(k) or 0) for k in USAGE_KEYS}
        if not usage["total_tokens"]:
            usage["total_tokens"] = usage["prompt_tokens"] + usage["completion_tokens"]
        return ChatResult(text=content or "", usage=usage, raw=raw, attempts=attempts, seconds=seconds)

    def _wait(self, attempt: int, retry_after: float | None) -> float:
        if retry_after is not None:
            return min(max(retry_after, 0.0), self.max_backoff)
        base = min(self.backoff * (2 ** (attempt - 1)), self.max_backoff)
        return base * (0.5 + random.random() / 2)


def _retry_after(resp: httpx.Response) -> float | None:
    value = resp.headers.get("retry-after")
    if value is None:
        return None
    try:
        return float(value)
    except ValueError:
        return None  # an HTTP date: fall back to our own backoff


def _snippet(resp: httpx.Response, limit: int = 300) -> str:
    text = resp.text.strip().replace("\n", " ")
    return text[:limit] + ("..." if len(text) > limit else "")
