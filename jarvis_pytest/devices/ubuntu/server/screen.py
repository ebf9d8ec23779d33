"""Screen capture: the root window (MIT-SHM, else Pillow's XCB grab), the real cursor drawn on it, PNG out.

The cursor is the X server's current cursor image (XFixes), so an agent sees an I-beam over text and a hand over
links, drawn at the pointer. The PNG is written by the devices' shared encoder (`devices/png.py`), not by Pillow,
from the X server's own pixels: only the bands of rows that changed since the last screenshot are converted and
compressed. Server CPU per 1920×1080 screenshot: about 27 ms for a whole new screen, 8 ms after a click, 3.5 ms
for an unchanged one (one encoding of a whole frame cost 23 ms before, every time; Pillow's PNG writer at level
1 about twice that).
"""

from __future__ import annotations

import struct
import threading
from typing import Any, Callable

from PIL import Image, ImageGrab, ImageStat
from Xlib import X, display
from Xlib.error import XError
from Xlib.ext import xfixes  # noqa: F401  (registers the XFixes requests on Display)

from jarvis_pytest.devices.png import PngEncoder

# Keep freed image memory for the next grab: `grab()` and `painted()` build 6-8 MB images, and fresh memory costs
# about 14 ms of page faults each time.
Image.core.set_blocks_max(4)


def cursor_image(reply) -> Image.Image:
    """An XFixes GetCursorImage reply (premultiplied ARGB words) as an RGBA image."""
    argb = struct.pack(f"<{len(reply.cursor_image)}I", *reply.cursor_image)
    return Image.frombytes("RGBA", (reply.width, reply.height), argb, "raw", "BGRa")


def bgrx_to_rgb(pixels: bytes, width: int, rows: int, stride: int) -> bytes:
    """Packed RGB of BGRX rows (Pillow's C unpacker: 4x faster than the shared encoder's own slicing)."""
    return Image.frombuffer("RGB", (width, rows), bytes(pixels), "raw", "BGRX", stride, 1).tobytes()


def draw_on_bgrx(pixels: bytearray, width: int, height: int, stride: int, image: Image.Image, x: int, y: int) -> None:
    """Draw the RGBA `image` with its top-left corner at (x, y), clipped to the screen, into BGRX `pixels` (rows of
    `stride` bytes); only the rows and columns under the image are touched."""
    left, top = max(x, 0), max(y, 0)
    right, bottom = min(x + image.width, width), min(y + image.height, height)
    if left >= right or top >= bottom:
        return
    row = (right - left) * 4
    spans = [slice(r * stride + left * 4, r * stride + left * 4 + row) for r in range(top, bottom)]
    under = Image.frombytes("RGB", (right - left, bottom - top), b"".join(pixels[s] for s in spans), "raw", "BGRX")
    part = image.crop((left - x, top - y, right - x, bottom - y))
    under.paste(part, (0, 0), part)
    drawn = under.tobytes("raw", "BGRX")
    for i, s in enumerate(spans):
        pixels[s] = drawn[i * row:(i + 1) * row]


