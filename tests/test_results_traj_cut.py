"""traj.jsonl keeps the first CUT_TEXT_CHARS characters of a model's text and records how long it was."""

from __future__ import annotations

import json

from jarvis_pytest.results.model import CUT_TEXT_CHARS, StepRecord, TaskResult
from jarvis_pytest.results.writer import TaskRecorder


def test_a_huge_model_answer_is_cut_and_says_so(tmp_path):
    recorder = TaskRecorder(tmp_path, TaskResult(task_id="t", category="atomic", platforms=["ubuntu"],
                                                 instruction="i", status="running"))
    huge = "é" * (10 * CUT_TEXT_CHARS + 7)
    recorder.step(StepRecord(index=0, platform=None, action=None, raw_output=huge, reasoning=huge[:100]))
    recorder.step(StepRecord(index=1, platform=None, action=None, raw_output="short", reasoning="r"))
    recorder.finish()
    path = recorder.dir / "traj.jsonl"
    first, second = (json.loads(line) for line in path.read_text(encoding="utf-8").splitlines())
    assert first["raw_output"] == huge[:CUT_TEXT_CHARS] and first["cut"] == {"raw_output": len(huge)}
    assert first["reasoning"] == huge[:100]  # short enough: kept whole
    assert second["raw_output"] == "short" and second["cut"] == {}
    assert path.stat().st_size < 3 * CUT_TEXT_CHARS  # 2 bytes a character, and the rest of the lines
    # read back (the dashboard, --agent replay): as written, the length before the cut kept
    again = StepRecord.model_validate_json(path.read_text(encoding="utf-8").splitlines()[0])
    assert again.cut == {"raw_output": len(huge)} and len(again.raw_output) == CUT_TEXT_CHARS


def test_reasoning_is_cut_the_same_way():
    record = StepRecord(index=0, platform=None, action=None, reasoning="r" * (CUT_TEXT_CHARS + 1))
    assert len(record.reasoning) == CUT_TEXT_CHARS and record.cut == {"reasoning": CUT_TEXT_CHARS + 1}
