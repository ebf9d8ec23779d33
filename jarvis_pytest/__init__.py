"""jarvis-pytest: a pytest-native benchmark for cross-device GUI agents (after the JarvisGUI paper)."""

__version__ = "0.1.0"
