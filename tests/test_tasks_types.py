"""The slot type system: tasks/types.json, t ⪯ u, validation errors, `jarvis types`."""

from __future__ import annotations

import json

import pytest

from jarvis_pytest.cli import main
from jarvis_pytest.errors import ConfigError
from jarvis_pytest.tasks.types import REPO_TYPES_FILE, TypeSystem, load_types


@pytest.fixture(scope="module")
def types() -> TypeSystem:
    return load_types()


def test_repository_types_file_loads(types):
    assert types.source == REPO_TYPES_FILE
    assert types.parents["file"] is None
    assert "xlsx_file" in types and "text" in types


@pytest.mark.parametrize("t,u,expected", [
    ("xlsx_file", "office_file", True),
    ("xlsx_file", "ordinary_file", True),
    ("xlsx_file", "file", True),
    ("xlsx_file", "xlsx_file", True),
    ("office_file", "xlsx_file", False),
    ("png_file", "office_file", False),
    ("email", "text", True),
    ("text", "email", False),
    ("number", "file", False),
])
def test_subtype_queries(types, t, u, expected):
    assert types.is_subtype(t, u) is expected


def test_every_file_type_descends_from_file(types):
    files = [t for t in types.names if types.is_file(t)]
    assert {"file", "jpg_file", "zip_file", "m4a_file", "pdf_file"} <= set(files)
    assert not types.is_file("text") and not types.is_file("directory")


def test_ancestors_are_nearest_first(types):
    assert types.ancestors("xlsx_file") == ["xlsx_file", "spreadsheet_file", "office_file", "ordinary_file", "file"]


def _write(tmp_path, data) -> str:
    path = tmp_path / "types.json"
    path.write_text(data if isinstance(data, str) else json.dumps(data))
    return path


def test_cycle_is_one_clear_error(tmp_path):
    path = _write(tmp_path, {"types": {"file": None, "a": "b", "b": "c", "c": "a"}})
    with pytest.raises(ConfigError) as err:
        TypeSystem.load(path)
    assert str(path) in str(err.value)
    assert "cycle" in str(err.value) and "a → b → c → a" in str(err.value)


def test_undeclared_parent_is_an_error_with_a_suggestion(tmp_path):
    path = _write(tmp_path, {"types": {"file": None, "office_file": "file", "xlsx_file": "ofice_file"}})
    with pytest.raises(ConfigError) as err:
        TypeSystem.load(path)
    msg = str(err.value)
    assert str(path) in msg and "types.xlsx_file" in msg and "'ofice_file'" in msg and "office_file" in msg


def test_bad_json_names_the_file_and_line(tmp_path):
    path = _write(tmp_path, '{"types": {"file": null,}}')
    with pytest.raises(ConfigError) as err:
        TypeSystem.load(path)
    assert str(path) in str(err.value) and "line 1" in str(err.value)


def test_root_file_type_is_required(tmp_path):
    path = _write(tmp_path, {"types": {"text": None}})
    with pytest.raises(ConfigError, match="'file' must be declared"):
        TypeSystem.load(path)


def test_unknown_type_query_is_an_error(types):
    with pytest.raises(ConfigError, match="unknown slot type 'xlsx_fil'.*xlsx_file"):
        types.is_subtype("xlsx_fil", "file")


def test_cli_types_json_prints_every_type_with_its_parent(capsys, types):
    assert main(["types", "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed == types.to_json()
    assert printed["xlsx_file"] == "spreadsheet_file" and printed["file"] is None


def test_cli_types_tree(capsys):
    assert main(["types"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "file" in lines and "        xlsx_file" in lines  # file > ordinary > office > spreadsheet > xlsx


def test_cli_types_reports_bad_file(tmp_path, capsys):
    path = _write(tmp_path, {"types": {"file": None, "a": "a"}})
    assert main(["types", "--types", str(path)]) == 2
    assert "cycle" in capsys.readouterr().err
