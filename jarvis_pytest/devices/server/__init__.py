"""The control server that runs inside a desktop device: one long-lived process, no interpreter per action.

It runs as the desktop user inside the X session (python3 from Debian, python-xlib, Pillow, pydantic from
wheels) and exposes health, screenshot, accessibility tree, actions, files, commands and application launch
over HTTP on the container's control port. Modules: `screen` (capture), `xinput` (XTest actions), `a11y`
(AT-SPI tree), `system` (commands, files, launch, health), `app` (HTTP routing).
"""
