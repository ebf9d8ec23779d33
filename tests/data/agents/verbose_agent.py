"""A user agent loaded as `verbose_agent:VerboseAgent` (module:Class): it gives up at once (FAIL), with a model
answer of `chars` characters (option, default 1,000,000) as its raw output."""

from jarvis_pytest.agents.protocol import AgentStep
from jarvis_pytest.devices.actions import Fail


class VerboseAgent:
    name = "verbose"

    def __init__(self, options=None):
        self.chars = int((options or {}).get("chars", 1_000_000))

    def reset(self, task):
        pass

    def act(self, observations, history):
        return AgentStep(platform=None, action=Fail(), reasoning="giving up", raw_output="y" * self.chars)

    def config(self):
        return {"name": self.name, "chars": self.chars}
