"""Grounding: turn "the element to act on" plus one screenshot into a pixel, through a grounding model.

Every adapter under the top-level ``agents/`` folder subclasses :class:`Grounder` and supplies only what is its
model's own: the prompt (``messages``), the request parameters, where the answer sits in the text
(``answer_tags``/``answer_marker``) and the coordinate convention (``scale`` for relative models, ``resize`` for
models that answer in the pixels of the image they were shown). Everything else lives here:

* :func:`smart_resize` — the Qwen2-VL/2.5-VL resize rule. Absolute-pixel models get the screenshot pre-resized to
  that size on the client, so the server keeps it as is and the answer is in a known pixel space.
* :func:`extract_point` — tolerant parsing: JSON objects (``{"x":..,"y":..}``, ``"coordinate": [..]``), UI-TARS
  tags (``<point>x y</point>``, ``<bbox>``, ``<|box_start|>``, ``start_box='(x,y)'``), bracketed numbers, spaces,
  floats, 4-number boxes (their centre) and text around them.
* mapping back to screen pixels, clamped to the screen.

An answer that cannot be understood raises :class:`GroundingError`; the planner–grounder agent turns it into a
step error ("action not found: ...") for the planner to see, never a crash.
"""

from __future__ import annotations

import io
import json
import math
import re
import time
from dataclasses import dataclass, field
from typing import Any, ClassVar

from PIL import Image

from jarvis_pytest.errors import JarvisError
from jarvis_pytest.llm.client import ChatClient, image_part

MAX_RATIO = 200


class GroundingError(JarvisError):
    """The grounding model's answer holds no usable point; `answer` and `usage` are those of the failed call."""

    def __init__(self, message: str, *, answer: str | None = None, usage: dict[str, int] | None = None):
        super().__init__(message)
        self.answer = answer
        self.usage = dict(usage or {})


def smart_resize(height: int, width: int, factor: int = 28, min_pixels: int = 56 * 56,
                 max_pixels: int = 14 * 14 * 4 * 1280) -> tuple[int, int]:
    """(height, width) after the Qwen2-VL resize rule: each side rounded to a multiple of `factor` (Python
    `round`, half to even), then scaled down (floor) if the area exceeds `max_pixels` or up (ceil) if below
    `min_pixels`, keeping the aspect ratio. Sizes this returns map to themselves."""
    if min(height, width) <= 0:
        raise ValueError(f"image size must be positive, got {width}x{height}")
    if max(height, width) / min(height, width) > MAX_RATIO:
        raise ValueError(f"aspect ratio must be below {MAX_RATIO}, got {width}x{height}")
    h_bar = max(factor, round(height / factor) * factor)
    w_bar = max(factor, round(width / factor) * factor)
    if h_bar * w_bar > max_pixels:
        beta = math.sqrt(height * width / max_pixels)
        h_bar = max(factor, math.floor(height / beta / factor) * factor)
        w_bar = max(factor, math.floor(width / beta / factor) * factor)
    elif h_bar * w_bar < min_pixels:
        beta = math.sqrt(min_pixels / (height * width))
        h_bar = math.ceil(height * beta / factor) * factor
        w_bar = math.ceil(width * beta / factor) * factor
    return h_bar, w_bar


@dataclass(frozen=True)
class Resize:
    """The smart_resize parameters of a model that answers in the pixels of the (resized) image it saw."""

    factor: int
    min_pixels: int
    max_pixels: int

    def size(self, width: int, height: int) -> tuple[int, int]:
        """(width, height) the model sees for a `width`x`height` screenshot."""
        h, w = smart_resize(height, width, self.factor, self.min_pixels, self.max_pixels)
        return w, h


# -- tolerant parsing --------------------------------------------------------------------------------------------
_NUMBER = r"[-+]?\d+(?:\.\d+)?"
_NUMBER_RE = re.compile(_NUMBER)
_TAG_PATTERNS = [
    re.compile(r"<point>(.*?)</point>", re.S),
    re.compile(r"<bbox>(.*?)</bbox>", re.S),
    re.compile(r"<\|box_start\|>(.*?)<\|box_end\|>", re.S),
    re.compile(r"(?:start_box|point)\s*=\s*['\"]?\s*([\[(][^)\]]*[)\]])", re.S),
]
_GROUP_RE = re.compile(r"[\[(]\s*(" + _NUMBER + r"(?:\s*[,;\s]\s*" + _NUMBER + r")+)\s*[\])]")
_POINT_KEYS = ("coordinate", "coordinates", "point", "position", "click", "start_box", "bbox", "box")


def numbers(text: str) -> list[float]:
    """Every number in `text`, as floats."""
    return [float(n) for n in _NUMBER_RE.findall(text)]


