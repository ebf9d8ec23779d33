"""Runs inside the Ubuntu device: a full-screen window that logs the X input events it receives, one JSON
object per line, to the file named by argv[1]. Used to check the control server's actions by their effect."""

import json
import sys

from Xlib import X, XK, display

d = display.Display()
screen = d.screen()
# override-redirect: the window manager leaves it alone. A managed window gets xfwm4's click-to-focus button grab,
# which is synchronous: the pointer freezes on a press until xfwm4 replays it, and on a busy machine the X server
# then delivers the queued button events with the pointer's later position (seen: a double-click reported at the
# place of a move sent after it). This window checks the control server's input, not the window manager.
win = screen.root.create_window(0, 0, screen.width_in_pixels, screen.height_in_pixels, 0, screen.root_depth,
                                override_redirect=True,
                                event_mask=X.ButtonPressMask | X.ButtonReleaseMask | X.KeyPressMask
                                | X.KeyReleaseMask | X.PointerMotionMask | X.ExposureMask)
win.set_wm_name("jarvis-event-recorder")
win.map()
d.sync()
out = open(sys.argv[1], "a", buffering=1)
keysym_names = {v: k[3:] for k, v in vars(XK).items() if k.startswith("XK_") and isinstance(v, int)}
names = {X.ButtonPress: "press", X.ButtonRelease: "release", X.KeyPress: "key_down", X.KeyRelease: "key_up",
         X.MotionNotify: "motion"}
while True:
    e = d.next_event()
    if e.type == X.Expose:
        win.set_input_focus(X.RevertToParent, X.CurrentTime)
        d.sync()
        out.write(json.dumps({"type": "ready"}) + "\n")
    elif e.type in names:
        rec = {"type": names[e.type], "x": e.root_x, "y": e.root_y, "time": e.time}
        if e.type in (X.ButtonPress, X.ButtonRelease):
            rec["button"] = e.detail
        if e.type in (X.KeyPress, X.KeyRelease):
            sym = d.keycode_to_keysym(e.detail, 0)
            rec["key"] = keysym_names.get(sym, hex(sym))
        out.write(json.dumps(rec) + "\n")
