"""The six grounding adapters against a loopback OpenAI-compatible server that answers in each model's documented
format: the pixel they return is within 1 px of the right one on 1920x1080, 1280x720, 1080x2400 and 3840x2160
screens, for tidy and awkward answers (spaces, floats, boxes, text around); the absolute-pixel models send the
screenshot pre-resized by smart_resize (checked on the image the server received); unparseable answers raise
GroundingError. Also smart_resize itself and the tolerant parser."""

from __future__ import annotations

import json

import pytest

from jarvis_pytest.agents.grounding import GroundingError, Resize, extract_point, smart_resize
from jarvis_pytest.agents.registry import load_grounder_class
from jarvis_pytest.llm.client import ChatClient
from jarvis_pytest.llm.fake_server import FakeChatServer
from screens import screenshot

SIZES = [(1920, 1080), (1280, 720), (1080, 2400), (3840, 2160)]
STYLES = ["canonical", "spaces", "floats", "box", "extra_text"]
FRACTION = (0.8713, 0.9281)  # where the fake model points, as a fraction of the image it saw

# Each model's convention, written out independently of the adapters: relative scale, or smart_resize bounds.
CONVENTIONS = {
    "qwen3-vl": {"scale": 1000},
    "holo2": {"scale": 1000},
    "mai-ui": {"scale": 999},
    "ui-tars-1.5": {"resize": (28, 100 * 28 * 28, 16384 * 28 * 28)},
    "ui-venus": {"resize": (28, 2_000_000, 4_800_000)},
    "gui-owl": {"resize": (28, 3136, 10_035_200)},
}


def _fmt(v: float, style: str) -> str:
    return f"{v:.1f}" if style == "floats" else str(int(v))


def _values(x: float, y: float, style: str) -> list[float]:
    """The numbers the fake model prints: a point (1 decimal for "floats", else integers) or an integer box."""
    if style == "floats":
        return [round(x, 1), round(y, 1)]
    cx, cy = round(x), round(y)
    return [cx - 20, cy - 10, cx + 20, cy + 10] if style == "box" else [cx, cy]


def _centre(values: list[float]) -> tuple[float, float]:
    return (values[0], values[1]) if len(values) == 2 else ((values[0] + values[2]) / 2, (values[1] + values[3]) / 2)


def render(model: str, values: list[float], style: str) -> str:
    """The answer `model` gives for `values` (a point or a box) in its documented format, styled."""
    sp = " " if style == "spaces" else ""
    nums = f",{sp}".join(_fmt(v, style) for v in values)
    if style == "spaces":
        nums = " " + " ,  ".join(_fmt(v, style) for v in values) + " "
    if model == "qwen3-vl":
        body = (f'<tool_call>\n{{"name": "computer_use", "arguments": {{"action": "left_click", '
                f'"coordinate": [{nums}]}}}}\n</tool_call>')
    elif model == "holo2":
        # structured output cannot be a box: the "box" style becomes its centre written as floats
        x, y = (_fmt(v, "floats" if style in ("floats", "box") else style) for v in _centre(values))
        body = f'{{ "x" : {x} , "y" : {y} }}' if style == "spaces" else f'{{"x": {x}, "y": {y}}}'
    elif model == "ui-tars-1.5":
        if len(values) == 4:
            body = "Action: click(start_box='<bbox>" + " ".join(_fmt(v, style) for v in values) + "</bbox>')"
        elif style == "spaces":
            body = f"Action: click(point='<point> {_fmt(values[0], style)}   {_fmt(values[1], style)} </point>')"
        elif style == "floats":
            body = f"Action: click(start_box='({nums})')"
        else:
            body = f"Action: click(point='<point>{' '.join(_fmt(v, style) for v in values)}</point>')"
    elif model == "mai-ui":
        body = (f"<grounding_think>The icon left of the 12:45 clock, 3rd of 7 in row 2.</grounding_think>\n"
                f'<answer>\n{{"coordinate": [{nums}]}}\n</answer>')
    elif model == "ui-venus":
        body = f"[{nums}]"
    elif model == "gui-owl":
        body = (f"<thinking>Row 2, item 3 of 9 is the target.</thinking>\n<tool_call>\n"
                f'{{"name": "computer_use", "arguments": {{"action": "click", "coordinate": [{nums}]}}}}\n'
                f"</tool_call>\n<conclusion>Click item 3 of 9.</conclusion>")
    else:
        raise AssertionError(model)
    if style == "extra_text":
        return f"Sure. The element is 4th in the list of 10.\n{body}\nHope this helps!"
    return body


