"""Root conftest: the jarvis plugin is loaded through its pytest11 entry point; nothing else lives here."""
