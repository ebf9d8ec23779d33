"""Grab the X root window through MIT-SHM (libX11/libXext via ctypes): the pixels arrive in shared memory instead
of through the X socket, about 7 ms for 1920×1080 against about 20 ms for a plain GetImage.

Only usable when the X server shares the IPC namespace with this process (it does inside a device container).
"""

from __future__ import annotations

import ctypes
import threading

from PIL import Image

_ZPIXMAP = 2
_IPC_CREAT = 0o1000
_IPC_RMID = 0
_ALL_PLANES = 0xFFFFFFFF


class _XImage(ctypes.Structure):  # the leading fields of Xlib's XImage
    _fields_ = [("width", ctypes.c_int), ("height", ctypes.c_int), ("xoffset", ctypes.c_int),
                ("format", ctypes.c_int), ("data", ctypes.c_void_p), ("byte_order", ctypes.c_int),
                ("bitmap_unit", ctypes.c_int), ("bitmap_bit_order", ctypes.c_int), ("bitmap_pad", ctypes.c_int),
                ("depth", ctypes.c_int), ("bytes_per_line", ctypes.c_int), ("bits_per_pixel", ctypes.c_int),
                ("red_mask", ctypes.c_ulong), ("green_mask", ctypes.c_ulong), ("blue_mask", ctypes.c_ulong)]


class _ShmInfo(ctypes.Structure):  # XShmSegmentInfo
    _fields_ = [("shmseg", ctypes.c_ulong), ("shmid", ctypes.c_int), ("shmaddr", ctypes.c_void_p),
                ("readOnly", ctypes.c_int)]


def _libs():
    x11 = ctypes.CDLL("libX11.so.6")
    xext = ctypes.CDLL("libXext.so.6")
    libc = ctypes.CDLL("libc.so.6", use_errno=True)
    vp, ul, i = ctypes.c_void_p, ctypes.c_ulong, ctypes.c_int
    for fn, res, args in (
        (x11.XInitThreads, i, []),
        (x11.XOpenDisplay, vp, [ctypes.c_char_p]),
        (x11.XDefaultScreen, i, [vp]),
        (x11.XRootWindow, ul, [vp, i]),
        (x11.XDefaultVisual, vp, [vp, i]),
        (x11.XDefaultDepth, i, [vp, i]),
        (x11.XDisplayWidth, i, [vp, i]),
        (x11.XDisplayHeight, i, [vp, i]),
        (x11.XSync, i, [vp, i]),
        (xext.XShmQueryExtension, i, [vp]),
        (xext.XShmCreateImage, ctypes.POINTER(_XImage),
         [vp, vp, ctypes.c_uint, i, ctypes.c_char_p, ctypes.POINTER(_ShmInfo), ctypes.c_uint, ctypes.c_uint]),
        (xext.XShmAttach, i, [vp, ctypes.POINTER(_ShmInfo)]),
        (xext.XShmGetImage, i, [vp, ul, ctypes.POINTER(_XImage), i, i, ul]),
        (libc.shmget, i, [i, ctypes.c_size_t, i]),
        (libc.shmat, vp, [i, vp, i]),
        (libc.shmctl, i, [i, i, vp]),
    ):
        fn.restype, fn.argtypes = res, args
    return x11, xext, libc


class ShmGrabber:
    """Whole-screen grabs into one shared-memory image (thread-safe). Raises OSError when MIT-SHM is unusable."""

    def __init__(self, name: str | None = None):
        x11, xext, libc = self._x11, self._xext, self._libc = _libs()
        x11.XInitThreads()
        self.dpy = x11.XOpenDisplay(name.encode() if name else None)
        if not self.dpy:
            raise OSError(f"cannot open X display {name or ':0 ($DISPLAY)'}")
        if not xext.XShmQueryExtension(self.dpy):
            raise OSError("the X server has no MIT-SHM extension")
        scr = x11.XDefaultScreen(self.dpy)
        self.root = x11.XRootWindow(self.dpy, scr)
        self.width, self.height = x11.XDisplayWidth(self.dpy, scr), x11.XDisplayHeight(self.dpy, scr)
        self.info = _ShmInfo()
        self.image = xext.XShmCreateImage(self.dpy, x11.XDefaultVisual(self.dpy, scr), x11.XDefaultDepth(self.dpy, scr),
                                          _ZPIXMAP, None, ctypes.byref(self.info), self.width, self.height)
        img = self.image.contents
        if img.bits_per_pixel != 32 or img.red_mask != 0xFF0000 or img.byte_order != 0:
            raise OSError(f"unsupported X visual ({img.bits_per_pixel} bpp, red mask {img.red_mask:#x})")
        self.stride, self.size = img.bytes_per_line, img.bytes_per_line * img.height
        # The X server (root) attaches the segment on behalf of the desktop user: the mode must let it.
        self.info.shmid = libc.shmget(0, self.size, _IPC_CREAT | 0o666)
        if self.info.shmid < 0:
            raise OSError(ctypes.get_errno(), "shmget failed")
        self.info.shmaddr = img.data = libc.shmat(self.info.shmid, None, 0)
        attached = xext.XShmAttach(self.dpy, ctypes.byref(self.info))
        x11.XSync(self.dpy, 0)
        libc.shmctl(self.info.shmid, _IPC_RMID, None)  # freed by the kernel when both sides detach
        if not attached:
            raise OSError("XShmAttach failed")
        self.buffer = (ctypes.c_char * self.size).from_address(self.info.shmaddr)
        self.lock = threading.Lock()

    def _get(self) -> None:
        if not self._xext.XShmGetImage(self.dpy, self.root, self.image, 0, 0, _ALL_PLANES):
            raise OSError("XShmGetImage failed")

    def grab(self) -> Image.Image:
        """The whole screen as an RGB image (a copy, safe to draw on)."""
        with self.lock:
            self._get()
            return Image.frombytes("RGB", (self.width, self.height), self.buffer, "raw", "BGRX", self.stride, 1)

    def grab_bgrx(self) -> bytearray:
        """The whole screen as the X server lays it out, 4 bytes a pixel (B, G, R, unused), rows of `stride`
        bytes (a copy, safe to draw on)."""
        with self.lock:
            self._get()
            return bytearray(self.buffer)
