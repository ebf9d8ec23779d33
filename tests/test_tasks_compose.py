"""Composition (Algorithm 1): transfers, value propagation, evaluability, categories, the dataset file and CLI."""

from __future__ import annotations

import json
import os
import random
import subprocess
import sys
from pathlib import Path

import pytest

from jarvis_pytest.cli import main
from jarvis_pytest.errors import ConfigError
from jarvis_pytest.tasks.compose import Draft, Link, Node, build, category_plan, compose, compose_task
from jarvis_pytest.tasks.dataset import dumps_dataset, load_dataset, load_tasks
from jarvis_pytest.tasks.graph import classify, evaluability_problems, task_problems
from jarvis_pytest.tasks.library import Library, load_library
from jarvis_pytest.devices.platforms import spec
from jarvis_pytest.tasks.transfer import transfer_links

LIBRARY = Path(__file__).parent / "data" / "library"


@pytest.fixture(scope="module")
def library() -> Library:
    return load_library(LIBRARY)


def node(library: Library, template_id: str, **values) -> Node:
    tpl = library.get(template_id)
    base = {name: (slot.choices[0] if slot.choices else slot.range[0] if slot.range else "x")
            for name, slot in tpl.inputs.items()}
    return Node(tpl, {**base, **values})


# -- building graphs: transfers and value propagation ------------------------------------------------------
def test_cross_platform_edge_gets_a_transfer_and_values_propagate(library):
    draft = Draft((node(library, "android-camera-take_photo", photo_name="receipt"),
                   node(library, "ubuntu-imagemagick-brighten_image", percent=130)),
                  (Link(0, "photo", 1, "image"),))
    built = build(draft)
    photo, transfer, bright = built.subtasks
    assert [s.template for s in built.subtasks] == ["android-camera-take_photo", "transfer-android-to-ubuntu",
                                                    "ubuntu-imagemagick-brighten_image"]
    assert transfer.platform == "ubuntu" and transfer.source_platform == "android" and transfer.app == "transfer"
    assert transfer.input["transferred_file"].value == "/sdcard/DCIM/Camera/receipt.jpg"
    assert transfer.output["received_file"].value == f"{spec('ubuntu').transfer_folder}/receipt.jpg"
    assert transfer.output["received_file"].type == "jpg_file"  # the transfer hands on the specific type
    assert bright.input["image"].value == "/tmp/transfer/receipt.jpg"
    assert bright.output["bright_image"].value == "/tmp/transfer/receipt_bright.jpg"
    assert "/tmp/transfer/receipt.jpg" in bright.instruction
    assert bright.evaluate[1].args["reference"] == "/tmp/transfer/receipt.jpg"
    assert [s.type for s in bright.config] == ["launch"]  # the step that provided `image` was dropped
    assert [e.model_dump(by_alias=True) for e in built.edges] == [
        {"from": (0, "photo"), "to": (1, "transferred_file")}, {"from": (1, "received_file"), "to": (2, "image")}]
    (check,) = transfer.evaluate
    assert check.func == "transfer_arrived_unchanged" and check.args == {
        "source": "/sdcard/DCIM/Camera/receipt.jpg", "source_platform": "android",
        "path": "/tmp/transfer/receipt.jpg", "folder": "/data"}


def test_a_received_file_edited_downstream_is_not_compared_with_the_source():
    """Notepad converts the received file's line breaks on purpose, after the transfer: the transfer then does not
    compare the destination (the converter compares with what arrived); a copy kept as it arrived is compared. The
    run_script that made the file ran before the transfer: it changes nothing later. Sides are decided from the
    graph when the task is evaluated, never written into the dataset."""
    real = load_library(Path(__file__).resolve().parents[1] / "tasks")
    run = node(real, "ubuntu-terminal-run_script")
    edited = build(Draft((run, node(real, "windows-notepad-crlf_line_endings")), (Link(0, "result", 1, "text_file"),)))
    links = transfer_links(edited.subtasks, edited.edges, 1)
    assert links.destination_consumed == "edit" and not links.source_changed_later and links.upstream == 0
    kept = build(Draft((run, node(real, "windows-wordpad-save_rtf")), (Link(0, "result", 1, "text_file"),)))
    links = transfer_links(kept.subtasks, kept.edges, 1)
    assert links.destination_consumed is None and not links.source_changed_later
    assert all(set(e.args) == {"source", "source_platform", "path", "folder"} for e in kept.subtasks[1].evaluate)


