"""`{{slot}}` templating: rendering, path parts, typed whole placeholders, clear errors."""

from __future__ import annotations

import pytest

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.tasks.templating import Where, find_placeholders, has_placeholder, path_part, render_data, render_text

WHERE = Where("tasks/ubuntu/x.json", "ubuntu-x", "instruction")


def test_render_text_replaces_every_placeholder():
    assert render_text("Sort {{file}} by {{ col }}.", {"file": "/a/b.xlsx", "col": "B"}) == "Sort /a/b.xlsx by B."


@pytest.mark.parametrize("value,attr,expected", [
    ("/home/user/Documents/report.final.xlsx", "name", "report.final.xlsx"),
    ("/home/user/Documents/report.final.xlsx", "stem", "report.final"),
    ("/home/user/Documents/report.final.xlsx", "ext", ".xlsx"),
    ("/home/user/Documents/report.xlsx", "dir", "/home/user/Documents"),
    ("C:\\Users\\Docker\\Documents\\target.txt", "name", "target.txt"),
    ("C:\\Users\\Docker\\Documents\\target.txt", "dir", "C:\\Users\\Docker\\Documents"),
    ("/sdcard/DCIM/Camera/noext", "ext", ""),
])
def test_path_parts(value, attr, expected):
    assert path_part(value, attr) == expected
    assert render_text(f"{{{{f.{attr}}}}}", {"f": value}) == expected


def test_render_is_single_pass():
    assert render_text("{{a}}", {"a": "{{b}}", "b": "x"}) == "{{b}}"


def test_whole_placeholder_keeps_the_value_type_in_data():
    data = {"args": {"percent": "{{level}}", "text": "at {{level}}%", "items": ["{{level}}", 3]}}
    assert render_data(data, {"level": 40}) == {"args": {"percent": 40, "text": "at 40%", "items": [40, 3]}}


def test_unknown_placeholder_names_file_task_field_and_placeholder():
    with pytest.raises(ConfigError) as err:
        render_text("Open {{fiel}}", {"file": "x"}, WHERE)
    msg = str(err.value)
    assert "tasks/ubuntu/x.json" in msg and "'ubuntu-x'" in msg and "instruction" in msg and "{{fiel}}" in msg
    assert err.value.path == "tasks/ubuntu/x.json" and err.value.field == "instruction"


def test_unknown_placeholder_inside_nested_data_names_the_nested_field():
    with pytest.raises(ConfigError) as err:
        render_data({"args": {"path": "{{nope}}"}}, {}, Where("f.json", "t", "evaluate[0]"))
    assert err.value.field == "evaluate[0].args.path"


@pytest.mark.parametrize("text", ["{{ bad-name }}", "{{x", "x}}", "{{}}", "{{a.b.c}}"])
def test_malformed_placeholders_are_errors(text):
    with pytest.raises(ConfigError, match="malformed placeholder"):
        find_placeholders(text, WHERE)


def test_unknown_attribute_is_an_error():
    with pytest.raises(ConfigError, match="unknown attribute 'suffix'"):
        find_placeholders("{{f.suffix}}", WHERE)


def test_path_part_of_a_number_is_an_error():
    with pytest.raises(ConfigError, match="non-path value 3"):
        render_text("{{n.name}}", {"n": 3}, WHERE)


def test_has_placeholder_finds_leftovers_anywhere():
    assert has_placeholder({"a": [{"b": "x {{y}}"}]})
    assert not has_placeholder({"a": [{"b": "x {y}"}], "n": 3})
