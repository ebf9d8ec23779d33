"""Generators of spreadsheets files."""

from __future__ import annotations

from jarvis_pytest.generators.registry import generator  # noqa: F401