def point_of(values: list[float]) -> tuple[float, float]:
    """A point from 2 numbers, or the centre of a 4-number box (x1, y1, x2, y2); finite ones only."""
    if not all(math.isfinite(v) for v in values):
        raise GroundingError(f"a point needs finite numbers, not {values}")
    if len(values) == 2:
        return values[0], values[1]
    if len(values) == 4:
        return (values[0] + values[2]) / 2, (values[1] + values[3]) / 2
    raise GroundingError(f"expected 2 numbers (a point) or 4 (a box), found {len(values)}")


def json_objects(text: str) -> list[Any]:
    """Every JSON object embedded in `text`, outermost first, in order."""
    decoder = json.JSONDecoder()
    out, i = [], text.find("{")
    while i != -1:
        try:
            obj, end = decoder.raw_decode(text, i)
        except json.JSONDecodeError:
            i = text.find("{", i + 1)
            continue
        out.append(obj)
        i = text.find("{", end)
    return out


def _point_in_json(obj: Any) -> tuple[float, float] | None:
    if isinstance(obj, dict):
        if "x" in obj and "y" in obj:
            try:
                return point_of([float(obj["x"]), float(obj["y"])])
            except (TypeError, ValueError, GroundingError):
                return None
        for key in _POINT_KEYS:
            value = obj.get(key)
            if isinstance(value, (list, tuple)):
                try:
                    return point_of([float(v) for v in value])
                except (TypeError, ValueError, GroundingError):
                    continue
            if isinstance(value, str) and len(numbers(value)) in (2, 4):
                return point_of(numbers(value))
        for value in obj.values():
            found = _point_in_json(value)
            if found is not None:
                return found
    return None


def extract_point(text: str) -> tuple[float, float]:
    """The point a grounding answer names, in the model's own coordinates; raises GroundingError if none."""
    for obj in json_objects(text):
        found = _point_in_json(obj)
        if found is not None:
            return found
    for pattern in _TAG_PATTERNS:
        match = pattern.search(text)
        if match and len(numbers(match.group(1))) in (2, 4):
            return point_of(numbers(match.group(1)))
    for match in _GROUP_RE.finditer(text):
        values = numbers(match.group(1))
        if len(values) in (2, 4):
            return point_of(values)
    values = numbers(text)
    if len(values) in (2, 4):
        return point_of(values)
    raise GroundingError(f"no point or box found in the answer {text.strip()[:200]!r}")


def strip_tags(text: str, tags: tuple[str, ...]) -> str:
    """`text` without the <tag>...</tag> blocks of `tags` (reasoning that may mention other numbers)."""
    for tag in tags:
        text = re.sub(rf"<{tag}>.*?</{tag}>", " ", text, flags=re.S)
        if f"</{tag}>" in text:  # an opening tag the server swallowed
            text = text.split(f"</{tag}>", 1)[1]
    return text


def tagged(text: str, tag: str) -> str | None:
    """The content of the last <tag>...</tag> block (an unclosed last block counts), or None."""
    found = re.findall(rf"<{tag}>(.*?)(?:</{tag}>|$)", text, flags=re.S)
    return found[-1] if found else None


def function_call_prompt(preamble: str, tool: dict[str, Any]) -> str:
    """A system prompt in the Qwen function-calling template (Qwen2.5-VL/Qwen3-VL and their fine-tunes): the
    preamble, the tool's JSON signature inside <tools></tools>, and the <tool_call></tool_call> answer format."""
    return (f"{preamble}\n\n# Tools\n\nYou may call one or more functions to assist with the user query.\n\n"
            "You are provided with function signatures within <tools></tools> XML tags:\n<tools>\n"
            f"{json.dumps(tool, ensure_ascii=False)}\n</tools>\n\n"
            "For each function call, return a json object with function name and arguments within "
            "<tool_call></tool_call> XML tags:\n<tool_call>\n"
            '{"name": <function-name>, "arguments": <args-json-object>}\n</tool_call>')


def click_tool(name: str, description: str, action_doc: str, coordinate_doc: str, enum: str,
               required: tuple[str, ...]) -> dict[str, Any]:
    """The JSON signature of a one-action (click) computer/mobile tool, as the Qwen-style grounding prompts use."""
    return {"type": "function", "function": {
        "name": name, "description": description,
        "parameters": {"properties": {
            "action": {"description": action_doc, "enum": [enum], "type": "string"},
            "coordinate": {"description": coordinate_doc, "type": "array"}},
            "required": list(required), "type": "object"}}}


# -- the adapter base class --------------------------------------------------------------------------------------
@dataclass
class Grounding:
    """One grounding: the screen pixel, and how it was obtained."""

    x: int
    y: int
    answer: str
    model_point: tuple[float, float]
    sent_size: tuple[int, int]
    screen_size: tuple[int, int]
    usage: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0
    model_seconds: float = 0.0  # of `seconds`, the time waiting for the model's answer

    def record(self) -> dict[str, Any]:
        """A JSON-ready summary for the trajectory."""
        return {"point": [self.x, self.y], "model_point": list(self.model_point), "sent_size": list(self.sent_size),
                "screen_size": list(self.screen_size), "answer": self.answer, "seconds": round(self.seconds, 3)}


