"""GUI-Owl (Mobile-Agent-v3) as grounding model (paper, grounding-prompt tables "GUI-OWL for mobile/desktop").

Prompt: the Qwen function-calling system prompt with a ``mobile_use`` tool (Android) or a ``computer_use`` tool
(Windows, Ubuntu) whose only action is ``click`` and which states the screen resolution. Answer:
``<tool_call>{"name": ..., "arguments": {"action": "click", "coordinate": [x, y]}}</tool_call>``, possibly between
<thinking> and <conclusion> blocks. Coordinates are absolute pixels of the image the model saw: the screenshot
resized by smart_resize(factor 28, min 3136, max 10 035 200) as GUI-Owl's own agent code does; the resolution in
the prompt is that resized size, and the client sends the image already resized
(x_screen = x * width / resized_width).
"""

from __future__ import annotations

from jarvis_pytest.agents.grounding import Grounder, Resize, click_tool, function_call_prompt
from jarvis_pytest.llm.client import text_part

_CLICK_DOC = "(x, y): The x (pixels from the left edge) and y (pixels from the top edge) coordinates to click."
_GUIDE = ("* Make sure to click any buttons, links, icons, etc with the cursor tip in the center of the element.\n"
          "* Don't click boxes on their edges unless asked.")


def system_prompt(platform: str, width: int, height: int) -> str:
    """The mobile prompt for Android, the desktop prompt otherwise, for a `width`x`height` image."""
    if platform == "android":
        tool = click_tool(
            "mobile_use",
            "Use a touchscreen to interact with a mobile device.\n* This is an interface to a mobile device with "
            f"touchscreen.\n* The screen's resolution is {width}x{height}.\n{_GUIDE}",
            "The action to perform. The available actions are:\n* `click`: Click the point on the screen with "
            "coordinate (x, y).", _CLICK_DOC, "click", ("action", "coordinate"))
    else:
        tool = click_tool(
            "computer_use",
            "Use a mouse to interact with a computer.\n* This is an interface to a desktop GUI.\n* The screen's "
            f"resolution is {width}x{height}.\n{_GUIDE}",
            "The action to perform. The available actions are:\n* `click`: Click the left mouse button at a "
            "specified (x, y) pixel coordinate on the screen.", _CLICK_DOC, "click", ("action", "coordinate"))
    return function_call_prompt("You are a helpful assistant.", tool)


class GUIOwlGrounder(Grounder):
    name = "gui-owl"
    default_model = "mPLUG/GUI-Owl-32B"
    scale = None
    resize = Resize(factor=28, min_pixels=3136, max_pixels=10_035_200)
    params = {"temperature": 0.0, "max_tokens": 512}
    answer_tags = ("tool_call",)
    think_tags = Grounder.think_tags + ("conclusion",)

    def messages(self, instruction, image, size, platform):
        return [{"role": "system", "content": system_prompt(platform, *size)},
                {"role": "user", "content": [text_part(instruction), image]}]


GROUNDERS = {"gui-owl": GUIOwlGrounder}
