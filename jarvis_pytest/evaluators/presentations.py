"""Checks of presentation files (Impress .odp / .pptx), read on the host."""

from __future__ import annotations

from jarvis_pytest.evaluators.registry import Verdict, evaluator  # noqa: F401
from jarvis_pytest.evaluators.state import FinalState  # noqa: F401
