"""Template files: the test library, atomic instances, and one clear error per bad file."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from jarvis_pytest.cli import main
from jarvis_pytest.errors import ConfigError
from jarvis_pytest.tasks.graph import task_problems
from jarvis_pytest.tasks.instances import atomic_instances, materialise
from jarvis_pytest.tasks.library import load_library
from jarvis_pytest.tasks.model import BoundSlot
from jarvis_pytest.tasks.templating import has_placeholder

LIBRARY = Path(__file__).parent / "data" / "library"

GOOD = {
    "id": "ubuntu-test-copy_file",
    "platform": "ubuntu",
    "app": "Terminal",
    "instruction": "Copy {{source}} to {{copy}}.",
    "inputs": {"source": {"type": "txt_file", "choices": ["/home/user/a.txt", "/home/user/b.txt"]}},
    "outputs": {"copy": {"type": "txt_file", "value": "{{source.dir}}/copy_of_{{source.name}}"}},
    "config": [{"type": "upload_file", "path": "{{source}}", "content": "hello", "provides": "source"}],
    "evaluate": [{"func": "file_copied", "args": {"path": "{{copy}}", "source": "{{source}}"}}],
    "solution": [{"command": "cp '{{source}}' '{{copy}}'"}],
}


@pytest.fixture(scope="module")
def library():
    return load_library(LIBRARY)


def test_test_library_has_six_to_eight_templates_per_platform(library):
    for platform in ("android", "windows", "ubuntu"):
        assert 6 <= len(library.by_platform(platform)) <= 8, platform
    assert [t.id for t in library.templates] == sorted(t.id for t in library.templates)
    assert library.sources["android-files-delete_file"].name == "files.json"  # a file holding a list


def test_test_library_evaluators_are_named_with_templated_args(library):
    for tpl in library.templates:
        assert tpl.evaluate and all(spec.func for spec in tpl.evaluate)


def test_atomic_instances_are_seeded_readable_and_valid(library):
    tasks = atomic_instances(library, seeds_per_template=3)
    assert len(tasks) == 3 * len(library.templates)
    assert tasks[0].id == f"{library.templates[0].id}[seed0]"
    assert [t.id for t in tasks] == [f"{tpl.id}[seed{n}]" for tpl in library.templates for n in range(3)]
    again = atomic_instances(library, seeds_per_template=3)
    assert [t.to_json() for t in tasks] == [t.to_json() for t in again]
    for task in tasks:
        assert task.category == "atomic" and len(task.formatted_subtasks) == 1
        assert task_problems(task, library.types) == []
        assert not has_placeholder(task.to_json())


def test_atomic_instance_does_not_depend_on_other_templates(library, tmp_path):
    lone = tmp_path / "lib"
    (lone / "ubuntu").mkdir(parents=True)
    src = library.sources["ubuntu-calc-sort_column"]
    (lone / "ubuntu" / src.name).write_text(src.read_text())
    alone = atomic_instances(load_library(lone), 2)
    full = [t for t in atomic_instances(library, 2) if t.id.startswith("ubuntu-calc-sort_column[")]
    assert [t.to_json() for t in alone] == [t.to_json() for t in full]


def test_materialise_binds_inputs_outputs_and_drops_provided_setup(library):
    tpl = library.get("ubuntu-calc-sort_column")
    sub = materialise(tpl, {"spreadsheet": "/home/user/Documents/grades.xlsx", "column": "B"})
    assert sub.output["sorted_file"].value == "/home/user/Documents/grades_sorted.xlsx"
    assert [s.type for s in sub.config] == ["upload_file", "open"]
    assert sub.config[0].fixture == "office/grades.xlsx"
    assert sub.evaluate[1].args == {"path": "/home/user/Documents/grades_sorted.xlsx",
                                    "reference": "/home/user/Documents/grades.xlsx", "column": "B"}
    fed = materialise(tpl, {"spreadsheet": "/x.xlsx", "column": "B"},
                      fed={"spreadsheet": BoundSlot(type="xlsx_file", value="/tmp/transfer/q.xlsx")})
    assert fed.config == []  # both setup steps provide the fed input
    assert fed.input["spreadsheet"].type == "xlsx_file"
    assert fed.output["sorted_file"].value == "/tmp/transfer/q_sorted.xlsx"


def test_same_type_as_takes_the_bound_type(library):
    tpl = library.get("ubuntu-files-rename_file")
    sub = materialise(tpl, {"source_file": "/home/user/x.txt", "new_stem": "y"},
                      fed={"source_file": BoundSlot(type="jpg_file", value="/home/user/p.jpg")})
    assert sub.output["renamed_file"].type == "jpg_file"
    assert sub.output["renamed_file"].value == "/home/user/y.jpg"


def test_atomic_instances_are_typed_tasks_in_the_dataset_format(tmp_path):
    tasks = atomic_instances(load_library(LIBRARY), 1)
    assert tasks[0].id.endswith("[seed0]") and tasks[0].category == "atomic"
    sub = tasks[0].to_json()["formatted_subtasks"][0]
    assert {"template", "platform", "app", "instruction", "input", "output", "config", "evaluate", "solution"} <= set(sub)
    empty = tmp_path / "empty"
    empty.mkdir()
    assert atomic_instances(load_library(empty), 2) == []


def test_cli_templates_lists_and_checks_the_library(capsys):
    assert main(["templates", "--library", str(LIBRARY)]) == 0
    out = capsys.readouterr().out
    assert "ubuntu-calc-sort_column\tubuntu\tLibreOffice Calc" in out and "21 templates, all valid" in out


def test_unknown_evaluator_or_generator_is_refused_when_templates_load(tmp_path, capsys):
    """Names are resolved at load time, naming the file and the field (not at run time, per task)."""
    tpl = json.loads((LIBRARY / "ubuntu" / "files_rename_file.json").read_text())
    bad = dict(tpl, evaluate=[{"func": "no_such_check", "args": {}}])
    root = tmp_path / "lib"
    (root / "ubuntu").mkdir(parents=True)
    (root / "ubuntu" / "x.json").write_text(json.dumps(bad))
    assert main(["templates", "--library", str(root)]) == 2
    err = capsys.readouterr().err
    assert "unknown evaluator 'no_such_check'" in err and "x.json" in err and "evaluate[0].func" in err
    bad = dict(tpl, config=[{"type": "upload_file", "path": "/home/user/a.txt", "generator": "no_such_gen"}])
    (root / "ubuntu" / "x.json").write_text(json.dumps(bad))
    assert main(["templates", "--library", str(root)]) == 2
    assert "unknown file generator 'no_such_gen'" in capsys.readouterr().err


@pytest.mark.parametrize("fixture, why", [
    ("/etc/passwd", "relative"), ("../../../etc/passwd", "relative"), ("C:\\Windows\\win.ini", "relative"),
    ("escape/passwd", "leads out"),
])
def test_fixture_outside_fixtures_files_is_refused_at_load(tmp_path, capsys, fixture, why, monkeypatch):
    """A template cannot copy a host file into a device: absolute paths, `..` and symlinks out are refused."""
    from jarvis_pytest.tasks import library as library_module

    files = tmp_path / "files"
    files.mkdir()
    (files / "escape").symlink_to("/etc")
    monkeypatch.setattr(library_module, "FIXTURE_FILES", files)
    monkeypatch.setattr(library_module.fixture_problem, "__defaults__", (files,))
    tpl = json.loads((LIBRARY / "ubuntu" / "files_rename_file.json").read_text())
    bad = dict(tpl, config=[{"type": "upload_file", "path": "/home/user/a.txt", "fixture": fixture}])
    root = tmp_path / "lib"
    (root / "ubuntu").mkdir(parents=True)
    (root / "ubuntu" / "x.json").write_text(json.dumps(bad))
    assert main(["templates", "--library", str(root)]) == 2
    err = capsys.readouterr().err
    assert why in err and "x.json" in err and "fixture" in err and "Traceback" not in err


@pytest.mark.parametrize("path", ["/etc/cron.d/evil", "/home/user/../../etc/x", "relative/file.txt"])
def test_upload_outside_the_writable_places_of_the_device_is_refused(tmp_path, capsys, path):
    tpl = json.loads((LIBRARY / "ubuntu" / "files_rename_file.json").read_text())
    bad = dict(tpl, config=[{"type": "upload_file", "path": path, "content": "x"}])
    root = tmp_path / "lib"
    (root / "ubuntu").mkdir(parents=True)
    (root / "ubuntu" / "x.json").write_text(json.dumps(bad))
    assert main(["templates", "--library", str(root)]) == 2
    err = capsys.readouterr().err
    assert "not where a task may write" in err and "config[0].path" in err


# -- bad task files: one clear error each, naming the file -----------------------------------------------------
def _library_with(tmp_path: Path, content: object, *, platform: str = "ubuntu", name: str = "bad.json",
                  types: object | None = None) -> tuple[Path, Path]:
    root = tmp_path / "lib"
    (root / platform).mkdir(parents=True)
    path = root / platform / name
    path.write_text(content if isinstance(content, str) else json.dumps(content))
    if types is not None:
        (root / "types.json").write_text(json.dumps(types))
    return root, path


def _mutated(**changes: object) -> dict:
    data = copy.deepcopy(GOOD)
    for dotted, value in changes.items():
        keys = dotted.split("__")
        target = data
        for key in keys[:-1]:
            target = target[key]
        if value is None:
            del target[keys[-1]]
        else:
            target[keys[-1]] = value
    return data


def test_good_template_loads(tmp_path):
    root, _ = _library_with(tmp_path, GOOD)
    assert [t.id for t in load_library(root).templates] == ["ubuntu-test-copy_file"]


BAD_FILES = [
    ("unknown type", _mutated(inputs__source__type="txt_fil"), "inputs.source.type", "unknown slot type 'txt_fil'"),
    ("missing slot", _mutated(instruction="Copy {{sourse}} to {{copy}}."), "instruction",
     "placeholder {{sourse}} names no slot"),
    ("missing slot in evaluator", _mutated(evaluate=[{"func": "file_exists", "args": {"path": "{{out}}"}}]),
     "evaluate[0].args.path", "{{out}} names no slot"),
    ("output uses an output", _mutated(outputs__copy__value="{{copy}}.bak"), "outputs.copy.value",
     "{{copy}} names no slot (slots: source)"),
    ("bad JSON", '{"id": "x",\n "platform": "ubuntu",,}', None, "not valid JSON"),
    ("unknown field", _mutated(evaluators=[]), "evaluators", "unknown field"),
    ("missing field", _mutated(evaluate=None), "evaluate", "required field is missing"),
    ("no domain", _mutated(inputs__source={"type": "txt_file"}), "inputs.source", "no sampling domain"),
    ("bad setup step", _mutated(config=[{"type": "upload", "path": "x"}]), "config[0]", "upload"),
    ("provides no input", _mutated(config=[{"type": "open", "path": "{{source}}", "provides": "src"}]),
     "config[0].provides", "provides names no input slot"),
    ("consumes no input", _mutated(consumes={"src": "move"}), "consumes.src", "consumes names no input slot"),
    ("path part of a scalar", _mutated(inputs__n={"type": "number", "range": [1, 3]}, instruction="{{n.name}}"),
     "instruction", "not a file"),
    ("bad action", _mutated(solution=[{"action": {"type": "CLIK"}}]), "solution[0]", "invalid action"),
    ("platform folder mismatch", _mutated(platform="windows"), "platform", "in the ubuntu/ folder"),
    ("same_type_as too narrow", _mutated(outputs__copy={"type": "jpg_file", "value": "/x", "same_type_as": "source"}),
     "outputs.copy.type", "not a supertype"),
    ("reserved id", _mutated(id="transfer-ubuntu-to-windows"), "id", "reserved"),
]


@pytest.mark.parametrize("label,content,field,needle", BAD_FILES, ids=[b[0] for b in BAD_FILES])
def test_bad_task_file_gives_one_clear_error(tmp_path, label, content, field, needle):
    root, path = _library_with(tmp_path, content)
    with pytest.raises(ConfigError) as err:
        load_library(root)
    msg = str(err.value)
    assert err.value.path == str(path), msg
    assert str(path) in msg and needle in msg, msg
    if field is not None:
        assert err.value.field == field, msg
    assert err.value.fix, msg


def test_error_in_a_list_file_names_the_item_and_task(tmp_path):
    root, path = _library_with(tmp_path, [GOOD, _mutated(id="ubuntu-test-two", inputs__source__type="nope")])
    with pytest.raises(ConfigError) as err:
        load_library(root)
    assert "'ubuntu-test-two'" in str(err.value) and str(path) in str(err.value)


def test_schema_error_in_a_list_file_names_the_index(tmp_path):
    root, _ = _library_with(tmp_path, [GOOD, _mutated(id="ubuntu-test-two", app=None)])
    with pytest.raises(ConfigError) as err:
        load_library(root)
    assert err.value.field == "[1].app" and "'ubuntu-test-two'" in str(err.value)


def test_duplicate_ids_name_both_files(tmp_path):
    root, first = _library_with(tmp_path, GOOD, name="a.json")
    second = root / "ubuntu" / "b.json"
    second.write_text(json.dumps(GOOD))
    with pytest.raises(ConfigError) as err:
        load_library(root)
    assert str(second) in str(err.value) and str(first) in str(err.value)


def test_cycle_in_the_library_types_file(tmp_path):
    root, _ = _library_with(tmp_path, GOOD, types={"types": {"file": None, "txt_file": "text_file",
                                                             "text_file": "txt_file"}})
    with pytest.raises(ConfigError) as err:
        load_library(root)
    assert str(root / "types.json") in str(err.value) and "cycle" in str(err.value)


def test_unknown_evaluator_with_a_registry(tmp_path):
    root, path = _library_with(tmp_path, GOOD)
    with pytest.raises(ConfigError, match="unknown evaluator 'file_copied'") as err:
        load_library(root, evaluators={"file_exists"})
    assert err.value.path == str(path)
    assert load_library(root, evaluators={"file_copied"}).templates


def test_missing_library_folder(tmp_path):
    with pytest.raises(ConfigError, match="no such library folder"):
        load_library(tmp_path / "nowhere")


def test_cli_schema_prints_a_json_schema_for_template_files(capsys):
    assert main(["schema"]) == 0
    schema = json.loads(capsys.readouterr().out)
    assert schema["$schema"].startswith("https://json-schema.org/")
    assert "TaskTemplate" in schema["$defs"] and {"$ref": "#/$defs/TaskTemplate"} in schema["anyOf"]
    props = schema["$defs"]["TaskTemplate"]["properties"]
    assert {"id", "platform", "app", "instruction", "inputs", "outputs", "config", "evaluate", "solution"} <= set(props)


def test_cli_schema_of_dataset_files(capsys):
    assert main(["schema", "--kind", "dataset"]) == 0
    schema = json.loads(capsys.readouterr().out)
    assert "from" in schema["$defs"]["Edge"]["properties"]


def test_every_template_of_the_benchmark_carries_near_miss_negatives():
    """Issue 16: at least two negatives per template, an `artefact` and a wrong/partial/damage state."""
    from jarvis_pytest.tasks.library import negative_problems

    lib = load_library(Path(__file__).resolve().parents[1] / "tasks")
    lacking = {t.id: negative_problems(t) for t in lib.templates if negative_problems(t) or len(t.negatives) < 2}
    assert not lacking, lacking


def test_pytest_cases_make_atomic_instances_on_first_use(monkeypatch, pytestconfig):
    """Collection and `-k`/`-m` selection read a case's id, category, platforms, applications and size without
    making its instance (every xdist worker once made every instance only to deselect most); what they read is
    what the made task says, and the task is the one `atomic_instances` makes."""
    from types import SimpleNamespace

    from jarvis_pytest.plugin import cases
    from jarvis_pytest.harness.runner import task_platforms
    from jarvis_pytest.tasks import instances

    repo_tasks = Path(__file__).resolve().parents[1] / "tasks"
    expected = atomic_instances(load_library(repo_tasks), 3)
    made = []
    real = instances.atomic_task
    monkeypatch.setattr(instances, "atomic_task", lambda t, n, **kw: made.append(n) or real(t, n, **kw))
    params = cases.params("atomic", SimpleNamespace(library=repo_tasks, instances=3, trials=1),
                          pytestconfig)  # the application markers are declared on it
    assert made == [] and len(params) == 3 * len(load_library(repo_tasks).templates)
    for param, task in zip(params, expected, strict=True):
        case = param.values[0]
        assert param.id == case.id == task.id and case.category == task.category == "atomic"
        assert case.platforms == list(task_platforms(task)) and case.size == len(task.formatted_subtasks)
        assert case.apps == sorted({s.app for s in task.formatted_subtasks if s.app})
        assert [m.name for m in param.marks] == [*case.platforms, "atomic",
                                                 *(cases.app_marker(a) for a in case.apps)]
        assert case.task.to_json() == task.to_json() and case.task is case.task  # made once
    assert len(made) == len(params)
