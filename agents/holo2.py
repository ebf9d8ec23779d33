"""Holo2 (H Company) as grounding model (paper, grounding-prompt table "HOLO2").

Prompt: "Localize an element on the GUI image ..." with the JSON schema of ``ClickCoordinates`` (x and y,
integers normalized between 0 and 1000), followed by the target. Request: structured output with that schema
(``response_format`` json_schema, honoured by vLLM) and thinking off (``chat_template_kwargs: {"thinking":
false}``), as H Company's model card does for localization. Answer: ``{"x": int, "y": int}``, relative 0-1000
(x_screen = x / 1000 * width); the screenshot is sent as is.
"""

from __future__ import annotations

from pydantic import BaseModel, Field

from jarvis_pytest.agents.grounding import Grounder
from jarvis_pytest.llm.client import text_part


class ClickCoordinates(BaseModel):
    x: int = Field(ge=0, le=1000, description="The x coordinate, normalized between 0 and 1000.")
    y: int = Field(ge=0, le=1000, description="The y coordinate, normalized between 0 and 1000.")


SCHEMA = ClickCoordinates.model_json_schema()
# The model card renders the schema with Python's str() of the dict; keep that exact text.
PROMPT = ("Localize an element on the GUI image according to the provided target and output a click position.\n"
          f"     * You must output a valid JSON following the format: {SCHEMA}\n"
          "     Your target is:")


class Holo2Grounder(Grounder):
    name = "holo2"
    default_model = "Hcompany/Holo2-30B-A3B"
    scale = 1000.0
    params = {"temperature": 0.0, "max_tokens": 64,
              "response_format": {"type": "json_schema",
                                  "json_schema": {"name": "ClickCoordinates", "schema": SCHEMA}},
              "chat_template_kwargs": {"thinking": False}}

    def messages(self, instruction, image, size, platform):
        return [{"role": "user", "content": [image, text_part(f"{PROMPT}\n{instruction}")]}]


GROUNDERS = {"holo2": Holo2Grounder}
