"""`python.exe -m jarvis_pytest.devices.windows.server --port 5000` (inside the device, from `C:\\jarvis`), or
`--wait-desktop SECONDS`, or `--run-script` (a PYAUTOGUI script from standard input, in the server's child)."""

import sys

sys.modules["_wmi"] = None  # platform.system() would crash through _wmi under Wine; plain WinAPI answers instead

import argparse

from . import win32

win32.SetProcessDPIAware()  # coordinates and screenshots in physical pixels

from .app import run_script_here, serve, wait_desktop

parser = argparse.ArgumentParser(prog="jarvis-control-server-windows")
parser.add_argument("--host", default="0.0.0.0", help="inside the device; Docker publishes it on 127.0.0.1 only")
parser.add_argument("--port", type=int, default=5000)
parser.add_argument("--wait-desktop", type=float, metavar="SECONDS",
                    help="only wait until the desktop is up (exit 0) or the time is over (exit 1)")
parser.add_argument("--run-script", action="store_true",
                    help="run one PYAUTOGUI script from standard input (the server's child for each script)")
args = parser.parse_args()
if args.run_script:
    from jarvis_pytest.devices.pyautogui_compat import child_main

    child_main(run_script_here)
if args.wait_desktop is not None:
    sys.exit(0 if wait_desktop(args.wait_desktop) else 1)
serve(args.host, args.port)