def expected_sent_size(model: str, width: int, height: int) -> tuple[int, int]:
    conv = CONVENTIONS[model]
    if "resize" not in conv:
        return width, height
    factor, lo, hi = conv["resize"]
    h, w = smart_resize(height, width, factor, lo, hi)
    return w, h


def expected_pixel(model: str, value: float, screen: int, sent: int) -> float:
    conv = CONVENTIONS[model]
    return value / conv["scale"] * screen if "scale" in conv else value * screen / sent


@pytest.fixture(scope="module")
def pngs() -> dict[tuple[int, int], bytes]:
    return {size: screenshot(*size, [(size[0] // 3, size[1] // 3, size[0] // 3 + 60, size[1] // 3 + 40)])
            for size in SIZES}


@pytest.fixture(scope="module")
def server():
    with FakeChatServer() as srv:
        yield srv


def _model_point(model: str, sent: tuple[int, int]) -> tuple[float, float]:
    conv = CONVENTIONS[model]
    if "scale" in conv:
        return FRACTION[0] * conv["scale"], FRACTION[1] * conv["scale"]
    return FRACTION[0] * sent[0], FRACTION[1] * sent[1]


CASES = [(m, s, st) for m in CONVENTIONS for s in SIZES for st in STYLES
         # on 4K, the resizing models get two styles (each resize of 8 Mpx costs ~0.4 s on this machine)
         if not (s == (3840, 2160) and "resize" in CONVENTIONS[m] and st not in ("canonical", "box"))]


@pytest.mark.parametrize("model,size,style", CASES, ids=[f"{m}-{s[0]}x{s[1]}-{st}" for m, s, st in CASES])
def test_grounded_pixel_within_one_px(model, size, style, pngs, server):
    served = f"{model}-{size[0]}x{size[1]}-{style}"
    sent_sizes: list[tuple[int, int]] = []
    answers: list[list[float]] = []

    def answer(req):  # the fake model: points at FRACTION of the image it actually received
        sent = req.image_sizes()[0]
        sent_sizes.append(sent)
        values = _values(*_model_point(model, sent), style)
        answers.append(values)
        return render(model, values, style)

    server.respond_with(answer, model=served)
    grounder = load_grounder_class(model)(ChatClient(server.url, served, backoff=0.01))
    result = grounder.ground(pngs[size], "the Save button", "android" if size == (1080, 2400) else "ubuntu")

    width, height = size
    sent = expected_sent_size(model, width, height)
    assert sent_sizes == [sent], "the client did not send the smart_resize'd image"
    assert result.sent_size == sent and result.screen_size == size
    mx, my = _centre(answers[0])
    ex, ey = expected_pixel(model, mx, width, sent[0]), expected_pixel(model, my, height, sent[1])
    assert abs(result.x - ex) <= 1 and abs(result.y - ey) <= 1, (result, ex, ey)


def test_known_smart_resize_values():
    # Hand-computed with the rule in DESIGN §5 (round to the factor; floor when above max, ceil when below min).
    assert smart_resize(1080, 1920, 28, 100 * 784, 16384 * 784) == (1092, 1932)
    assert smart_resize(720, 1280, 28, 2_000_000, 4_800_000) == (1064, 1904)  # scaled up to >= 2 Mpx
    assert smart_resize(2160, 3840, 28, 2_000_000, 4_800_000) == (1624, 2912)  # scaled down to <= 4.8 Mpx
    assert smart_resize(2160, 3840, 28, 3136, 10_035_200) == (2156, 3836)
    assert smart_resize(2400, 1080, 28, 2_000_000, 4_800_000) == (2408, 1092)
    assert smart_resize(70, 42, 28, 1, 10**9) == (56, 56)  # 2.5 and 1.5 round half to even: 2 and 2
    with pytest.raises(ValueError):
        smart_resize(10, 5000)


@pytest.mark.parametrize("resize", [Resize(28, 100 * 784, 16384 * 784), Resize(28, 2_000_000, 4_800_000),
                                    Resize(28, 3136, 10_035_200), Resize(32, 65536, 16777216)])
@pytest.mark.parametrize("size", SIZES + [(1366, 768), (2560, 1440), (720, 1600), (800, 601)])
def test_smart_resize_is_a_fixed_point(resize, size):
    """What the client sends is kept as is by the server (which applies the same rule again)."""
    w, h = resize.size(*size)
    assert (w % resize.factor, h % resize.factor) == (0, 0)
    assert resize.min_pixels <= w * h <= resize.max_pixels
    assert resize.size(w, h) == (w, h)
    assert abs(w / h - size[0] / size[1]) / (size[0] / size[1]) < 0.05


@pytest.mark.parametrize("text,point", [
    ('{"x": 12, "y": 34}', (12, 34)),
    ('noise {"coordinate": [ 10.5 , 20 ]} tail', (10.5, 20)),
    ('{"arguments": {"coordinate": [0, 0, 10, 20]}}', (5, 10)),
    ("click(point='<point>7 8</point>')", (7, 8)),
    ("<|box_start|>(100,200)<|box_end|>", (100, 200)),
    ("click(start_box='(3, 4)')", (3, 4)),
    ("<bbox>0 0 100 50</bbox>", (50, 25)),
    ("The box is [ 1 , 2 , 3 , 4 ].", (2, 3)),
    ("(640, 360)", (640, 360)),
    ("640 360", (640, 360)),
])
def test_extract_point_tolerates(text, point):
    assert extract_point(text) == pytest.approx(point)


@pytest.mark.parametrize("model", sorted(CONVENTIONS))
@pytest.mark.parametrize("answer", ["", "I cannot find it.", "<answer>nothing here</answer>",
                                    '{"x": "left"}', "[1, 2, 3]",
                                    # numbers no screen has (issue 37: the model's garbage, the agent's step error)
                                    '{"x": "nan", "y": 5}', '{"coordinate": [1e400, 2]}', '{"x": "inf", "y": "-inf"}'])
def test_unparseable_answer_is_a_grounding_error(model, answer, server):
    served = f"bad-{model}-{len(answer)}"
    server.respond_with(lambda req: answer, model=served)
    grounder = load_grounder_class(model)(ChatClient(server.url, served))
    with pytest.raises(GroundingError, match=model):
        grounder.ground(screenshot(320, 200), "the OK button")


def _request(server, model: str, platform: str, size=(1080, 2400)):
    served = f"shape-{model}-{platform}"
    server.respond_with(lambda req: render(model, [10.0, 10.0], "canonical"), model=served)
    grounder = load_grounder_class(model)(ChatClient(server.url, served))
    grounder.ground(screenshot(*size), "the Wi-Fi toggle", platform)
    return server.requests_for(served)[-1]


@pytest.mark.parametrize("model,platform,needles", [
    ("qwen3-vl", "ubuntu", ["The screen's resolution is 1000x1000", "left_click", "<tool_call>", "MUST left click"]),
    ("holo2", "ubuntu", ["Localize an element on the GUI image", "normalized between 0 and 1000.'", "'title': 'ClickCoordinates'", "Your target is:"]),
    ("ui-tars-1.5", "ubuntu", ["click(point='<point>x1 y1</point>'')", "## User Instruction \n the Wi-Fi toggle"]),
    ("mai-ui", "android", ["You are a GUI grounding agent.", "<grounding_think>", '{"coordinate": [x,y]}']),
    ("ui-venus", "android", ["Outline the position corresponding to the instruction: the Wi-Fi toggle. "
                             "The output should be only [x1,y1,x2,y2]."]),
    ("gui-owl", "android", ['"name": "mobile_use"', "The screen's resolution is 1092x2408", "touchscreen"]),
    ("gui-owl", "windows", ['"name": "computer_use"', "The screen's resolution is 1092x2408", "desktop GUI"]),
])
def test_each_model_gets_its_own_prompt(model, platform, needles, server):
    req = _request(server, model, platform)
    text = req.text()
    for needle in needles:
        assert needle in text, f"{needle!r} missing from the {model} prompt:\n{text}"
    assert "the Wi-Fi toggle" in text
    assert len(req.images()) == 1 and req.body["temperature"] == 0.0


def test_holo2_asks_for_structured_output_without_thinking(server):
    body = _request(server, "holo2", "ubuntu").body
    schema = body["response_format"]["json_schema"]["schema"]
    assert body["response_format"]["type"] == "json_schema"
    assert set(schema["required"]) == {"x", "y"} and schema["properties"]["x"]["maximum"] == 1000
    assert body["chat_template_kwargs"] == {"thinking": False}
    json.dumps(body)  # plain JSON all the way down
