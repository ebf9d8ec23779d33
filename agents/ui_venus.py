"""UI-Venus-Ground as grounding model (paper, grounding-prompt table "UI-Venus").

Prompt: "Outline the position corresponding to the instruction: {instruction}. The output should be only
[x1,y1,x2,y2]." Answer: a box ``[x1,y1,x2,y2]``; the point is its centre. Coordinates are absolute pixels of the
image the model saw: the screenshot resized by smart_resize(factor 28, min 2 000 000, max 4 800 000), as the
official evaluation sets min/max pixels; the client sends it already resized (x_screen = x * width / resized_width).
"""

from __future__ import annotations

from jarvis_pytest.agents.grounding import Grounder, Resize
from jarvis_pytest.llm.client import text_part

PROMPT = "Outline the position corresponding to the instruction: {instruction}. The output should be only [x1,y1,x2,y2]."


class UIVenusGrounder(Grounder):
    name = "ui-venus"
    default_model = "inclusionAI/UI-Venus-Ground-7B"
    scale = None
    resize = Resize(factor=28, min_pixels=2_000_000, max_pixels=4_800_000)
    params = {"temperature": 0.0, "max_tokens": 128}

    def messages(self, instruction, image, size, platform):
        return [{"role": "user", "content": [image, text_part(PROMPT.format(instruction=instruction))]}]


GROUNDERS = {"ui-venus": UIVenusGrounder}
