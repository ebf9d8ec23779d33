"""Runs inside the Ubuntu device: a full-screen window that logs the X input events it receives, one JSON
object per line, to the file named by argv[1]. Used to check the control server's actions by their effect."""

import json
import sys

from Xlib import X, XK, display

d = display.Display()
screen = d.screen()
win = screen.root.create_window(0, 0, screen.width_in_pixels, screen.height_in_pixels, 0, screen.root_depth,
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