def test_a_program_that_shows_an_upstream_file_is_opened_by_the_subtask_not_at_set_up():
    """WordPad launched at set-up would show the text before Notepad's edit (or no file at all): the launch is
    held back in `opens`, and the instruction asks to open the file instead of saying it is open."""
    real = load_library(Path(__file__).resolve().parents[1] / "tasks")
    edit, save = build(Draft((node(real, "windows-notepad-delete_lines"), node(real, "windows-wordpad-save_rtf")),
                             (Link(0, "edited_file", 1, "text_file"),))).subtasks
    path = edit.output["edited_file"].value
    assert [s.type for s in edit.config][-1] == "launch" and edit.opens is None
    assert "launch" not in [s.type for s in save.config]
    assert [(o.type, o.app, o.args) for o in save.opens] == [("launch", "wordpad", [path])]
    assert save.instruction.startswith(f"Open {path} in WordPad.") and "is open in" not in save.instruction


def test_transfer_to_windows_uses_a_windows_path(library):
    draft = Draft((node(library, "ubuntu-calc-sort_column", spreadsheet="/home/user/Documents/grades.xlsx"),
                   node(library, "windows-calc-add_total_row")), (Link(0, "sorted_file", 1, "spreadsheet"),))
    transfer = build(draft).subtasks[1]
    assert transfer.output["received_file"].value == "C:\\Users\\user\\Downloads\\transfer\\grades_sorted.xlsx"
    assert transfer.solution[0].platform == "ubuntu"  # the oracle uploads on the source device


def test_same_platform_edge_has_no_transfer(library):
    draft = Draft((node(library, "ubuntu-imagemagick-brighten_image", image="/home/user/Pictures/beach.jpg"),
                   node(library, "ubuntu-settings-set_wallpaper")), (Link(0, "bright_image", 1, "image"),))
    built = build(draft)
    assert [s.template for s in built.subtasks] == ["ubuntu-imagemagick-brighten_image", "ubuntu-settings-set_wallpaper"]
    assert built.subtasks[1].input["image"].value == "/home/user/Pictures/beach_bright.jpg"
    assert built.subtasks[1].config == []
    assert classify(built.subtasks, built.edges) == "sw"


def test_upstream_node_added_later_is_ordered_first(library):
    # node 0 consumes what node 1 (added later, as in Algorithm 1 case (i)) produces
    draft = Draft((node(library, "ubuntu-settings-set_wallpaper"), node(library, "ubuntu-imagemagick-brighten_image")),
                  (Link(1, "bright_image", 0, "image"),))
    built = build(draft)
    assert [s.template for s in built.subtasks] == ["ubuntu-imagemagick-brighten_image", "ubuntu-settings-set_wallpaper"]
    assert built.index == {1: 0, 0: 1}


# -- evaluability -------------------------------------------------------------------------------------------------
def test_moving_an_earlier_output_is_rejected(library):
    draft = Draft((node(library, "ubuntu-imagemagick-brighten_image"), node(library, "ubuntu-files-rename_file")),
                  (Link(0, "bright_image", 1, "source_file"),))
    built = build(draft)
    problems = evaluability_problems(built.subtasks, built.edges, library.types)
    assert len(problems) == 1 and "moves" in problems[0] and "no longer be evaluated" in problems[0]


