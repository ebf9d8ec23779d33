"""UI-TARS-1.5 as grounding model (paper, grounding-prompt table "UI-Tars-1.5").

Prompt: the UI-TARS grounding prompt (``Action: ...`` with the single action ``click(point='<point>x1 y1</point>')``;
the stray quote is in the official prompt) and the instruction. Answer: ``Action: click(point='<point>x y</point>')``;
older forms ``start_box='(x,y)'``, ``<|box_start|>(x,y)<|box_end|>`` and ``<bbox>x1 y1 x2 y2</bbox>`` are
accepted. Coordinates are absolute pixels of the image the model saw, which is the screenshot resized by
smart_resize(factor 28, min 100*28*28, max 16384*28*28); the client sends it already resized
(x_screen = x * width / resized_width).
"""

from __future__ import annotations

from jarvis_pytest.agents.grounding import Grounder, Resize
from jarvis_pytest.llm.client import text_part

PROMPT = ("You are a GUI agent. You are given a task and your action history, with screenshots. You need to perform "
          "the next action to complete the task. \n\n## Output Format\n\nAction: ...\n\n\n## Action Space\n"
          "click(point='<point>x1 y1</point>'')\n\n## User Instruction \n {instruction}")


class UITarsGrounder(Grounder):
    name = "ui-tars-1.5"
    default_model = "ByteDance-Seed/UI-TARS-1.5-7B"
    scale = None
    resize = Resize(factor=28, min_pixels=100 * 28 * 28, max_pixels=16384 * 28 * 28)
    params = {"temperature": 0.0, "max_tokens": 128}
    answer_marker = "Action:"

    def messages(self, instruction, image, size, platform):
        return [{"role": "user", "content": [text_part(PROMPT.format(instruction=instruction)), image]}]


GROUNDERS = {"ui-tars-1.5": UITarsGrounder}
