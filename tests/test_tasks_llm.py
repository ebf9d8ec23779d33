"""The optional LLM steps (instruction rewrite, LLM-as-a-judge filter) against the loopback fake server."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from jarvis_pytest.cli import main
from jarvis_pytest.errors import ConfigError
from jarvis_pytest.llm.fake_server import FakeChatServer
from jarvis_pytest.tasks import llm_steps
from jarvis_pytest.tasks.compose import compose
from jarvis_pytest.tasks.dataset import load_dataset
from jarvis_pytest.tasks.library import load_library

LIBRARY_DIR = Path(__file__).parent / "data" / "library"
MODEL = "judge-model"


@pytest.fixture(scope="module")
def library():
    return load_library(LIBRARY_DIR)


@pytest.fixture(scope="module")
def md_task(library):
    return next(t for t in compose(library, seed=1, count=6, max_subtasks=4, balanced=True) if t.category == "md")


@pytest.fixture(autouse=True)
def no_endpoint_env(monkeypatch):
    for name in ("BASE_URL", "MODEL", "API_KEY"):
        monkeypatch.delenv(f"JARVIS_COMPOSER_{name}", raising=False)


def _task_of(prompt: str) -> str:
    return prompt.split("Task:\n", 1)[1]


def faithful_rewrite(req) -> str:
    """A 'rewrite' that keeps every value: the numbered steps joined into one paragraph."""
    steps = _task_of(req.text()).splitlines()[1:]
    return "<think>joining the steps</think>" + " Then ".join(re.sub(r"^\d+\. ", "", s) for s in steps)


def judge_or_rewrite(rejects: str = "Notepad"):
    def answer(req) -> str:
        text = req.text()
        if text.startswith("You rewrite"):
            return faithful_rewrite(req)
        if rejects in text:
            return 'The second step is pointless. {"authenticity": 4, "rationality": 2, "evaluability": 5}'
        return '```json\n{"authenticity": 5, "rationality": 5, "evaluability": 5}\n```'
    return answer


def chat_for(server: FakeChatServer, cache: Path) -> llm_steps.CachedChat:
    return llm_steps.cached_chat(llm_steps.endpoint(server.url, MODEL, env={}), cache)


def test_rewrite_keeps_every_value_verbatim(md_task, tmp_path):
    with FakeChatServer(faithful_rewrite) as server:
        out = llm_steps.rewrite_instruction(md_task, chat_for(server, tmp_path))
    assert out.instruction != md_task.instruction and "<think>" not in out.instruction
    assert out.template_instruction == md_task.instruction
    values = llm_steps.kept_values(md_task)
    assert values and all(v in out.instruction for v in values)
    assert server.requests_for(MODEL)[0].body["temperature"] == 0


def test_rewrite_that_alters_a_value_falls_back_to_the_deterministic_text(md_task, tmp_path):
    path = md_task.formatted_subtasks[0].input[sorted(md_task.formatted_subtasks[0].input)[0]].value
    lossy = md_task.instruction.replace(str(path), "the file")
    with FakeChatServer(lambda req: lossy) as server:
        out = llm_steps.rewrite_instruction(md_task, chat_for(server, tmp_path))
    assert out == md_task


def test_rewrite_with_a_placeholder_is_refused(md_task, tmp_path):
    with FakeChatServer(lambda req: md_task.instruction + " {{image}}") as server:
        assert llm_steps.rewrite_instruction(md_task, chat_for(server, tmp_path)) == md_task


def test_judge_prompt_follows_the_paper(md_task, tmp_path):
    with FakeChatServer(judge_or_rewrite()) as server:
        llm_steps.judge_task(md_task, chat_for(server, tmp_path))
    prompt = server.requests_for(MODEL)[0].text()
    for needle in ("Task Authenticity", "Task Rationality", "Evaluability", "Recycle Bin", "network drive",
                   '{"authenticity": 2, "rationality": 4, "evaluability": 5}', "{{slot}}"):
        assert needle in prompt, needle
    edge = md_task.edges[0]
    assert f"from {{{{{edge.from_[1]}}}}} of subtask {edge.from_[0] + 1} as {{{{{edge.to[1]}}}}}" in prompt
    assert md_task.formatted_subtasks[0].instruction in prompt


@pytest.mark.parametrize("answer,expected", [
    ('{"authenticity": 5, "rationality": 5, "evaluability": 5}', {"realism": 5, "coherence": 5, "evaluability": 5}),
    ('<think>{"authenticity": 1, "rationality": 1, "evaluability": 1}</think> {"authenticity": 5, '
     '"rationality": 4, "evaluability": 3}', {"realism": 5, "coherence": 4, "evaluability": 3}),
    ('{"authenticity": 9, "rationality": 5, "evaluability": 5}', None),
    ('{"authenticity": "high", "rationality": 5, "evaluability": 5}', None),
    ("I cannot rate this.", None),
])
def test_parse_scores(answer, expected):
    assert llm_steps.parse_scores(answer) == expected


def test_only_five_five_five_passes():
    assert llm_steps.passes({"realism": 5, "coherence": 5, "evaluability": 5})
    assert not llm_steps.passes({"realism": 5, "coherence": 4, "evaluability": 5})
    assert not llm_steps.passes(None)


def test_responses_are_cached_on_disk(md_task, tmp_path):
    with FakeChatServer(judge_or_rewrite()) as server:
        chat = chat_for(server, tmp_path / "cache")
        first = llm_steps.judge_task(md_task, chat)
        second = llm_steps.judge_task(md_task, chat)
        assert first == second == {"realism": 5, "coherence": 5, "evaluability": 5}
        assert len(server.requests_for(MODEL)) == 1
    assert len(list((tmp_path / "cache").glob("*.json"))) == 1
    with FakeChatServer() as silent:  # nothing scripted: any request would fail
        assert llm_steps.judge_task(md_task, chat_for(silent, tmp_path / "cache")) == first
        assert silent.requests_for(MODEL) == []


def test_pipeline_rewrites_then_filters(library, tmp_path):
    with FakeChatServer(judge_or_rewrite("File Explorer")) as server:
        finalize = llm_steps.pipeline(chat_for(server, tmp_path), rewrite=True, judge=True)
        tasks = compose(library, seed=4, count=9, max_subtasks=4, balanced=True, finalize=finalize)
        judged = [r for r in server.requests_for(MODEL) if not r.text().startswith("You rewrite")]
    assert len(tasks) == 9 and len(judged) > 9  # the judge rejected some draws
    assert any("File Explorer" in r.text() for r in judged)
    for task in tasks:
        assert task.judge == {"realism": 5, "coherence": 5, "evaluability": 5}
        assert all(s.app != "File Explorer" for s in task.formatted_subtasks)
        assert task.template_instruction and all(v in task.instruction for v in llm_steps.kept_values(task))


def test_cli_compose_with_llm_steps_is_reproducible_from_the_cache(tmp_path, monkeypatch, capsys):
    cache = tmp_path / "cache"
    with FakeChatServer(judge_or_rewrite(), api_key="sk-test") as server:
        monkeypatch.setenv("JARVIS_COMPOSER_BASE_URL", server.url)
        monkeypatch.setenv("JARVIS_COMPOSER_API_KEY", "sk-test")
        args = ["compose", "--library", str(LIBRARY_DIR), "--seed", "3", "--count", "6", "--balanced",
                "--max-subtasks", "4", "--rewrite", "--judge", "--composer-model", MODEL, "--llm-cache", str(cache)]
        assert main(args + ["--out", str(tmp_path / "a.json")]) == 0
        asked = len(server.requests_for(MODEL))
        assert main(args + ["--out", str(tmp_path / "b.json")]) == 0
        assert len(server.requests_for(MODEL)) == asked  # all answers came from the cache
    a, b = (tmp_path / "a.json").read_bytes(), (tmp_path / "b.json").read_bytes()
    assert a == b and b"sk-test" not in a
    data = json.loads(a)
    assert data["meta"]["llm"] == {"model": MODEL, "rewrite": True, "judge": True}
    assert all(t["judge"] == {"realism": 5, "coherence": 5, "evaluability": 5} for t in data["tasks"])
    assert load_dataset(tmp_path / "a.json").tasks  # rewritten datasets still validate


def test_llm_steps_without_an_endpoint_are_a_clear_error(tmp_path, capsys):
    assert main(["compose", "--library", str(LIBRARY_DIR), "--seed", "0", "--count", "3", "--judge",
                 "--out", str(tmp_path / "x.json")]) == 2
    err = capsys.readouterr().err
    assert "no composer base url configured" in err and "JARVIS_COMPOSER_BASE_URL" in err
    with pytest.raises(ConfigError, match="composer model"):
        llm_steps.endpoint("http://127.0.0.1:9/v1", None, env={})