def test_deleting_an_earlier_output_is_rejected(library):
    draft = Draft((node(library, "android-camera-take_photo"), node(library, "android-files-delete_file")),
                  (Link(0, "photo", 1, "target"),))
    built = build(draft)
    assert any("deletes" in p for p in evaluability_problems(built.subtasks, built.edges, library.types))


def test_editing_content_checked_output_is_rejected_but_a_transferred_copy_may_be_edited(library):
    same = Draft((node(library, "android-markor-save_note"), node(library, "android-markor-save_note")), ())
    assert evaluability_problems(build(same).subtasks, [], library.types)  # same note path twice: a clash
    draft = Draft((node(library, "windows-notepad-replace_text"), node(library, "ubuntu-gedit-replace_text")),
                  (Link(0, "edited_file", 1, "text_file"),))
    built = build(draft)  # windows → transfer → ubuntu edits the transferred copy: fine
    assert evaluability_problems(built.subtasks, built.edges, library.types) == []
    local = Draft((node(library, "ubuntu-gedit-replace_text"), node(library, "ubuntu-gedit-replace_text")),
                  (Link(0, "edited_file", 1, "text_file"),))
    built = build(local)
    assert any("edits" in p and "evaluators read its content" in p
               for p in evaluability_problems(built.subtasks, built.edges, library.types))


def test_two_subtasks_changing_one_setting_are_rejected(library):
    draft = Draft((node(library, "ubuntu-settings-set_wallpaper", image="/home/user/Pictures/sunset.jpg"),
                   node(library, "ubuntu-settings-set_wallpaper", image="/home/user/Pictures/forest.png")))
    built = build(draft)
    assert any("'wallpaper' setting" in p for p in evaluability_problems(built.subtasks, built.edges, library.types))


def test_two_subtasks_claiming_one_path_are_rejected(library):
    draft = Draft((node(library, "ubuntu-gedit-replace_text", text_file="/home/user/Documents/notes.txt"),
                   node(library, "ubuntu-files-rename_file", source_file="/home/user/Documents/notes.txt")))
    built = build(draft)
    assert any("both use /home/user/Documents/notes.txt" in p
               for p in evaluability_problems(built.subtasks, built.edges, library.types))


def test_composition_never_emits_an_unevaluable_graph(library):
    tasks = compose(library, seed=3, count=45, max_subtasks=5, balanced=True)
    for task in tasks:
        assert task_problems(task, library.types) == [], task.id


# -- categories, ids, determinism ------------------------------------------------------------------------------------
def test_balanced_gives_equal_thirds_with_readable_ids(library):
    tasks = compose(library, seed=11, count=9, max_subtasks=4, balanced=True)
    assert [t.category for t in tasks] == ["sw"] * 3 + ["mi"] * 3 + ["md"] * 3
    assert [t.id for t in tasks] == [f"{c}-{i:04d}" for i, c in enumerate(["sw"] * 3 + ["mi"] * 3 + ["md"] * 3)]
    for t in tasks:
        platforms = {s.platform for s in t.formatted_subtasks}
        assert t.devices == sorted(platforms)
        if t.category == "sw":
            assert len(platforms) == 1 and t.edges
        elif t.category == "mi":
            assert len(platforms) > 1 and not t.edges
        else:
            assert len(platforms) > 1 and t.edges
        assert 2 <= len(t.formatted_subtasks) <= 4


def test_category_plan():
    assert category_plan(0, 7, True) == ["sw"] * 3 + ["mi"] * 2 + ["md"] * 2
    plan = category_plan(5, 300, False)
    assert set(plan) == {"mi", "dependent"} and 70 < plan.count("mi") < 130
    assert plan == category_plan(5, 300, False)


def test_compose_is_deterministic_and_seed_sensitive(library):
    a = compose(library, seed=42, count=12, max_subtasks=4)
    b = compose(library, seed=42, count=12, max_subtasks=4)
    c = compose(library, seed=43, count=12, max_subtasks=4)
    assert dumps_dataset(a) == dumps_dataset(b)
    assert dumps_dataset(a) != dumps_dataset(c)
    assert len({t.id for t in a}) == 12


