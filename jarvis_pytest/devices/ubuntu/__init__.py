"""The Ubuntu platform: its control server (`server/`, runs inside the device image) and its backend
(`backend.py`, host side). Nothing is imported here: the device image carries only the server."""
