"""Optional LLM steps of the paper's pipeline (§4.2): rewriting the merged instruction, and the LLM-as-a-judge
filter (appendix "Data Filtering"), through any OpenAI-compatible endpoint.

Rewrite: the model turns the numbered, deterministic instruction into one concise, coherent description that
keeps every procedural detail. Every slot value that appears in the deterministic text (paths, names, numbers)
must appear verbatim in the rewrite; otherwise the deterministic text is kept. The judge rates realism
(authenticity), coherence (rationality) and evaluability from 1 to 5; only tasks rated 5/5/5 are kept.
Responses are cached on disk, keyed by the model, the messages and the parameters, so a rerun with the same
inputs asks nothing and gives the same dataset.
"""

from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path
from typing import Any, Callable, Mapping, Protocol

from jarvis_pytest.llm.config import EndpointConfig, resolve_endpoint
from jarvis_pytest.devices.platforms import spec
from jarvis_pytest.tasks.model import Task

ROLE = "composer"  # options/env/pyproject: --composer-*, JARVIS_COMPOSER_*, [tool.jarvis.composer]
DEFAULT_CACHE = Path(".cache") / "jarvis-compose-llm"
SCORE_KEYS = {"authenticity": "realism", "rationality": "coherence", "evaluability": "evaluability"}

REWRITE_PROMPT = """You rewrite the instruction of a cross-device GUI task for a user.
The task below is a numbered list of steps, each on a device (Android phone, Windows PC, Ubuntu desktop).
Rewrite it as one concise, coherent and unambiguous instruction, as a user would ask for it.
Keep every procedural detail and the order of the steps. Copy every file path, file name, number and other
value exactly as written, character for character; do not shorten, translate or quote them differently.
Say on which device each step happens. Answer with the rewritten instruction only.

Task:
{instruction}"""

JUDGE_PROMPT = """Please score the following cross-device GUI agent task. It is made of subtasks; each describes its
input, the command to carry out, and its output. Inputs and outputs are written as {{{{slot}}}} placeholders
with their values. Subtasks may depend on each other, written as "from {{{{another_output}}}} as
{{{{current_input}}}}".

Rate the task on three dimensions, from 1 (worst) to 5 (best):
1. Task Authenticity: does it reflect a real user need and a plausible scenario?
2. Task Rationality: is the design logical, free of meaningless or superfluous operations? For example,
   compressing a result and copying it to another device is rational; sending a file from Android to Windows
   only to put it in the Recycle Bin is not, because the second step serves no purpose. Using random text as
   the text to search for in a spreadsheet is irrational (a match is nearly impossible), but using it as the
   replacement text is rational.
3. Evaluability: does combining the subtasks destroy the result of an earlier subtask? For example, if
   subtask A produces a file and subtask B moves it elsewhere, B destroys A's observable output, and whether
   A succeeded can no longer be checked once all subtasks are done.

Note: the GUI agent can use a network drive to move files between devices; cross-device transfers are part of
the task.

Answer with JSON only, for example {{"authenticity": 2, "rationality": 4, "evaluability": 5}}.

Task to evaluate:
{task}"""


class Chat(Protocol):
    """What the steps need from a chat client (jarvis_pytest.llm.client.ChatClient)."""

    def chat(self, messages: list[dict[str, Any]], **params: Any) -> Any: ...


def endpoint(base_url: str | None = None, model: str | None = None, api_key: str | None = None,
             env: Mapping[str, str] | None = None) -> EndpointConfig:
    """The composer's endpoint: options first, then JARVIS_COMPOSER_BASE_URL / _MODEL / _API_KEY, then
    `[tool.jarvis.composer]` in pyproject.toml (the shared resolution of jarvis_pytest.llm.config)."""
    given = {"base_url": base_url, "model": model, "api_key": api_key}
    return resolve_endpoint(ROLE, {ROLE: {k: v for k, v in given.items() if v}}, env=env)


def cached_chat(config: EndpointConfig, cache_dir: Path | str = DEFAULT_CACHE) -> "CachedChat":
    """A cached chat over the shared OpenAI-compatible client for `config`."""
    return CachedChat(config.client(), config.model, cache_dir)


