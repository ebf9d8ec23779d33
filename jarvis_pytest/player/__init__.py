"""The browser player: a person plays a task in the browser as the agent `human` (`jarvis play <task>`).

`agent.HumanAgent` is an agent like any other: the harness's step loop calls its `act()`, which shows the step's
screens in the page (`server.py`, `static/player.*`, bound to 127.0.0.1) and waits for the person's next input; the
input becomes one action of the unified action space (`inputs.py`: displayed points mapped to device pixels, keys
to HOTKEY, text to TYPING, the wheel to SCROLL). So a played run has the runner's set-up, evaluation, results and
`traj.jsonl` of any agent's run, `--agent replay` reproduces it, and `solution.py` saves it as a template's
`gui_solution`.
"""
