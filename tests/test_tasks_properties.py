"""Property-based tests of composition over random template libraries and seeds.

Every composed graph: all edges type-compatible and carrying their value; acyclic; a transfer subtask exactly
where an edge crosses platforms; no later subtask destroying an earlier output; no unrendered placeholder;
category consistent with its graph; and equal seeds give equal output.
"""

from __future__ import annotations

import random
from pathlib import Path

from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from jarvis_pytest.tasks.compose import compose, compose_task
from jarvis_pytest.tasks.dataset import dumps_dataset
from jarvis_pytest.tasks.graph import task_problems
from jarvis_pytest.tasks.library import Library, load_library
from jarvis_pytest.tasks.model import Task, TaskTemplate
from jarvis_pytest.tasks.types import load_types

TYPES = load_types()
LIBRARY = load_library(Path(__file__).parent / "data" / "library")
PLATFORMS = ("android", "ubuntu", "windows")
FILE_TYPES = ("ordinary_file", "office_file", "xlsx_file", "text_file", "txt_file", "image_file", "jpg_file")
SCALAR_TYPES = ("text", "file_name", "number", "percentage", "color")
EXT = {"xlsx_file": ".xlsx", "docx_file": ".docx", "txt_file": ".txt", "jpg_file": ".jpg", "png_file": ".png",
       "zip_file": ".zip", "image_file": ".png", "text_file": ".txt", "office_file": ".xlsx", "ordinary_file": ".bin"}
BASE = {"android": "/sdcard/Download", "ubuntu": "/home/user/Documents", "windows": "C:\\Users\\user\\Documents"}
SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _join(platform: str, *parts: str) -> str:
    return ("\\" if platform == "windows" else "/").join(parts)


@st.composite
def templates(draw, index: int) -> TaskTemplate:
    platform = draw(st.sampled_from(PLATFORMS))
    tid = f"{platform}-rand-t{index}"
    inputs, outputs = {}, {}
    for k in range(draw(st.integers(0, 3))):
        if draw(st.integers(0, 2)):  # two in three inputs are files
            t = draw(st.sampled_from(FILE_TYPES))
            names = draw(st.lists(st.sampled_from(["a", "b", "c", "d"]), min_size=1, max_size=3, unique=True))
            inputs[f"in{k}"] = {"type": t, "choices": [_join(platform, BASE[platform], n + EXT[t]) for n in names]}
        else:
            t = draw(st.sampled_from(SCALAR_TYPES))
            inputs[f"in{k}"] = ({"type": t, "range": [1, 9]} if t in ("number", "percentage")
                                else {"type": t, "pattern": "{word}-{int:1-5}"})
    file_inputs = [n for n, s in inputs.items() if s["type"] in FILE_TYPES]
    for k in range(draw(st.integers(0, 2))):
        same = file_inputs and draw(st.booleans())
        if same:
            source = draw(st.sampled_from(file_inputs))
            outputs[f"out{k}"] = {"type": inputs[source]["type"], "same_type_as": source,
                                  "value": _join(platform, f"{{{{{source}.dir}}}}", f"{tid}_out{k}{{{{{source}.ext}}}}"),
                                  "content_checked": draw(st.booleans())}
        elif draw(st.integers(0, 2)):
            t = draw(st.sampled_from(FILE_TYPES))
            outputs[f"out{k}"] = {"type": t, "value": _join(platform, BASE[platform], f"{tid}_out{k}{EXT[t]}")}
        else:
            t = draw(st.sampled_from(SCALAR_TYPES))
            outputs[f"out{k}"] = {"type": t, "value": f"{tid}-value-{k}"}
    slots = list(inputs) + list(outputs)
    consumes = {n: draw(st.sampled_from(["move", "delete", "edit"])) for n in file_inputs if draw(st.booleans())}
    return TaskTemplate.model_validate({
        "id": tid, "platform": platform, "app": "RandomApp",
        "instruction": f"Do {tid}" + "".join(f" with {{{{{s}}}}}" for s in slots) + ".",
        "inputs": inputs, "outputs": outputs,
        "config": [{"type": "upload_file", "path": f"{{{{{n}}}}}", "content": f"data {{{{{n}.name}}}}", "provides": n}
                   for n in file_inputs] + [{"type": "sleep", "seconds": 0.1}],
        "evaluate": [{"func": "file_contains", "args": {"path": _join(platform, BASE[platform], "answer.txt"),
                                                        "text": f"is {{{{{s}}}}}"}} for s in slots]
        or [{"func": "file_exists", "args": {"path": _join(platform, BASE[platform], "answer.txt")}}],
        "solution": [{"command": f"echo {{{{{s}}}}}"} for s in slots],
        "consumes": consumes,
        "settings": draw(st.lists(st.sampled_from(["wallpaper", "theme"]), max_size=1)),
    })


