"""Request validation by hand, for the control servers inside devices: the unified action space of
`jarvis_pytest/devices/actions.py` and the request bodies of `protocol.py`, with messages that name the field,
e.g. ``invalid request: CLICK.clicks: must be an integer in [1, 3]``.

No pydantic inside a device: the Windows device's embeddable Python has none, and importing it cost the Ubuntu
server 0.15 of its 0.31 CPU-seconds at every boot. It mirrors those models, and is stricter (no numeric strings,
no booleans as numbers): everything the harness sends (a model's JSON) passes, with the same values, and nothing
the models reject does (`tests/test_device_validate.py` holds it to that)."""

from __future__ import annotations

import json
import math

REQUIRED = object()
BUTTONS = ("left", "middle", "right")
SYSTEM_BUTTONS = ("home", "back", "menu", "enter", "volume_up", "volume_down", "power")

# Bounds of the action space (`actions.py` takes them from here). A value outside them is the agent's error, refused
# before it reaches a device; a device stops what still runs past its 20 s for one action (`control_http.py`), well
# inside the harness's 30 s wait for its answer.
MAX_COORD = 32_767      # |x|, |y|, start and offsets in pixels (X11's range); on screen or not, the device checks
MAX_SCROLL = 100        # |dx|, |dy| wheel notches of one SCROLL
MAX_TEXT = 10_000       # characters of one TYPING (about 1 s of ASCII on an Ubuntu device; see type_within)
MAX_SCRIPT = 20_000     # characters of one PYAUTOGUI script
MAX_KEYS = 16           # keys of one HOTKEY
MAX_KEY_NAME = 64       # characters of one key name


class Invalid(ValueError):
    """A request that does not match its schema; the message names the field."""


def _int(lo=None, hi=None, optional=False):
    return ("int", lo, hi, optional, False)


def _coord(optional=False):
    return _int(-MAX_COORD, MAX_COORD, optional)


def _text(least: int, most: int):
    """A string of `least` to `most` characters that UTF-8 can encode (no lone surrogate)."""
    return ("str", least, most)


def _float(lo=None, hi=None, above=False):
    """A number in [lo, hi], or in (lo, hi] when `above`."""
    return ("float", lo, hi, False, above)


# field → (kind, ...), default (REQUIRED when there is none)
_XY_OPT = {"x": (_coord(optional=True), None), "y": (_coord(optional=True), None)}
_KEY = _text(1, MAX_KEY_NAME)
ACTIONS: dict[str, dict[str, tuple]] = {
    "MOVE_TO": {"x": (_coord(), REQUIRED), "y": (_coord(), REQUIRED)},
    "CLICK": {**_XY_OPT, "button": (("enum", BUTTONS), "left"), "clicks": (_int(1, 3), 1)},
    "MOUSE_DOWN": {"button": (("enum", BUTTONS), "left")},
    "MOUSE_UP": {"button": (("enum", BUTTONS), "left")},
    "RIGHT_CLICK": dict(_XY_OPT),
    "DOUBLE_CLICK": dict(_XY_OPT),
    "DRAG_TO": {"x": (_coord(), REQUIRED), "y": (_coord(), REQUIRED), "start_x": (_coord(optional=True), None),
                "start_y": (_coord(optional=True), None)},
    "SCROLL": {"dx": (_int(-MAX_SCROLL, MAX_SCROLL), 0), "dy": (_int(-MAX_SCROLL, MAX_SCROLL), 0), **_XY_OPT},
    "SWIPE": {"x": (_coord(), REQUIRED), "y": (_coord(), REQUIRED), "dx": (_coord(), REQUIRED),
              "dy": (_coord(), REQUIRED), "duration": (_int(0, 10_000), 300)},
    "LONG_PRESS": {"x": (_coord(), REQUIRED), "y": (_coord(), REQUIRED), "duration": (_int(0, 10_000), 800)},
    "TYPING": {"text": (_text(0, MAX_TEXT), REQUIRED)},
    "KEY_DOWN": {"key": (_KEY, REQUIRED)},
    "KEY_UP": {"key": (_KEY, REQUIRED)},
    "HOTKEY": {"keys": (("strlist", _KEY), REQUIRED)},
    "SYSTEM_BUTTON": {"button": (("enum", SYSTEM_BUTTONS), REQUIRED)},
    "WAIT": {"seconds": (_float(0, 60), 1.0)},
    "DONE": {},
    "FAIL": {},
    "PYAUTOGUI": {"script": (_text(0, MAX_SCRIPT), REQUIRED)},
}
REQUESTS: dict[str, dict[str, tuple]] = {
    "run": {"command": (("str", 1), REQUIRED), "user": (("str?",), None),
            "timeout": (_float(0, 3600, above=True), 60.0)},
    "launch": {"app": (("str", 1), REQUIRED), "args": (("strlist0",), []), "window_wait": (_float(0, 120), 0.0)},
    "open": {"path": (("str", 1), REQUIRED), "window_wait": (_float(0, 120), 0.0)},
    "focus": {"title": (("str?", 1), None), "id": (_int(optional=True), None), "timeout": (_float(0, 60), 5.0)},
    "clipboard": {"text": (("str", 0), REQUIRED)},
}


