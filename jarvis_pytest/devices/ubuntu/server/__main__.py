"""`python3 -m jarvis_pytest.devices.ubuntu.server --port 5000`, or `--run-script` (a PYAUTOGUI script from
standard input, run by the server in a child process: `pyautogui_compat.run_isolated`)."""

import argparse

from jarvis_pytest.devices.ubuntu.server.app import run_script_here, serve

parser = argparse.ArgumentParser(prog="jarvis-control-server")
parser.add_argument("--host", default="0.0.0.0", help="inside the container; Docker publishes it on 127.0.0.1 only")
parser.add_argument("--port", type=int, default=5000)
parser.add_argument("--platform", default="ubuntu", help="the device's platform, named in refusals")
parser.add_argument("--run-script", action="store_true", help="run one PYAUTOGUI script from standard input")
args = parser.parse_args()
if args.run_script:
    from jarvis_pytest.devices.pyautogui_compat import child_main

    child_main(run_script_here)
serve(args.host, args.port, args.platform)