class Grounder:
    """Base class of the grounding adapters; subclasses set the class attributes and `messages`.

    * ``name``: the agent name (``holo2``); ``default_model``: the served model name when none is configured.
    * ``scale``: for relative models, the value that means the right/bottom edge (1000, 999); ``None`` for
      absolute-pixel models, which set ``resize`` instead.
    * ``params``: request parameters (temperature, max_tokens, structured output, ...).
    * ``answer_tags``: tags whose content holds the answer (the last one wins), ``answer_marker``: text after
      which the answer starts (UI-TARS' "Action:"), ``think_tags``: reasoning blocks ignored when parsing.
    """

    name: ClassVar[str] = ""
    default_model: ClassVar[str] = ""
    scale: ClassVar[float | None] = 1000.0
    resize: ClassVar[Resize | None] = None
    params: ClassVar[dict[str, Any]] = {"temperature": 0.0, "max_tokens": 256}
    answer_tags: ClassVar[tuple[str, ...]] = ()
    answer_marker: ClassVar[str | None] = None
    think_tags: ClassVar[tuple[str, ...]] = ("think", "thinking", "grounding_think")

    def __init__(self, client: ChatClient):
        self.client = client
        self.overrides: dict[str, Any] = {}  # sampling parameters the run set (`--agent-option grounder_*`)
        self.call_params: dict[str, Any] = {}  # per task and trial: its seed (set by the agent's reset)

    # -- what a subclass provides --------------------------------------------------------------------------------
    def messages(self, instruction: str, image: dict[str, Any], size: tuple[int, int],
                 platform: str) -> list[dict[str, Any]]:
        """The chat messages for one grounding; `image` is the image part, `size` the (w, h) it has."""
        raise NotImplementedError

    def request_params(self) -> dict[str, Any]:
        """Every request's parameters: the adapter's `params`, the run's sampling overrides, the trial's seed."""
        return {**self.params, **self.overrides, **self.call_params}

    @classmethod
    def model_input(cls) -> dict[str, Any]:
        """How a screenshot reaches the model, for the run card: its encoding and, per platform, the size it is sent
        at for the platform's default screen."""
        from jarvis_pytest.devices.platforms import PLATFORMS

        sent = {p: list(cls.resize.size(*f.screen) if cls.resize else f.screen) for p, f in PLATFORMS.items()}
        return {"encoding": "PNG", "screen": {p: list(f.screen) for p, f in PLATFORMS.items()}, "sent": sent}

    # -- shared logic --------------------------------------------------------------------------------------------
    def parse(self, text: str) -> tuple[float, float]:
        """The point in the model's coordinates (see the class docstring for where it is looked for)."""
        region = strip_tags(text, self.think_tags)
        for tag in self.answer_tags:
            inner = tagged(region, tag)
            if inner is not None and inner.strip():
                region = inner
                break
        if self.answer_marker and self.answer_marker in region:
            region = region.rsplit(self.answer_marker, 1)[1]
        return extract_point(region)

    def prepare(self, png: bytes) -> tuple[bytes, tuple[int, int], tuple[int, int]]:
        """(image bytes to send, screen size, sent size): pre-resized for absolute-pixel models, else as is."""
        with Image.open(io.BytesIO(png)) as img:
            screen = img.size
            if self.resize is None:
                return png, screen, screen
            target = self.resize.size(*screen)
            if target == screen:
                return png, screen, screen
            img.load()
            resized = img.resize(target, Image.Resampling.BICUBIC)
        out = io.BytesIO()
        resized.save(out, format="PNG", compress_level=1)
        return out.getvalue(), screen, target

    def to_screen(self, point: tuple[float, float], screen: tuple[int, int],
                  sent: tuple[int, int]) -> tuple[int, int]:
        """Map a model point to screen pixels, clamped to the screen."""
        (mx, my), (w, h) = point, screen
        if self.scale is not None:
            x, y = mx / self.scale * w, my / self.scale * h
        else:
            x, y = mx * w / sent[0], my * h / sent[1]
        return min(max(int(round(x)), 0), w - 1), min(max(int(round(y)), 0), h - 1)

    def ground(self, png: bytes, instruction: str, platform: str = "ubuntu") -> Grounding:
        """Ground `instruction` on the screenshot `png`; the answer is in the screenshot's own pixels.
        Raises GroundingError for an answer without a point, InfrastructureError when the endpoint fails."""
        t0 = time.monotonic()
        data, screen, sent = self.prepare(png)
        result = self.client.chat(self.messages(instruction, image_part(data), sent, platform),
                                  **self.request_params())
        try:
            point = self.parse(result.text)
        except GroundingError as exc:
            raise GroundingError(f"{self.name}: {exc}", answer=result.text, usage=result.usage) from None
        x, y = self.to_screen(point, screen, sent)
        return Grounding(x=x, y=y, answer=result.text, model_point=point, sent_size=sent, screen_size=screen,
                         usage=dict(result.usage), seconds=time.monotonic() - t0, model_seconds=result.seconds)