def test_compose_task_respects_the_size_limit(library):
    for seed in range(30):
        task = compose_task(library, "md", random.Random(seed), 3)
        if task is not None:
            assert len(task.formatted_subtasks) == 3 and task.category == "md"


def test_merged_instruction_is_numbered_and_names_devices(library):
    task = next(t for t in compose(library, seed=1, count=6, max_subtasks=4, balanced=True) if t.category == "md")
    lines = task.instruction.splitlines()
    assert lines[0].startswith(f"Complete the following {len(task.formatted_subtasks)} steps in order")
    for i, (line, sub) in enumerate(zip(lines[1:], task.formatted_subtasks), 1):
        assert line.startswith(f"{i}. ") and line.endswith(sub.instruction)
        if sub.source_platform is None:
            assert "On the " in line


def test_one_platform_library_cannot_give_mi(tmp_path):
    root = tmp_path / "lib"
    (root / "ubuntu").mkdir(parents=True)
    for path in (LIBRARY / "ubuntu").glob("*.json"):
        (root / "ubuntu" / path.name).write_text(path.read_text())
    one = load_library(root)
    assert [t.category for t in compose(one, seed=0, count=1, max_subtasks=3, balanced=True)] == ["sw"]
    with pytest.raises(ConfigError) as err:
        compose(one, seed=0, count=3, max_subtasks=3, balanced=True)
    assert "could not compose a new mi task" in str(err.value) and err.value.fix


def test_bad_arguments(library):
    with pytest.raises(ConfigError, match="at least 2 subtasks"):
        compose(library, seed=0, count=3, max_subtasks=1)
    with pytest.raises(ConfigError, match="MD task needs at least 3"):
        compose(library, seed=0, count=3, max_subtasks=2, balanced=True)
    assert {t.category for t in compose(library, seed=0, count=6, max_subtasks=2)} <= {"sw", "mi"}


# -- the dataset file and the CLI ---------------------------------------------------------------------------------
def test_cli_compose_twice_is_byte_identical(tmp_path, capsys):
    args = ["compose", "--library", str(LIBRARY), "--seed", "7", "--count", "9", "--balanced",
            "--max-subtasks", "4", "--out"]
    assert main(args + [str(tmp_path / "a.json")]) == 0
    assert main(args + [str(tmp_path / "b.json")]) == 0
    assert "wrote 9 tasks" in capsys.readouterr().out
    a, b = (tmp_path / "a.json").read_bytes(), (tmp_path / "b.json").read_bytes()
    assert a == b and a.endswith(b"}\n")


def test_compose_output_does_not_depend_on_the_hash_seed(tmp_path):
    outputs = []
    for hash_seed in ("1", "12345"):
        out = tmp_path / hash_seed / "ds.json"  # the same command line in both runs: meta records it
        out.parent.mkdir()
        subprocess.run([sys.executable, "-m", "jarvis_pytest.cli", "compose", "--library", str(LIBRARY), "--seed", "5",
                        "--count", "6", "--max-subtasks", "5", "--out", "ds.json"], check=True, capture_output=True,
                       cwd=out.parent, env={**os.environ, "PYTHONHASHSEED": hash_seed,
                                            "PYTHONPATH": str(Path(__file__).resolve().parents[1])})
        outputs.append(out.read_bytes())
    assert outputs[0] == outputs[1]


