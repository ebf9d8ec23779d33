"""The Windows-native control server (standard library + ctypes against Win32); see app.py."""
