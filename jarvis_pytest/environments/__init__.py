"""A task's environment (its devices, drive and network: `lifecycle.py`) and each worker's pool of them, booted
ahead (`pool.py`): above `devices/` (which it boots through their backends) and `infra/` (containers, networks,
engines)."""
