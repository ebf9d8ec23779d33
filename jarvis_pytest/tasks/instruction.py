"""The deterministic merged instruction of a composed task, rendered from its subtasks' instructions."""

from __future__ import annotations

from typing import Sequence

from jarvis_pytest.devices.platforms import spec
from jarvis_pytest.tasks.model import Subtask


def merged_instruction(subtasks: Sequence[Subtask], dependent: bool) -> str:
    """One numbered line per subtask, each naming its device (transfer steps name both devices themselves).

    A single subtask keeps its own instruction. `dependent` says whether the steps must run in order.
    """
    if len(subtasks) == 1:
        return subtasks[0].instruction
    n = len(subtasks)
    head = (f"Complete the following {n} steps in order; later steps use the results of earlier ones:" if dependent
            else f"Complete the following {n} tasks; they are independent of each other:")
    lines = [head]
    for i, sub in enumerate(subtasks, 1):
        prefix = "" if sub.source_platform else f"On the {spec(sub.platform).device_name}: "
        lines.append(f"{i}. {prefix}{sub.instruction}")
    return "\n".join(lines)
