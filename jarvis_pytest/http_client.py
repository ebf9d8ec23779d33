"""HTTP clients that share one TLS context.

`httpx.Client()` builds a TLS context and loads the CA bundle into it each time: about 23 ms of CPU per client
(measured with httpx 0.28). A task makes several clients (its devices, its drive, the agent's model endpoints,
readiness polls), so that was a tenth to a quarter of a second of CPU per task for nothing. One context, built on first
use with httpx's own defaults (certifi, or SSL_CERT_FILE / SSL_CERT_DIR), serves every client; an SSLContext
may be shared between threads.
"""

from __future__ import annotations

import functools
import ssl
from typing import Any

import httpx


@functools.cache
def tls_context() -> ssl.SSLContext:
    """The process's TLS context for verified HTTPS, as httpx makes it by default."""
    return httpx.create_ssl_context()


def http_client(**kwargs: Any) -> httpx.Client:
    """`httpx.Client(**kwargs)` with the shared TLS context (unless `verify` is given)."""
    kwargs.setdefault("verify", tls_context())
    return httpx.Client(**kwargs)
