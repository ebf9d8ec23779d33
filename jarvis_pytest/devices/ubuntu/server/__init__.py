"""The control server that runs inside a desktop device: one long-lived process, no interpreter per action.

It runs as the desktop user inside the X session (python3, python-xlib, Pillow and PyGObject from Debian; no
pydantic: the JSON shapes of `devices/protocol.py`, validated by `devices/validate.py`) and exposes health,
screenshot, accessibility tree, actions, files, commands and application launch over HTTP on the container's
control port (the plumbing and the action dispatch every platform's server shares are `devices/control_http.py`;
PYAUTOGUI scripts `devices/pyautogui_compat.py`). Modules: `app` (routes and endpoints), `screen` (capture with
the cursor, PNG), `xshm` (MIT-SHM grabs), `xinput` (XTest input, exact Unicode typing), `a11y` (AT-SPI tree),
`system` (commands, files, launch, readiness).

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
  POST /open      OpenRequest                        LaunchResponse; the file's default application (xdg-open)
  GET  /exists?path=/abs                             PathInfo
  GET  /windows                                      WindowList (id, title, class, box, focused)
  GET  /clipboard, PUT /clipboard   ClipboardText    the CLIPBOARD selection (xclip)
"""
