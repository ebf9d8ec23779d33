"""Evaluator arguments are checked at load against each evaluator's signature: a misspelt, missing or mistyped
argument of a template (at library load) or of a dataset's subtask (at dataset load) is one ConfigError naming
the file, the field (`evaluate[i].args.<name>`) and the fix — not a failed check at run time."""

from __future__ import annotations

import copy
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.evaluators import EVALUATORS, Verdict
from jarvis_pytest.tasks.compose import compose
from jarvis_pytest.tasks.dataset import dumps_dataset, load_dataset
from jarvis_pytest.tasks.library import load_library

REPO = Path(__file__).resolve().parents[1]
TEST_LIBRARY = REPO / "tests" / "data" / "library"

# file_text_equals(state, path: str, expected: str, strip: bool = True, unchanged: list[str] | None = None,
#                  platform: str | None = None)
TEMPLATE = {
    "id": "ubuntu-test-answer",
    "platform": "ubuntu",
    "app": "Terminal",
    "instruction": "Write {{word}} {{count}} times into {{answer}}.",
    "inputs": {"word": {"type": "text", "pattern": "{word}"}, "count": {"type": "number", "range": [2, 5]}},
    "outputs": {"answer": {"type": "txt_file", "value": "/home/user/Documents/{{word}}.txt"}},
    "evaluate": [{"func": "file_exists", "args": {"path": "{{answer}}"}},
                 {"func": "file_text_equals", "args": {"path": "{{answer}}", "expected": "{{word}}", "strip": True}}],
    "solution": [{"command": "echo {{word}} > {{answer}}"}],
}


def library_with(tmp_path: Path, **args_of_second: Any) -> Path:
    """A library of TEMPLATE whose second evaluator (file_text_equals) has `args_of_second` instead."""
    tpl = copy.deepcopy(TEMPLATE)
    tpl["evaluate"][1]["args"] = args_of_second
    root = tmp_path / "lib"
    (root / "ubuntu").mkdir(parents=True, exist_ok=True)
    (root / "ubuntu" / "answer.json").write_text(json.dumps(tpl))
    return root


def load_error(tmp_path: Path, **args: Any) -> ConfigError:
    root = library_with(tmp_path, **args)
    with pytest.raises(ConfigError) as err:
        load_library(root)
    assert err.value.path == str(root / "ubuntu" / "answer.json")
    return err.value


TAKES = "the evaluator takes: path, expected, strip, unchanged, platform"


def test_a_misspelt_argument_names_the_file_the_field_and_the_fix(tmp_path):
    err = load_error(tmp_path, pathh="{{answer}}", expected="{{word}}")
    assert err.field == "evaluate[1].args.pathh"
    assert "'file_text_equals' has no such argument ('pathh')" in err.detail
    assert err.fix == f"did you mean `path`? {TAKES}"
    assert "answer.json" in str(err) and "ubuntu-test-answer" in str(err)


def test_an_unknown_argument_with_no_close_name_lists_what_the_evaluator_takes(tmp_path):
    err = load_error(tmp_path, path="{{answer}}", expected="{{word}}", colour="red")
    assert err.field == "evaluate[1].args.colour" and TAKES in err.fix and "did you mean" not in err.fix


def test_a_missing_required_argument(tmp_path):
    err = load_error(tmp_path, path="{{answer}}", strip=False)
    assert err.field == "evaluate[1].args.expected"
    assert "needs the argument 'expected', which is missing" in err.detail
    assert "add `expected` (str) to args" in err.fix and TAKES in err.fix


def test_the_state_parameter_is_not_an_argument(tmp_path):
    err = load_error(tmp_path, path="{{answer}}", expected="x", state="x")
    assert err.field == "evaluate[1].args.state" and "not an argument" in err.detail


@pytest.mark.parametrize("name, value, words", [
    ("strip", "yes", ["takes bool, not str 'yes'", "write a value of type bool"]),
    ("unchanged", "/home/user/a.txt", ["takes list[str] | None, not str"]),
    ("unchanged", ["/home/user/a.txt", 3], ["takes list[str] | None, not list"]),
    ("expected", 7, ["takes str, not int 7"]),
    ("platform", ["ubuntu"], ["takes str | None, not list"]),
    # a whole placeholder keeps its slot's type: `count` is drawn from a range, an int
    ("expected", "{{count}}", ["takes str, not int 2 from slot 'count'", "make slot 'count' give str values"]),
])
def test_a_mistyped_value(tmp_path, name, value, words):
    args = {"path": "{{answer}}", "expected": "{{word}}", name: value}
    err = load_error(tmp_path, **args)
    assert err.field == f"evaluate[1].args.{name}"
    for word in words:
        assert word in str(err), str(err)


@pytest.mark.parametrize("args", [
    {"path": "{{answer}}", "expected": "{{word}}"},                       # a pattern slot renders as text
    {"path": "{{answer.dir}}/x.txt", "expected": "{{count}} times"},      # placeholders inside text: text
    {"path": "{{answer}}", "expected": "x", "unchanged": None, "platform": None},   # X | None takes None
    {"path": "{{answer}}", "expected": "x", "unchanged": ["{{answer}}", "/home/user/b.txt"], "strip": False},
])
def test_values_that_fit_load(tmp_path, args):
    assert load_library(library_with(tmp_path, **args)).templates


