"""The task engine, free of pytest: run one task end to end (boot, set up, drive the agent, evaluate, record), the
agent loop and who is to blame, the quality gate's near-miss states and GUI check. `plugin/` is the pytest glue
around it; a Ray node (issue 41) or any other caller can run it where pytest is not."""
