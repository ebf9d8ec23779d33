"""The Android platform over ADB: the `adb` wrapper (`adb.py`), parsers of the device's own output
(`screencap.py`, `uiautomator.py`, `outputs.py`), the action → `input`/`am` command mapping (`commands.py`), the
drive upload/download commands a device runs itself (`http.py`), the `AdbDevice` (`device.py`) and its two
backends, `emulator` and `attach` (`backend.py`; the emulator image: `image.py`, `fixtures/images/android/`)."""
