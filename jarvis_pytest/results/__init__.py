"""Per-task results on disk: the trajectory (`traj.jsonl`), screenshots and `result.json` (schema in `model`)."""
