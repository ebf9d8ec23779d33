"""Benchmarks of the harness itself: devices' latencies (`devices.py`, `jarvis bench devices`), tasks one machine
carries when the wait is for a model (`throughput.py`, `jarvis bench throughput`), one device container measured
straight from its image (`probe.py`)."""