def test_numbers_any_and_nested_annotations(tmp_path, monkeypatch):
    def check(state, path: str, scale: float, anything: Any, table: dict[str, list[int]] | None = None) -> Verdict:
        return Verdict(True, "")

    monkeypatch.setitem(EVALUATORS, "test_scaled", check)
    # an int where a float is wanted is fine; a placeholder deep inside keeps its slot's type (`count`: an int)
    ok = {"path": "x", "scale": "{{count}}", "anything": {"a": [1, None]}, "table": {"a": [1, "{{count}}"]}}
    root = library_with(tmp_path, path="{{answer}}", expected="x")
    tpl = json.loads((root / "ubuntu" / "answer.json").read_text())
    tpl["evaluate"].append({"func": "test_scaled", "args": ok})
    (root / "ubuntu" / "answer.json").write_text(json.dumps(tpl))
    assert load_library(root).templates
    tpl["evaluate"][2]["args"] = dict(ok, table={"a": [1, "2"]})
    (root / "ubuntu" / "answer.json").write_text(json.dumps(tpl))
    with pytest.raises(ConfigError) as err:
        load_library(root)
    assert err.value.field == "evaluate[2].args.table" and "dict[str, list[int]] | None" in str(err.value)


def test_an_evaluator_taking_kwargs_takes_any_name(tmp_path, monkeypatch):
    monkeypatch.setitem(EVALUATORS, "test_open", lambda state, path, **rest: Verdict(True, ""))
    root = library_with(tmp_path, path="{{answer}}", expected="x")
    tpl = json.loads((root / "ubuntu" / "answer.json").read_text())
    tpl["evaluate"].append({"func": "test_open", "args": {"path": "x", "whatever": 1}})
    (root / "ubuntu" / "answer.json").write_text(json.dumps(tpl))
    assert load_library(root).templates
    tpl["evaluate"][2]["args"] = {"whatever": 1}
    (root / "ubuntu" / "answer.json").write_text(json.dumps(tpl))
    with pytest.raises(ConfigError, match="needs the argument 'path'"):
        load_library(root)


def test_the_check_reads_the_registry_when_it_runs(tmp_path, monkeypatch):
    """An evaluator's signature as registered at load time decides: the same template passes, then fails once the
    evaluator no longer takes the argument (e.g. an argument removed from an evaluator)."""
    root = library_with(tmp_path, path="{{answer}}", expected="x")
    tpl = json.loads((root / "ubuntu" / "answer.json").read_text())
    tpl["evaluate"].append({"func": "test_changing", "args": {"path": "x", "later": True}})
    (root / "ubuntu" / "answer.json").write_text(json.dumps(tpl))
    monkeypatch.setitem(EVALUATORS, "test_changing", lambda state, path, later=False: Verdict(True, ""))
    assert load_library(root).templates
    monkeypatch.setitem(EVALUATORS, "test_changing", lambda state, path: Verdict(True, ""))
    with pytest.raises(ConfigError) as err:
        load_library(root)
    assert err.value.field == "evaluate[2].args.later" and "has no such argument" in str(err.value)


# -- datasets ---------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def dataset_data(tmp_path_factory) -> dict:
    return json.loads(dumps_dataset(compose(load_library(TEST_LIBRARY), seed=2, count=4, max_subtasks=3)))


def _first(data: dict, func: str) -> tuple[int, int, int, dict]:
    for i, task in enumerate(data["tasks"]):
        for j, sub in enumerate(task["formatted_subtasks"]):
            for k, spec in enumerate(sub["evaluate"]):
                if spec["func"] == func:
                    return i, j, k, spec
    raise AssertionError(f"no {func} in the dataset")


@pytest.mark.parametrize("change, name, words", [
    (lambda a: a.update(pathh=a.pop("path")), "pathh", ["has no such argument ('pathh')", "did you mean `path`?"]),
    (lambda a: a.pop("path"), "path", ["needs the argument 'path'", "add `path` (str)"]),
    (lambda a: a.update(path=["x"]), "path", ["takes str, not list ['x']"]),
])
def test_a_dataset_task_with_a_bad_argument(tmp_path, dataset_data, change, name, words):
    data = copy.deepcopy(dataset_data)
    assert load_dataset(_write(tmp_path, data)).tasks
    i, j, k, spec = _first(data, "file_exists")
    change(spec["args"])
    path = _write(tmp_path, data)
    with pytest.raises(ConfigError) as err:
        load_dataset(path)
    assert err.value.path == str(path)
    assert err.value.field == f"tasks[{i}].formatted_subtasks[{j}].evaluate[{k}].args.{name}"
    assert f"task {data['tasks'][i]['id']!r}" in str(err.value)
    for word in words:
        assert word in str(err.value), str(err.value)


def _write(tmp_path: Path, data: dict) -> Path:
    path = tmp_path / "ds.json"
    path.write_text(json.dumps(data))
    return path


# -- the shipped library and the command line -------------------------------------------------------------------
@pytest.mark.parametrize("root", [REPO / "tasks", TEST_LIBRARY], ids=["tasks", "test library"])
def test_the_libraries_pass_the_check(root):
    assert load_library(root).templates


def test_jarvis_templates_reports_the_bad_argument_in_one_line(tmp_path):
    root = library_with(tmp_path, pathh="{{answer}}", expected="x")
    proc = subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "templates", "--library", str(root)],
                          cwd=REPO, capture_output=True, text=True, timeout=120)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 2 and "Traceback" not in out, out
    assert "answer.json" in out and "evaluate[1].args.pathh" in out and "did you mean `path`?" in out, out
