"""`python3 -m jarvis_pytest.devices.ubuntu.server --port 5000`"""

import argparse

from jarvis_pytest.devices.ubuntu.server.app import serve

parser = argparse.ArgumentParser(prog="jarvis-control-server")
parser.add_argument("--host", default="0.0.0.0", help="inside the container; Docker publishes it on 127.0.0.1 only")
parser.add_argument("--port", type=int, default=5000)
parser.add_argument("--platform", default="ubuntu", help="the device's platform, named in refusals")
args = parser.parse_args()
serve(args.host, args.port, args.platform)