class Screen:
    """Screenshots of the X display (thread-safe)."""

    def __init__(self, name: str | None = None):
        self.name = name
        self.display = display.Display(name)
        self.root = self.display.screen().root
        self.display.xfixes_query_version()  # XFixes answers nothing before the version is negotiated
        self.lock = threading.Lock()
        self._cursor: tuple[int, Image.Image] | None = None  # (serial, image)
        try:
            from jarvis_pytest.devices.ubuntu.server.xshm import ShmGrabber

            self._shm: ShmGrabber | None = ShmGrabber(name)
        except OSError:
            self._shm = None  # e.g. an X server in another IPC namespace: the socket path still works
        self._encoder = PngEncoder(layout="BGRX", to_rgb=bgrx_to_rgb) if self._shm else PngEncoder()

    def size(self) -> tuple[int, int]:
        with self.lock:
            geom = self.root.get_geometry()
        return geom.width, geom.height

    def _raw(self) -> Image.Image:
        return self._shm.grab() if self._shm else ImageGrab.grab(xdisplay=self.name or "")

    def _pointer(self) -> tuple[int, int, Image.Image]:
        """Where the cursor image goes (top-left corner) and the image."""
        with self.lock:
            reply = self.display.xfixes_get_cursor_image(self.root)
            if self._cursor is None or self._cursor[0] != reply.cursor_serial:
                self._cursor = (reply.cursor_serial, cursor_image(reply))
            return reply.x - reply.xhot, reply.y - reply.yhot, self._cursor[1]

    def grab(self) -> Image.Image:
        """The screen with the cursor drawn where it is."""
        img = self._raw()
        x, y, cursor = self._pointer()
        img.paste(cursor, (x, y), cursor)
        return img

    def _viewable_clients(self, describe: Callable[[Any], Any]) -> dict[int, Any]:
        """`describe(window)` of every viewable window the window manager manages (EWMH `_NET_CLIENT_LIST`), by
        id; windows that went away meanwhile, or that `describe` gives None for, are left out."""
        found: dict[int, Any] = {}
        with self.lock:
            prop = self.root.get_full_property(self.display.intern_atom("_NET_CLIENT_LIST"), X.AnyPropertyType)
            for wid in prop.value if prop else ():
                window = self.display.create_resource_object("window", wid)
                try:
                    if window.get_attributes().map_state == X.IsViewable:
                        value = describe(window)
                        if value is not None:
                            found[wid] = value
                except XError:
                    continue
        return found

    def managed_classes(self) -> set[str]:
        """The WM classes of the viewable managed windows."""
        return set(self._viewable_clients(lambda w: (w.get_wm_class() or (None,))[0]).values())

    def app_windows(self) -> dict[int, str]:
        """The viewable application windows, id → title; splash screens, docks and the desktop do not count."""
        atom = self.display.intern_atom
        skip = {atom(f"_NET_WM_WINDOW_TYPE_{t}") for t in ("SPLASH", "DOCK", "DESKTOP")}

        def title(window) -> str | None:
            kind = window.get_full_property(atom("_NET_WM_WINDOW_TYPE"), X.AnyPropertyType)
            if kind and skip.intersection(kind.value):
                return None
            name = window.get_full_property(atom("_NET_WM_NAME"), atom("UTF8_STRING"))
            text = name.value if name else window.get_wm_name()
            return text.decode("utf-8", "replace") if isinstance(text, bytes) else str(text or "")

        return self._viewable_clients(title)

    def windows(self) -> list[dict[str, Any]]:
        """The viewable managed windows: id, title, WM class, box [x, y, w, h] on the screen, focused."""
        atom = self.display.intern_atom
        with self.lock:
            active = self.root.get_full_property(atom("_NET_ACTIVE_WINDOW"), X.AnyPropertyType)
        focused = active.value[0] if active and len(active.value) else None

        def describe(window) -> dict[str, Any]:
            name = window.get_full_property(atom("_NET_WM_NAME"), atom("UTF8_STRING"))
            text = name.value if name else window.get_wm_name()
            geo = window.get_geometry()
            pos = window.translate_coords(self.root, 0, 0)
            return {"id": window.id, "title": text.decode("utf-8", "replace") if isinstance(text, bytes) else
                    str(text or ""), "class": (window.get_wm_class() or ("", ""))[-1] or "",
                    "box": [-pos.x, -pos.y, geo.width, geo.height], "focused": window.id == focused}

        return sorted(self._viewable_clients(describe).values(), key=lambda w: w["id"])

    def focus(self, title: str) -> bool:
        """Activate (EWMH `_NET_ACTIVE_WINDOW`, as a pager does) the application window whose title shows `title`
        (`control_http.title_matches`); False when none shows."""
        from jarvis_pytest.devices.control_http import title_matches

        for wid, text in sorted(self.app_windows().items()):
            if title_matches(title, text):
                from Xlib.protocol import event

                with self.lock:
                    window = self.display.create_resource_object("window", wid)
                    atom = self.display.intern_atom("_NET_ACTIVE_WINDOW")
                    ev = event.ClientMessage(window=window, client_type=atom, data=(32, [2, X.CurrentTime, 0, 0, 0]))
                    self.root.send_event(ev, event_mask=X.SubstructureRedirectMask | X.SubstructureNotifyMask)
                    self.display.flush()
                return True
        return False

    def painted(self, min_stddev: float = 8.0) -> bool:
        """Whether the screen shows something (a desktop that is up but not yet drawn is one flat colour)."""
        small = self._raw().reduce(8).convert("L")
        return ImageStat.Stat(small).stddev[0] >= min_stddev

    def png(self) -> bytes:
        """The screen with the cursor as PNG. With MIT-SHM the X server's own pixels go to the encoder as they are
        (no image built: only the bands that changed are converted), the cursor drawn into them."""
        if self._shm is None:
            img = self.grab()  # RGB from either grab: converted only if not, as a copy costs 6-8 MB
            return self._encoder.encode((img if img.mode == "RGB" else img.convert("RGB")).tobytes(), *img.size)
        shm = self._shm
        pixels = shm.grab_bgrx()
        x, y, cursor = self._pointer()
        draw_on_bgrx(pixels, shm.width, shm.height, shm.stride, cursor, x, y)
        return self._encoder.encode(pixels, shm.width, shm.height, shm.stride)
