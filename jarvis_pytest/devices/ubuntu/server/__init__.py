"""The control server that runs inside a desktop device: one long-lived process, no interpreter per action.

It runs as the desktop user inside the X session (python3 from Debian, python-xlib, Pillow, pydantic from
wheels) and exposes health, screenshot, accessibility tree, actions, files, commands and application launch
over HTTP on the container's control port. Modules: `app` (HTTP routing, one action per request), `screen`
(capture with the cursor, PNG), `xshm` (MIT-SHM grabs), `xinput` (XTest input, exact Unicode typing),
`pyautogui_compat` (PYAUTOGUI scripts), `a11y` (AT-SPI tree), `system` (commands, files, launch, readiness).

Endpoints (JSON unless said; errors are 4xx/5xx `{"error": "..."}`):
  GET  /health                     Health: `desktop` true once the desktop is shown and drawn
  GET  /screen_size                ScreenSize
  GET  /screenshot                 image/png of the whole screen, cursor drawn
  GET  /a11y?max_nodes=&max_depth=&timeout=&all=   A11yTree
  POST /action    an Action (see `actions.py`)      ActionResult; 400 for an action this device refuses
  PUT  /files?path=/abs   body = bytes               written as the desktop user (root through sudo)
  GET  /files?path=/abs                              application/octet-stream
  POST /run       RunRequest                         RunResponse (returncode 124 on timeout)
  POST /launch    LaunchRequest                      LaunchResponse; started detached in the session, with
                                                     `window_wait` answered once its window shows
"""
