"""A user agent loaded as `slow_agent:SlowAgent` (module:Class): it never answers within a short step timeout."""

import time

from jarvis_pytest.agents.protocol import AgentStep
from jarvis_pytest.devices.actions import Done


class SlowAgent:
    name = "slow"

    def __init__(self, options=None):
        self.seconds = float((options or {}).get("seconds", 30))

    def reset(self, task):
        pass

    def act(self, observations, history):
        time.sleep(self.seconds)
        return AgentStep(platform=None, action=Done())

    def config(self):
        return {"name": self.name, "seconds": self.seconds}
