"""The Windows platform: the Windows-native control server (`server/`, run inside the device on the embeddable
Windows CPython), the backends (`backend.py`: `wine`, the offline stand-in, and `kvm`, a real Windows VM whose
preparation is in `real.py`)."""
