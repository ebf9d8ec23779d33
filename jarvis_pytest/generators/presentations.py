"""Generators of presentation files (Impress .odp / .pptx)."""

from __future__ import annotations

from jarvis_pytest.generators.registry import generator  # noqa: F401
