"""A user agent loaded as `trial_agent:SometimesAgent`: it solves "Create the file PATH." through the GUI in the
trials named by the option `wins` (e.g. `2` or `1,3`) and gives up at once (FAIL) in the others. It clicks into the
terminal that set-up opened at +100+100, types `touch` and `exit`, then says DONE. Each step's reasoning names the
trial and the seed the harness gave it."""

import re

from jarvis_pytest.agents.protocol import AgentStep
from jarvis_pytest.devices.actions import Click, Done, Fail, Typing, Wait


class SometimesAgent:
    name = "sometimes"

    def __init__(self, options=None):
        self.wins = sorted(int(n) for n in str((options or {}).get("wins", "")).split(",") if n.strip())
        self.plan = []
        self.note = ""

    def reset(self, task):
        self.note = f"trial {task.trial}, seed {task.seed}"
        found = re.search(r"Create the file (\S+)\.", task.instruction)
        if task.trial not in self.wins or found is None:
            self.plan = [(None, Fail())]
            return
        self.plan = [("ubuntu", Click(x=400, y=250)), ("ubuntu", Typing(text=f"touch '{found.group(1)}' && exit\n")),
                     ("ubuntu", Wait(seconds=1.0)), (None, Done())]

    def act(self, observations, history):
        platform, action = self.plan.pop(0) if self.plan else (None, Done())
        return AgentStep(platform=platform, action=action, reasoning=self.note)

    def config(self):
        return {"name": self.name, "wins": self.wins}
