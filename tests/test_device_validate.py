"""The control servers' hand validation (`devices/validate.py`) against the pydantic models it mirrors
(`devices/actions.py`, `devices/protocol.py`).

The servers inside devices import no pydantic (the Windows device's embeddable Python has none; on Ubuntu it was
half the server's CPU at every boot), so the same shapes are checked twice. What must hold, probed field by field
with values of every JSON kind, in range and out: everything the harness sends (a model's JSON) passes the hand
validation with the same values; whatever the models reject, it rejects too; whatever it accepts, the models accept
with the same values. It may be stricter (it takes no numeric strings and no booleans as numbers)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from pydantic import BaseModel, ValidationError

from jarvis_pytest.devices import actions as A
from jarvis_pytest.devices import protocol as P
from jarvis_pytest.devices import validate as V

REPO = Path(__file__).resolve().parents[1]
REQUEST_MODELS: dict[str, type[BaseModel]] = {"run": P.RunRequest, "launch": P.LaunchRequest,
                                              "open": P.OpenRequest, "focus": P.FocusRequest,
                                              "clipboard": P.ClipboardText}
ACTION_MODELS: dict[str, type[BaseModel]] = {cls.model_fields["type"].default: cls
                                             for cls in A._Action.__subclasses__()}
PROBES = [None, True, False, 0, 1, -1, 2, 3, 4, 0.5, 1.0, -0.5, 59.5, 60, 60.5, 120, 120.5, 3600, 3600.5, 10_000,
          10_001, "", "a", "5", "left", "home", [], ["a"], ["a", ""], [1], {}, {"a": 1},
          # the bounds of the action space (issue 37: an agent's garbage is refused, never sent on)
          100, 101, -100, -101, 32_767, 32_768, -32_767, -32_768, 1e9, 1e300, float("nan"), float("inf"),
          "\ud800", "a\udfffb", "\U0001F600", "x" * 64, "x" * 65, "x" * 10_000, "x" * 10_001, "x" * 20_001,
          ["a"] * 16, ["a"] * 17, ["x" * 65], ["\ud800"]]


def _valid(spec: tuple):
    """A value the field takes."""
    kind = spec[0]
    return {"int": 1, "float": 1.0, "enum": spec[-1][0] if kind == "enum" else None, "str": "a", "str?": "a",
            "strlist": ["a"], "strlist0": ["a"]}[kind]


def _bodies(schema: dict[str, tuple], type_: str | None) -> list[dict]:
    """Every required field valid, then each field (and an unknown one, and `type`) set to each probe or left out."""
    base = {"type": type_} if type_ else {}
    required = {name: _valid(spec) for name, (spec, default) in schema.items() if default is V.REQUIRED}
    bodies = [base | required]
    for name in [*schema, "unknown", *([] if type_ else ["type"])]:
        bodies.append({k: v for k, v in (base | required).items() if k != name})
        bodies += [base | required | {name: value} for value in PROBES]
    return bodies


def _pydantic(model: type[BaseModel] | None, body: bytes, type_: str | None):
    try:
        if type_ is None:
            return True, model.model_validate_json(body).model_dump(mode="json")
        return True, A.ACTION_ADAPTER.validate_json(body).model_dump(mode="json")
    except ValidationError:
        return False, None


def _by_hand(name: str, body: bytes, type_: str | None):
    try:
        return True, (V.action(body) if type_ else V.request(name, body))
    except V.Invalid as exc:
        assert str(exc), "a rejection names what is wrong"
        return False, None


def test_it_knows_every_action_and_request_field_with_the_models_defaults():
    assert set(V.ACTIONS) == set(A.ACTION_TYPES) == set(ACTION_MODELS)
    for type_, cls in ACTION_MODELS.items():
        fields = {n: f for n, f in cls.model_fields.items() if n != "type"}
        assert set(V.ACTIONS[type_]) == set(fields), type_
        for name, field in fields.items():
            default = V.ACTIONS[type_][name][1]
            assert (default is V.REQUIRED) == field.is_required(), (type_, name)
            if not field.is_required():
                assert default == field.get_default(call_default_factory=True), (type_, name)
    for name, cls in REQUEST_MODELS.items():
        assert set(V.REQUESTS[name]) == set(cls.model_fields), name
        for field_name, field in cls.model_fields.items():
            default = V.REQUESTS[name][field_name][1]
            assert (default is V.REQUIRED) == field.is_required(), (name, field_name)
            if not field.is_required():
                assert default == field.get_default(call_default_factory=True), (name, field_name)


CASES = [(type_, None) for type_ in sorted(V.ACTIONS)] + [(None, name) for name in sorted(V.REQUESTS)]


@pytest.mark.parametrize("type_, name", CASES, ids=[t or n for t, n in CASES])
def test_it_accepts_what_the_harness_sends_and_nothing_the_models_reject(type_, name):
    schema = V.ACTIONS[type_] if type_ else V.REQUESTS[name]
    model = None if type_ else REQUEST_MODELS[name]
    accepted = 0
    for data in _bodies(schema, type_):
        body = json.dumps(data).encode()
        by_model, value = _pydantic(model, body, type_)
        by_hand, checked = _by_hand(name, body, type_)
        if by_hand:
            assert by_model and checked == value, (data, checked, value)
            accepted += 1
        if by_model:  # what the harness sends is the model's own JSON
            canonical = json.dumps(value).encode()
            ok, again = _by_hand(name, canonical, type_)
            assert ok and again == value, (data, value, again)
    assert accepted > 0


def test_bad_bodies_are_refused_with_the_field_named():
    with pytest.raises(V.Invalid, match=r"CLICK\.clicks: must be an integer in \[1, 3\], not 9"):
        V.action(b'{"type": "CLICK", "clicks": 9}')
    with pytest.raises(V.Invalid, match=r"MOVE_TO\.z: extra field not permitted"):
        V.action(b'{"type": "MOVE_TO", "x": 1, "y": 1, "z": 2}')
    with pytest.raises(V.Invalid, match="is not an action type"):
        V.action(b'{"type": "CLIK"}')
    with pytest.raises(V.Invalid, match="body is not JSON"):
        V.action(b"{not json")
    with pytest.raises(V.Invalid, match=r"run\.timeout: must be a number in \(0, 3600\]"):
        V.request("run", b'{"command": "true", "timeout": 0}')
    with pytest.raises(V.Invalid, match=r"run\.type: extra field not permitted"):
        V.request("run", b'{"command": "true", "type": "CLICK"}')


def test_the_device_servers_import_no_pydantic():
    """The modules both control servers load (the Ubuntu image no longer carries pydantic at all)."""
    code = ("import sys\n"
            "import jarvis_pytest.devices.ubuntu.server.app, jarvis_pytest.devices.ubuntu.server.system\n"
            "import jarvis_pytest.devices.windows.server.app\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('pydantic', 'pydantic_core')))")
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout


@pytest.mark.parametrize("body, message", [
    (b'{"type": "SCROLL", "dy": 1e9}', r"SCROLL\.dy: must be an integer in \[-100, 100\], not 1000000000"),
    (b'{"type": "SCROLL", "dy": NaN}', r"SCROLL\.dy: must be an integer, not NaN"),
    (b'{"type": "CLICK", "x": Infinity, "y": 1}', r"CLICK\.x: must be an integer or null, not Infinity"),
    (b'{"type": "MOVE_TO", "x": 40000, "y": 1}', r"MOVE_TO\.x: must be an integer in \[-32767, 32767\]"),
    (b'{"type": "TYPING", "text": "a\\ud800"}', r"TYPING\.text: holds a lone surrogate \(U\+D800\) at character 1"),
    (b'{"type": "TYPING", "text": "' + b"x" * 10_001 + b'"}', r"TYPING\.text: must be at most 10000 characters"),
    (b'{"type": "HOTKEY", "keys": [' + b",".join([b'"a"'] * 17) + b"]}", r"HOTKEY\.keys: must hold at most 16"),
    (b'{"type": "HOTKEY", "keys": ["ctrl", ""]}', r"HOTKEY\.keys\[1\]: must not be empty"),
    (b'{"type": "CLICK", "x": true, "y": 1}', r"CLICK\.x: must be an integer or null, not true"),
    (b'{"type": "PYAUTOGUI", "script": "\\udfff"}', r"PYAUTOGUI\.script: holds a lone surrogate"),
])
def test_an_agents_garbage_is_refused_by_the_device_too(body, message):
    """Issue 37: what the action models refuse, a device server refuses (a 400, the agent's step error) even when
    it arrives from elsewhere, with the field and the bound named."""
    with pytest.raises(V.Invalid, match=message):
        V.action(body)
