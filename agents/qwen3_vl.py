"""Qwen3-VL as grounding model (paper, grounding-prompt table "Qwen3VL").

Prompt: the Qwen function-calling system prompt with a ``computer_use`` tool whose screen is 1000x1000 and whose
only action is ``left_click``. Answer: ``<tool_call>{"name": "computer_use", "arguments": {"action":
"left_click", "coordinate": [x, y]}}</tool_call>``. Coordinates are relative, 0-1000 on both axes
(x_screen = x / 1000 * width), so the screenshot is sent as is.
"""

from __future__ import annotations

from jarvis_pytest.agents.grounding import Grounder, click_tool, function_call_prompt
from jarvis_pytest.llm.client import text_part

TOOL = click_tool(
    "computer_use",
    "Use a mouse to interact with a computer.\n* The screen's resolution is 1000x1000.\n* Make sure to click any "
    "buttons, links, icons, etc with the cursor tip in the center of the element.\n* You can only use the "
    "left_click action to interact with the computer.",
    "The action to perform. The available actions are:\n* `left_click`: Click the left mouse button with "
    "coordinate (x, y).",
    "(x, y): The x (pixels from the left edge) and y (pixels from the top edge) coordinates to move the mouse to. "
    "Required only by `action=left_click`.",
    "left_click", ("action",))

SYSTEM_PROMPT = function_call_prompt(
    "You are a helpful assistant. The user will give you an instruction, and you MUST left click on the "
    "corresponding UI element via tool call. If you are not sure about where to click, guess a most likely one.",
    TOOL)


class Qwen3VLGrounder(Grounder):
    name = "qwen3-vl"
    default_model = "Qwen/Qwen3-VL-30B-A3B-Instruct"
    scale = 1000.0
    params = {"temperature": 0.0, "max_tokens": 256}
    answer_tags = ("tool_call",)

    def messages(self, instruction, image, size, platform):
        return [{"role": "system", "content": SYSTEM_PROMPT},
                {"role": "user", "content": [image, text_part(instruction)]}]


GROUNDERS = {"qwen3-vl": Qwen3VLGrounder}