def test_dataset_file_has_the_paper_format(tmp_path):
    out = tmp_path / "ds.json"
    assert main(["compose", "--library", str(LIBRARY), "--seed", "1", "--count", "6", "--balanced",
                 "--max-subtasks", "4", "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    assert set(data) == {"tasks", "meta"} and data["meta"]["seed"] == 1
    for task in data["tasks"]:
        assert {"id", "category", "devices", "instruction", "edges", "formatted_subtasks"} <= set(task)
        for edge in task["edges"]:
            assert set(edge) == {"from", "to"} and isinstance(edge["from"][0], int) and isinstance(edge["to"][1], str)
        for sub in task["formatted_subtasks"]:
            assert {"template", "platform", "instruction", "input", "output", "config", "evaluate"} <= set(sub)
            for slot in list(sub["input"].values()) + list(sub["output"].values()):
                assert {"type", "value"} <= set(slot)
    tasks = load_tasks([out])
    assert [t.id for t in tasks] == sorted(t["id"] for t in data["tasks"])


def _corrupt(path: Path, change) -> Path:
    data = json.loads(path.read_text())
    change(data)
    bad = path.with_name("bad.json")
    bad.write_text(json.dumps(data))
    return bad


@pytest.fixture
def dataset_file(tmp_path, library) -> Path:
    path = tmp_path / "ds.json"
    path.write_text(dumps_dataset(compose(library, seed=2, count=6, max_subtasks=4, balanced=True)))
    return path


def _md(data):
    return next(t for t in data["tasks"] if t["category"] == "md")


@pytest.mark.parametrize("label,change,needle", [
    ("value not propagated", lambda d: _md(d)["formatted_subtasks"][-1]["input"].update(
        {k: {**v, "value": "/elsewhere"} for k, v in _md(d)["formatted_subtasks"][-1]["input"].items()}),
     "was not propagated"),
    ("edge backwards", lambda d: _md(d)["edges"].__setitem__(0, {"from": _md(d)["edges"][0]["to"],
                                                                "to": _md(d)["edges"][0]["from"]}), "edge 0"),
    ("wrong category", lambda d: _md(d).update(category="mi"), "does not match its graph"),
    ("placeholder left", lambda d: _md(d)["formatted_subtasks"][0].update(instruction="Do {{x}}"), "unrendered"),
    ("duplicate id", lambda d: d["tasks"][1].update(id=d["tasks"][0]["id"]), "duplicate task id"),
    ("unknown field", lambda d: d["tasks"][0].update(extra=1), "unknown field"),
    ("transfer removed", lambda d: _md(d)["formatted_subtasks"][1].update(source_platform=None), "without a transfer"),
])
def test_bad_dataset_gives_one_clear_error(dataset_file, label, change, needle):
    bad = _corrupt(dataset_file, change)
    with pytest.raises(ConfigError) as err:
        load_dataset(bad)
    assert err.value.path == str(bad) and needle in str(err.value), str(err.value)


def test_bad_dataset_json(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"tasks": [}')
    with pytest.raises(ConfigError, match="not valid JSON"):
        load_dataset(bad)


def test_same_id_in_two_dataset_files(dataset_file):
    copy = dataset_file.with_name("copy.json")
    copy.write_text(dataset_file.read_text())
    with pytest.raises(ConfigError, match="also in"):
        load_tasks([dataset_file, copy])


def test_an_unfeedable_input_is_never_fed_from_upstream(library):
    """An input whose content the task assumes (`feedable: false`) keeps the file its own setup makes."""
    fed = {(e.to[1], t.formatted_subtasks[e.to[0]].template)
           for t in compose(library, seed=3, count=40, max_subtasks=3) for e in t.edges}
    assert fed, "the library composes tasks with edges"
    slot, template_id = sorted(fed)[0]
    tpl = library.get(template_id)
    locked = tpl.model_copy(update={"inputs": {**tpl.inputs, slot: tpl.inputs[slot].model_copy(
        update={"feedable": False})}})
    lib = Library.from_templates([locked if t.id == template_id else t for t in library.templates], library.types)
    tasks = compose(lib, seed=3, count=40, max_subtasks=3)
    assert tasks
    assert not [e for t in tasks for e in t.edges
                if e.to[1] == slot and t.formatted_subtasks[e.to[0]].template == template_id]
