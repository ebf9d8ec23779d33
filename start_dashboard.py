#!/usr/bin/env python3
"""Start the evaluation dashboard: `python start_dashboard.py [--port 8000] [--results reports/]`,
then open http://localhost:8000/viewer.html (same as `jarvis dashboard`)."""

import sys

from jarvis_pytest.dashboard.commands import main

if __name__ == "__main__":
    sys.exit(main())
