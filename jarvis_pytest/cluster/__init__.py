"""Running a run's task environments on the nodes of a Ray cluster (`--ray ADDRESS`): the agent loop stays in the
pytest workers on the head; each task's devices, drive and network are made on a node Ray's scheduler picks from
the resources the node declares, and everything done to them goes through an actor on that node. Ray is imported
only here, and only with `--ray`."""