class CachedChat:
    """Chat completions with an on-disk cache: one JSON file per (model, messages, parameters)."""

    def __init__(self, client: Chat, model: str, cache_dir: Path | str):
        self.client, self.model, self.cache_dir = client, model, Path(cache_dir)

    def _path(self, messages: list[dict[str, Any]], params: dict[str, Any]) -> Path:
        key = json.dumps({"model": self.model, "messages": messages, "params": params}, sort_keys=True)
        return self.cache_dir / f"{hashlib.sha256(key.encode()).hexdigest()}.json"

    def text(self, messages: list[dict[str, Any]], **params: Any) -> str:
        path = self._path(messages, params)
        if path.is_file():
            return json.loads(path.read_text(encoding="utf-8"))["text"]
        text = self.client.chat(messages, **params).text
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps({"model": self.model, "messages": messages, "params": params, "text": text},
                                  indent=1, sort_keys=True), encoding="utf-8")
        tmp.replace(path)
        return text

    def close(self) -> None:
        close = getattr(self.client, "close", None)
        if close is not None:
            close()


def _strip_thinking(text: str) -> str:
    return re.sub(r"<think>.*?</think>", "", text, flags=re.DOTALL).strip()


def kept_values(task: Task) -> list[str]:
    """The slot values written in the deterministic instruction; a rewrite must keep each one verbatim."""
    source = task.template_instruction or task.instruction
    values = {str(slot.value) for sub in task.formatted_subtasks
              for slot in list(sub.input.values()) + list(sub.output.values())}
    return sorted(v for v in values if v and v in source)


def rewrite_instruction(task: Task, chat: CachedChat) -> Task:
    """The task with an LLM-rewritten instruction, or unchanged when the rewrite drops or alters a value."""
    original = task.template_instruction or task.instruction
    prompt = REWRITE_PROMPT.format(instruction=original)
    text = _strip_thinking(chat.text([{"role": "user", "content": prompt}], temperature=0))
    if not text or "{{" in text or "}}" in text or any(value not in text for value in kept_values(task)):
        return task
    return task.model_copy(update={"instruction": text, "template_instruction": original})


def describe_for_judge(task: Task) -> str:
    """The task as the judge sees it: each subtask's inputs, command and outputs, with dependencies."""
    feeds = {tuple(e.to): tuple(e.from_) for e in task.edges}
    lines = [f"Instruction: {task.instruction}", ""]
    for i, sub in enumerate(task.formatted_subtasks, 1):
        lines.append(f"Subtask {i} on the {spec(sub.platform).device_name} ({sub.app}):")
        for name, slot in sorted(sub.input.items()):
            src = feeds.get((i - 1, name))
            origin = f" (from {{{{{src[1]}}}}} of subtask {src[0] + 1} as {{{{{name}}}}})" if src else ""
            lines.append(f"  input {{{{{name}}}}} ({slot.type}) = {slot.value}{origin}")
        lines.append(f"  command: {sub.instruction}")
        for name, slot in sorted(sub.output.items()):
            lines.append(f"  output {{{{{name}}}}} ({slot.type}) = {slot.value}")
    return "\n".join(lines)


def parse_scores(text: str) -> dict[str, int] | None:
    """The judge's three scores (realism, coherence, evaluability) from its answer, or None if unreadable."""
    text = _strip_thinking(text)
    for match in reversed(list(re.finditer(r"\{[^{}]*\}", text))):
        try:
            data = json.loads(match.group(0))
        except json.JSONDecodeError:
            continue
        if isinstance(data, dict) and all(k in data for k in SCORE_KEYS):
            try:
                scores = {SCORE_KEYS[k]: int(data[k]) for k in SCORE_KEYS}
            except (TypeError, ValueError):
                return None
            if all(1 <= v <= 5 for v in scores.values()):
                return scores
    return None


def judge_task(task: Task, chat: CachedChat) -> dict[str, int] | None:
    """Ask the judge; None when its answer has no valid scores."""
    prompt = JUDGE_PROMPT.format(task=describe_for_judge(task))
    return parse_scores(chat.text([{"role": "user", "content": prompt}], temperature=0))


def passes(scores: dict[str, int] | None) -> bool:
    """The paper keeps only tasks rated 5 on all three dimensions."""
    return scores is not None and all(v == 5 for v in scores.values())


def pipeline(chat: CachedChat, *, rewrite: bool, judge: bool) -> Callable[[Task], Task | None]:
    """The `finalize` step of `compose`: rewrite (optional), then judge (optional; None rejects the task)."""

    def finalize(task: Task) -> Task | None:
        if rewrite:
            task = rewrite_instruction(task, chat)
        if judge:
            scores = judge_task(task, chat)
            if not passes(scores):
                return None
            task = task.model_copy(update={"judge": scores})
        return task

    return finalize