@st.composite
def libraries(draw) -> Library:
    count = draw(st.integers(2, 10))
    return Library.from_templates([draw(templates(i)) for i in range(count)], TYPES)


def _acyclic(task: Task) -> bool:
    n = len(task.formatted_subtasks)
    indegree = [0] * n
    for e in task.edges:
        indegree[e.to[0]] += 1
    ready = [i for i in range(n) if indegree[i] == 0]
    seen = 0
    while ready:
        i = ready.pop()
        seen += 1
        for e in task.edges:
            if e.from_[0] == i:
                indegree[e.to[0]] -= 1
                if indegree[e.to[0]] == 0:
                    ready.append(e.to[0])
    return seen == n


def _strings(obj):
    if isinstance(obj, str):
        yield obj
    elif isinstance(obj, dict):
        for value in obj.values():
            yield from _strings(value)
    elif isinstance(obj, list):
        for item in obj:
            yield from _strings(item)


def check_graph_properties(task: Task, max_subtasks: int) -> None:
    subs = task.formatted_subtasks
    assert 2 <= len(subs) <= max_subtasks
    assert _acyclic(task)
    for e in task.edges:
        src, dst = subs[e.from_[0]], subs[e.to[0]]
        out, inp = src.output[e.from_[1]], dst.input[e.to[1]]
        assert TYPES.is_subtype(out.type, inp.type), (out.type, inp.type)
        assert out.value == inp.value
        # a transfer exactly where an edge crosses platforms
        if src.platform != dst.platform:
            assert dst.source_platform == src.platform and dst.template == f"transfer-{src.platform}-to-{dst.platform}"
            assert TYPES.is_file(out.type)
        else:
            assert dst.source_platform is None
    for t, sub in enumerate(subs):
        if sub.source_platform is not None:
            ins = [e for e in task.edges if e.to[0] == t]
            outs = [e for e in task.edges if e.from_[0] == t]
            assert len(ins) == 1 and subs[ins[0].from_[0]].platform == sub.source_platform
            assert outs and all(subs[e.to[0]].platform == sub.platform and subs[e.to[0]].source_platform is None
                                for e in outs)
    # evaluability: no later subtask moves, deletes (or edits a content-checked) earlier output
    for j, sub in enumerate(subs):
        for slot, how in sub.consumes.items():
            for i in range(j):
                for out in subs[i].output.values():
                    if subs[i].platform == sub.platform and out.value == sub.input[slot].value:
                        assert how == "edit" and out.content_checked is False
    assert not any("{{" in s or "}}" in s for s in _strings(task.to_json()))
    platforms = {s.platform for s in subs}
    expected = ("sw" if len(platforms) == 1 else "md") if task.edges else "mi"
    assert task.category == expected and task.devices == sorted(platforms)
    assert task_problems(task, TYPES) == []


@SETTINGS
@given(lib=libraries(), seed=st.integers(0, 2**32), category=st.sampled_from(["sw", "mi", "md", "dependent"]),
       max_subtasks=st.integers(2, 6))
def test_random_libraries_compose_valid_graphs(lib, seed, category, max_subtasks):
    results = []
    for attempt in range(5):
        task = compose_task(lib, category, random.Random(f"{seed}:{attempt}"), max_subtasks)
        again = compose_task(lib, category, random.Random(f"{seed}:{attempt}"), max_subtasks)
        assert (task is None and again is None) or task.to_json() == again.to_json()  # determinism
        if task is not None:
            check_graph_properties(task, max_subtasks)
            if category != "dependent":
                assert task.category == category
            results.append(task)
    event(f"composed {category}: {'yes' if results else 'no'}")
    if any(s.source_platform for t in results for s in t.formatted_subtasks):
        event("with a transfer")


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32), count=st.integers(1, 9), balanced=st.booleans(), max_subtasks=st.integers(3, 6))
def test_test_library_datasets_are_valid_and_deterministic(seed, count, balanced, max_subtasks):
    tasks = compose(LIBRARY, seed=seed, count=count, max_subtasks=max_subtasks, balanced=balanced)
    assert dumps_dataset(tasks) == dumps_dataset(compose(LIBRARY, seed=seed, count=count,
                                                         max_subtasks=max_subtasks, balanced=balanced))
    assert len({t.id for t in tasks}) == count
    for task in tasks:
        check_graph_properties(task, max_subtasks)
    if balanced:
        cats = [t.category for t in tasks]
        assert max(cats.count(c) for c in ("sw", "mi", "md")) - min(cats.count(c) for c in ("sw", "mi", "md")) <= 1
