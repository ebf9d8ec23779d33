"""MAI-UI (Tongyi) as grounding model (paper, grounding-prompt table "MAI-UI").

Prompt: the MAI-UI grounding system prompt (reason in <grounding_think>, answer in <answer>). Answer:
``<grounding_think>...</grounding_think><answer>{"coordinate": [x, y]}</answer>``. Coordinates are relative on a
0-999 scale (MAI-UI's SCALE_FACTOR = 999: x_screen = x / 999 * width); the screenshot is sent as is.
"""

from __future__ import annotations

from jarvis_pytest.agents.grounding import Grounder
from jarvis_pytest.llm.client import text_part

SYSTEM_PROMPT = (
    "You are a GUI grounding agent. \n## Task\nGiven a screenshot and the user's grounding instruction. Your task is "
    "to accurately locate a UI element based on the user's instructions.\nFirst, you should carefully examine the "
    "screenshot and analyze the user's instructions,  translate the user's instruction into a effective reasoning "
    "process, and then provide the final coordinate.\n## Output Format\nReturn a json object with a reasoning "
    "process in <grounding_think></grounding_think> tags, a [x,y] format coordinate within <answer></answer> XML "
    "tags:\n<grounding_think>...</grounding_think>\n<answer>\n{\"coordinate\": [x,y]}\n</answer>")


class MAIUIGrounder(Grounder):
    name = "mai-ui"
    default_model = "Tongyi-MAI/MAI-UI-8B"
    scale = 999.0
    params = {"temperature": 0.0, "max_tokens": 1024}
    answer_tags = ("answer",)

    def messages(self, instruction, image, size, platform):
        return [{"role": "system", "content": SYSTEM_PROMPT},
                {"role": "user", "content": [text_part(instruction), image]}]


GROUNDERS = {"mai-ui": MAIUIGrounder}
