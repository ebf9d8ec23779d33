"""The planner–grounder agent (paper, appendix "Planner Model"): a planner model decides each step from every
platform's screenshot, a grounding model finds its element on the chosen platform.

- :mod:`.prompt`: the planner's prompt (template, transfer server text, history).
- :mod:`.tools`: the planner's answer (``<step>`` format, parsing) and its tool call mapped to the action space.
- :mod:`.agent`: :class:`PlannerGrounderAgent` and :func:`build_planner_grounder`, its construction from options.
"""

from jarvis_pytest.agents.planner.agent import PlannerGrounderAgent, build_planner_grounder, redact
from jarvis_pytest.agents.planner.prompt import render_history, render_prompt, render_transfer
from jarvis_pytest.agents.planner.tools import (PlannerOutputError, PlannerStep, map_action, parse_planner_output,
                                                render_step)

__all__ = ["PlannerGrounderAgent", "PlannerOutputError", "PlannerStep", "build_planner_grounder", "map_action",
           "parse_planner_output", "redact", "render_history", "render_prompt", "render_step", "render_transfer"]
