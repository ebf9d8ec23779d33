"""Model interaction: the agent protocol, the built-in agents, the OpenAI-compatible client."""