def _check(where: str, name: str, spec: tuple, value):
    kind = spec[0]
    field = f"{where}.{name}"
    if kind in ("int", "float"):
        _, lo, hi, optional, above = spec
        if value is None and optional:
            return None
        if isinstance(value, bool) or not isinstance(value, (int, float)) or (
                kind == "int" and isinstance(value, float) and not value.is_integer()) or (
                isinstance(value, float) and not (math.isfinite(value) and abs(value) < 2 ** 63)):
            raise Invalid(f"{field}: must be {'an integer' if kind == 'int' else 'a number'}"
                          f"{' or null' if optional else ''}, not {_shown(value)}")
        value = int(value) if kind == "int" else float(value)
        low_ok = lo is None or (value > lo if above else value >= lo)
        if not low_ok or (hi is not None and value > hi):
            raise Invalid(f"{field}: must be {'an integer' if kind == 'int' else 'a number'} in "
                          f"{'(' if above else '['}{lo}, {hi}], not {value}")
        return value
    if kind == "enum":
        if value not in spec[1]:
            raise Invalid(f"{field}: must be one of {', '.join(spec[1])}, not {_shown(value)}")
        return value
    if kind == "str":
        if not isinstance(value, str):
            raise Invalid(f"{field}: must be a string, not {_shown(value)}")
        if len(value) < spec[1]:
            raise Invalid(f"{field}: must not be empty")
        text_problem = problem_of_text(value, spec[2] if len(spec) > 2 else None)
        if text_problem:
            raise Invalid(f"{field}: {text_problem}")
        return value
    if kind == "str?":
        if value is None:
            return None
        if not isinstance(value, str):
            raise Invalid(f"{field}: must be a string or null")
        return _check(where, name, ("str", spec[1] if len(spec) > 1 else 0), value)
    if kind in ("strlist", "strlist0"):
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise Invalid(f"{field}: must be a list of strings, not {_shown(value)}")
        if kind == "strlist" and not value:
            raise Invalid(f"{field}: must hold at least one key")
        if kind == "strlist" and len(value) > MAX_KEYS:
            raise Invalid(f"{field}: must hold at most {MAX_KEYS} keys, not {len(value)}")
        for i, item in enumerate(value):
            _check(where, f"{name}[{i}]", spec[1] if len(spec) > 1 else ("str", 0), item)
        return value
    raise AssertionError(kind)


def problem_of_text(text: str, most: int | None = None) -> str | None:
    """Why `text` cannot be sent to a device (None: it can): longer than `most` characters, or a lone surrogate
    (half of a UTF-16 pair, which UTF-8 cannot encode)."""
    if most is not None and len(text) > most:
        return f"must be at most {most} characters, not {len(text)}"
    try:
        text.encode("utf-8")
    except UnicodeEncodeError as exc:
        return (f"holds a lone surrogate (U+{ord(text[exc.start]):04X}) at character {exc.start}, which UTF-8 "
                f"cannot encode")
    return None


def _shown(value) -> str:
    """`value` as JSON for a message, cut to 80 characters."""
    text = json.dumps(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _fields(where: str, schema: dict[str, tuple], data: dict) -> dict:
    unknown = sorted(set(data) - set(schema))
    if unknown:
        raise Invalid(f"{where}.{unknown[0]}: extra field not permitted")
    out = {}
    for name, (spec, default) in schema.items():
        if name not in data:
            if default is REQUIRED:
                raise Invalid(f"{where}.{name}: field required")
            out[name] = list(default) if isinstance(default, list) else default  # never the shared default itself
        else:
            out[name] = _check(where, name, spec, data[name])
    return out


def _json(body: bytes):
    try:
        return json.loads(body or b"{}")
    except (ValueError, UnicodeDecodeError) as exc:
        raise Invalid(f"body is not JSON: {exc}") from None


def action(body: bytes) -> dict:
    """One action as a dict with `type` and every field (defaults filled in)."""
    data = _json(body)
    if not isinstance(data, dict):
        raise Invalid("an action must be a JSON object with a `type`")
    kind = data.get("type")
    if kind not in ACTIONS:
        raise Invalid(f"type: {json.dumps(kind)} is not an action type (one of {', '.join(ACTIONS)})")
    return {"type": kind, **_fields(kind, ACTIONS[kind], {k: v for k, v in data.items() if k != "type"})}


def request(name: str, body: bytes) -> dict:
    """The body of a `run`, `launch`, `open`, `focus` or `clipboard` request, checked, defaults filled in."""
    data = _json(body)
    if not isinstance(data, dict):
        raise Invalid("the body must be a JSON object")
    return _fields(name, REQUESTS[name], data)
