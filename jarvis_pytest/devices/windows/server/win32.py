"""ctypes bindings of the Win32 calls the server uses (user32, gdi32, kernel32, shell32), with their types.

Every function gets `argtypes`/`restype` so 64-bit handles and pointers pass intact. Nothing here runs a call;
importing this module needs Windows (or Wine).
"""

from __future__ import annotations

import ctypes
from ctypes import wintypes as W

user32 = ctypes.WinDLL("user32", use_last_error=True)
gdi32 = ctypes.WinDLL("gdi32", use_last_error=True)
kernel32 = ctypes.WinDLL("kernel32", use_last_error=True)
shell32 = ctypes.WinDLL("shell32", use_last_error=True)

LRESULT = ctypes.c_ssize_t
ULONG_PTR = ctypes.c_size_t


def _fn(dll, name: str, restype, *argtypes):
    f = getattr(dll, name)
    f.restype, f.argtypes = restype, list(argtypes)
    return f


# -- structures ------------------------------------------------------------------------------------------------
class MOUSEINPUT(ctypes.Structure):
    _fields_ = [("dx", W.LONG), ("dy", W.LONG), ("mouseData", W.DWORD), ("dwFlags", W.DWORD), ("time", W.DWORD),
                ("dwExtraInfo", ULONG_PTR)]


class KEYBDINPUT(ctypes.Structure):
    _fields_ = [("wVk", W.WORD), ("wScan", W.WORD), ("dwFlags", W.DWORD), ("time", W.DWORD),
                ("dwExtraInfo", ULONG_PTR)]


class HARDWAREINPUT(ctypes.Structure):
    _fields_ = [("uMsg", W.DWORD), ("wParamL", W.WORD), ("wParamH", W.WORD)]


class _INPUTUNION(ctypes.Union):
    _fields_ = [("mi", MOUSEINPUT), ("ki", KEYBDINPUT), ("hi", HARDWAREINPUT)]


class INPUT(ctypes.Structure):
    _anonymous_ = ("u",)
    _fields_ = [("type", W.DWORD), ("u", _INPUTUNION)]


class BITMAPINFOHEADER(ctypes.Structure):
    _fields_ = [("biSize", W.DWORD), ("biWidth", W.LONG), ("biHeight", W.LONG), ("biPlanes", W.WORD),
                ("biBitCount", W.WORD), ("biCompression", W.DWORD), ("biSizeImage", W.DWORD),
                ("biXPelsPerMeter", W.LONG), ("biYPelsPerMeter", W.LONG), ("biClrUsed", W.DWORD),
                ("biClrImportant", W.DWORD)]


class BITMAPINFO(ctypes.Structure):
    _fields_ = [("bmiHeader", BITMAPINFOHEADER), ("bmiColors", W.DWORD * 3)]


class CURSORINFO(ctypes.Structure):
    _fields_ = [("cbSize", W.DWORD), ("flags", W.DWORD), ("hCursor", W.HANDLE), ("ptScreenPos", W.POINT)]


class ICONINFO(ctypes.Structure):
    _fields_ = [("fIcon", W.BOOL), ("xHotspot", W.DWORD), ("yHotspot", W.DWORD), ("hbmMask", W.HBITMAP),
                ("hbmColor", W.HBITMAP)]


class GUITHREADINFO(ctypes.Structure):
    _fields_ = [("cbSize", W.DWORD), ("flags", W.DWORD), ("hwndActive", W.HWND), ("hwndFocus", W.HWND),
                ("hwndCapture", W.HWND), ("hwndMenuOwner", W.HWND), ("hwndMoveSize", W.HWND),
                ("hwndCaret", W.HWND), ("rcCaret", W.RECT)]


class STARTUPINFOW(ctypes.Structure):
    _fields_ = [("cb", W.DWORD), ("lpReserved", W.LPWSTR), ("lpDesktop", W.LPWSTR), ("lpTitle", W.LPWSTR),
                ("dwX", W.DWORD), ("dwY", W.DWORD), ("dwXSize", W.DWORD), ("dwYSize", W.DWORD),
                ("dwXCountChars", W.DWORD), ("dwYCountChars", W.DWORD), ("dwFillAttribute", W.DWORD),
                ("dwFlags", W.DWORD), ("wShowWindow", W.WORD), ("cbReserved2", W.WORD),
                ("lpReserved2", ctypes.c_void_p), ("hStdInput", W.HANDLE), ("hStdOutput", W.HANDLE),
                ("hStdError", W.HANDLE)]


class PROCESS_INFORMATION(ctypes.Structure):
    _fields_ = [("hProcess", W.HANDLE), ("hThread", W.HANDLE), ("dwProcessId", W.DWORD), ("dwThreadId", W.DWORD)]


class SHELLEXECUTEINFOW(ctypes.Structure):
    _fields_ = [("cbSize", W.DWORD), ("fMask", W.ULONG), ("hwnd", W.HWND), ("lpVerb", W.LPCWSTR),
                ("lpFile", W.LPCWSTR), ("lpParameters", W.LPCWSTR), ("lpDirectory", W.LPCWSTR), ("nShow", ctypes.c_int),
                ("hInstApp", W.HINSTANCE), ("lpIDList", ctypes.c_void_p), ("lpClass", W.LPCWSTR),
                ("hkeyClass", W.HKEY), ("dwHotKey", W.DWORD), ("hIconOrMonitor", W.HANDLE), ("hProcess", W.HANDLE)]


# -- constants -------------------------------------------------------------------------------------------------
INPUT_MOUSE, INPUT_KEYBOARD = 0, 1
MOUSEEVENTF_MOVE, MOUSEEVENTF_LEFTDOWN, MOUSEEVENTF_LEFTUP = 0x0001, 0x0002, 0x0004
MOUSEEVENTF_RIGHTDOWN, MOUSEEVENTF_RIGHTUP, MOUSEEVENTF_MIDDLEDOWN, MOUSEEVENTF_MIDDLEUP = 0x08, 0x10, 0x20, 0x40
MOUSEEVENTF_WHEEL, MOUSEEVENTF_HWHEEL = 0x0800, 0x1000
MOUSEEVENTF_VIRTUALDESK, MOUSEEVENTF_ABSOLUTE = 0x4000, 0x8000
KEYEVENTF_EXTENDEDKEY, KEYEVENTF_KEYUP, KEYEVENTF_UNICODE, KEYEVENTF_SCANCODE = 0x1, 0x2, 0x4, 0x8
WHEEL_DELTA = 120
SM_XVIRTUALSCREEN, SM_YVIRTUALSCREEN, SM_CXVIRTUALSCREEN, SM_CYVIRTUALSCREEN = 76, 77, 78, 79
SRCCOPY, CAPTUREBLT = 0x00CC0020, 0x40000000
DIB_RGB_COLORS, BI_RGB = 0, 0
CURSOR_SHOWING, DI_NORMAL = 0x1, 0x3
GW_OWNER = 4
GWL_STYLE, GWL_EXSTYLE = -16, -20
WS_VISIBLE, WS_DISABLED, WS_CAPTION, WS_CHILD = 0x10000000, 0x08000000, 0x00C00000, 0x40000000
WS_EX_TOOLWINDOW = 0x80
WM_GETTEXT, WM_GETTEXTLENGTH = 0x000D, 0x000E
SMTO_ABORTIFHUNG = 0x2
BM_GETCHECK = 0x00F0
CF_UNICODETEXT = 13
GMEM_MOVEABLE = 0x0002
PROCESS_QUERY_LIMITED_INFORMATION = 0x1000
WAIT_OBJECT_0, WAIT_TIMEOUT, INFINITE = 0, 0x102, 0xFFFFFFFF
STARTF_USESTDHANDLES, STARTF_USESHOWWINDOW = 0x100, 0x1
CREATE_SUSPENDED, CREATE_NO_WINDOW, DETACHED_PROCESS = 0x4, 0x08000000, 0x8
CREATE_BREAKAWAY_FROM_JOB = 0x01000000
SEE_MASK_NOCLOSEPROCESS, SEE_MASK_FLAG_NO_UI, SEE_MASK_NOASYNC = 0x40, 0x400, 0x100
SW_SHOWNORMAL = 1

WNDENUMPROC = ctypes.WINFUNCTYPE(W.BOOL, W.HWND, W.LPARAM)
IS_WINE = hasattr(ctypes.WinDLL("ntdll"), "wine_get_version")  # the Wine stand-in, not a real Windows

# -- user32 ----------------------------------------------------------------------------------------------------
SetProcessDPIAware = _fn(user32, "SetProcessDPIAware", W.BOOL)
GetSystemMetrics = _fn(user32, "GetSystemMetrics", ctypes.c_int, ctypes.c_int)
SendInput = _fn(user32, "SendInput", W.UINT, W.UINT, ctypes.POINTER(INPUT), ctypes.c_int)
GetCursorPos = _fn(user32, "GetCursorPos", W.BOOL, ctypes.POINTER(W.POINT))
SetCursorPos = _fn(user32, "SetCursorPos", W.BOOL, ctypes.c_int, ctypes.c_int)
GetCursorInfo = _fn(user32, "GetCursorInfo", W.BOOL, ctypes.POINTER(CURSORINFO))
GetIconInfo = _fn(user32, "GetIconInfo", W.BOOL, W.HANDLE, ctypes.POINTER(ICONINFO))
DrawIconEx = _fn(user32, "DrawIconEx", W.BOOL, W.HDC, ctypes.c_int, ctypes.c_int, W.HANDLE, ctypes.c_int,
                 ctypes.c_int, W.UINT, W.HBRUSH, W.UINT)
LoadCursorW = _fn(user32, "LoadCursorW", W.HANDLE, W.HINSTANCE, ctypes.c_void_p)
IDC_ARROW = 32512
GetDC = _fn(user32, "GetDC", W.HDC, W.HWND)
ReleaseDC = _fn(user32, "ReleaseDC", ctypes.c_int, W.HWND, W.HDC)
MapVirtualKeyW = _fn(user32, "MapVirtualKeyW", W.UINT, W.UINT, W.UINT)
VkKeyScanW = _fn(user32, "VkKeyScanW", ctypes.c_short, W.WCHAR)
ToUnicode = _fn(user32, "ToUnicode", ctypes.c_int, W.UINT, W.UINT, ctypes.POINTER(ctypes.c_ubyte), W.LPWSTR,
                ctypes.c_int, W.UINT)
EnumWindows = _fn(user32, "EnumWindows", W.BOOL, WNDENUMPROC, W.LPARAM)
EnumChildWindows = _fn(user32, "EnumChildWindows", W.BOOL, W.HWND, WNDENUMPROC, W.LPARAM)
GetWindow = _fn(user32, "GetWindow", W.HWND, W.HWND, W.UINT)
GetParent = _fn(user32, "GetParent", W.HWND, W.HWND)
GetDlgCtrlID = _fn(user32, "GetDlgCtrlID", ctypes.c_int, W.HWND)
GetAncestor = _fn(user32, "GetAncestor", W.HWND, W.HWND, W.UINT)
IsWindow = _fn(user32, "IsWindow", W.BOOL, W.HWND)
IsWindowVisible = _fn(user32, "IsWindowVisible", W.BOOL, W.HWND)
IsWindowEnabled = _fn(user32, "IsWindowEnabled", W.BOOL, W.HWND)
IsIconic = _fn(user32, "IsIconic", W.BOOL, W.HWND)
GetWindowRect = _fn(user32, "GetWindowRect", W.BOOL, W.HWND, ctypes.POINTER(W.RECT))
GetClassNameW = _fn(user32, "GetClassNameW", ctypes.c_int, W.HWND, W.LPWSTR, ctypes.c_int)
GetWindowTextW = _fn(user32, "GetWindowTextW", ctypes.c_int, W.HWND, W.LPWSTR, ctypes.c_int)
GetWindowLongW = _fn(user32, "GetWindowLongW", W.LONG, W.HWND, ctypes.c_int)
GetWindowThreadProcessId = _fn(user32, "GetWindowThreadProcessId", W.DWORD, W.HWND, ctypes.POINTER(W.DWORD))
GetForegroundWindow = _fn(user32, "GetForegroundWindow", W.HWND)
SetForegroundWindow = _fn(user32, "SetForegroundWindow", W.BOOL, W.HWND)
GetLastActivePopup = _fn(user32, "GetLastActivePopup", W.HWND, W.HWND)
ShowWindow = _fn(user32, "ShowWindow", W.BOOL, W.HWND, ctypes.c_int)
SW_RESTORE = 9
GetGUIThreadInfo = _fn(user32, "GetGUIThreadInfo", W.BOOL, W.DWORD, ctypes.POINTER(GUITHREADINFO))
FindWindowW = _fn(user32, "FindWindowW", W.HWND, W.LPCWSTR, W.LPCWSTR)
GetDesktopWindow = _fn(user32, "GetDesktopWindow", W.HWND)
SendMessageTimeoutW = _fn(user32, "SendMessageTimeoutW", LRESULT, W.HWND, W.UINT, W.WPARAM, W.LPARAM, W.UINT,
                          W.UINT, ctypes.POINTER(ULONG_PTR))
OpenClipboard = _fn(user32, "OpenClipboard", W.BOOL, W.HWND)
CloseClipboard = _fn(user32, "CloseClipboard", W.BOOL)
EmptyClipboard = _fn(user32, "EmptyClipboard", W.BOOL)
GetClipboardData = _fn(user32, "GetClipboardData", W.HANDLE, W.UINT)
SetClipboardData = _fn(user32, "SetClipboardData", W.HANDLE, W.UINT, W.HANDLE)
IsClipboardFormatAvailable = _fn(user32, "IsClipboardFormatAvailable", W.BOOL, W.UINT)

# -- gdi32 -----------------------------------------------------------------------------------------------------
CreateCompatibleDC = _fn(gdi32, "CreateCompatibleDC", W.HDC, W.HDC)
DeleteDC = _fn(gdi32, "DeleteDC", W.BOOL, W.HDC)
CreateDIBSection = _fn(gdi32, "CreateDIBSection", W.HBITMAP, W.HDC, ctypes.POINTER(BITMAPINFO), W.UINT,
                       ctypes.POINTER(ctypes.c_void_p), W.HANDLE, W.DWORD)
SelectObject = _fn(gdi32, "SelectObject", W.HGDIOBJ, W.HDC, W.HGDIOBJ)
DeleteObject = _fn(gdi32, "DeleteObject", W.BOOL, W.HGDIOBJ)
BitBlt = _fn(gdi32, "BitBlt", W.BOOL, W.HDC, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_int, W.HDC,
             ctypes.c_int, ctypes.c_int, W.DWORD)
GdiFlush = _fn(gdi32, "GdiFlush", W.BOOL)

# -- kernel32 --------------------------------------------------------------------------------------------------
CloseHandle = _fn(kernel32, "CloseHandle", W.BOOL, W.HANDLE)
GlobalAlloc = _fn(kernel32, "GlobalAlloc", W.HGLOBAL, W.UINT, ctypes.c_size_t)
GlobalLock = _fn(kernel32, "GlobalLock", ctypes.c_void_p, W.HGLOBAL)
GlobalUnlock = _fn(kernel32, "GlobalUnlock", W.BOOL, W.HGLOBAL)
GlobalFree = _fn(kernel32, "GlobalFree", W.HGLOBAL, W.HGLOBAL)
GlobalSize = _fn(kernel32, "GlobalSize", ctypes.c_size_t, W.HGLOBAL)
WaitForInputIdle = _fn(user32, "WaitForInputIdle", W.DWORD, W.HANDLE, W.DWORD)
GetProcessId = _fn(kernel32, "GetProcessId", W.DWORD, W.HANDLE)
GetExitCodeProcess = _fn(kernel32, "GetExitCodeProcess", W.BOOL, W.HANDLE, ctypes.POINTER(W.DWORD))
STILL_ACTIVE = 259
GetProcessTimes = _fn(kernel32, "GetProcessTimes", W.BOOL, W.HANDLE, ctypes.POINTER(W.FILETIME),
                      ctypes.POINTER(W.FILETIME), ctypes.POINTER(W.FILETIME), ctypes.POINTER(W.FILETIME))
OpenProcess = _fn(kernel32, "OpenProcess", W.HANDLE, W.DWORD, W.BOOL, W.DWORD)
QueryFullProcessImageNameW = _fn(kernel32, "QueryFullProcessImageNameW", W.BOOL, W.HANDLE, W.DWORD, W.LPWSTR,
                                 ctypes.POINTER(W.DWORD))
GetACP = _fn(kernel32, "GetACP", W.UINT)
GetOEMCP = _fn(kernel32, "GetOEMCP", W.UINT)

# -- shell32 ---------------------------------------------------------------------------------------------------
ShellExecuteExW = _fn(shell32, "ShellExecuteExW", W.BOOL, ctypes.POINTER(SHELLEXECUTEINFOW))


def text_of(buffer_len: int, call) -> str:
    """A string filled by `call(buffer, length)` (GetClassNameW-style)."""
    buf = ctypes.create_unicode_buffer(buffer_len)
    n = call(buf, buffer_len)
    return buf.value[:n] if n > 0 else ""


def class_name(hwnd: int) -> str:
    return text_of(256, lambda b, n: GetClassNameW(hwnd, b, n))


def window_rect(hwnd: int) -> list[int]:
    """[x, y, w, h] of a window on screen."""
    r = W.RECT()
    if not GetWindowRect(hwnd, ctypes.byref(r)):
        return [0, 0, 0, 0]
    return [r.left, r.top, r.right - r.left, r.bottom - r.top]


def window_text(hwnd: int, timeout_ms: int = 200, limit: int = 4096) -> str:
    """A window's text through WM_GETTEXT (works across processes; an edit control's content), bounded in time
    so a hung program costs `timeout_ms`, not the request."""
    n = ULONG_PTR()
    if not SendMessageTimeoutW(hwnd, WM_GETTEXTLENGTH, 0, 0, SMTO_ABORTIFHUNG, timeout_ms, ctypes.byref(n)):
        return ""
    size = min(int(n.value), limit) + 1
    buf = ctypes.create_unicode_buffer(size)
    got = ULONG_PTR()
    if not SendMessageTimeoutW(hwnd, WM_GETTEXT, size, ctypes.cast(buf, ctypes.c_void_p).value or 0,
                               SMTO_ABORTIFHUNG, timeout_ms, ctypes.byref(got)):
        return ""
    return buf.value


def top_level_windows() -> list[int]:
    """Every top-level window handle, in z-order (topmost first)."""
    found: list[int] = []

    @WNDENUMPROC
    def collect(hwnd, _):
        found.append(hwnd)
        return True

    EnumWindows(collect, 0)
    return found


def child_windows(hwnd: int) -> list[int]:
    """The direct children of a window (EnumChildWindows walks all descendants; those are filtered)."""
    found: list[int] = []

    @WNDENUMPROC
    def collect(child, _):
        if GetAncestor(child, 1) == hwnd:  # GA_PARENT
            found.append(child)
        return True

    EnumChildWindows(hwnd, collect, 0)
    return found


# -- menus -----------------------------------------------------------------------------------------------------
class MENUITEMINFOW(ctypes.Structure):
    _fields_ = [("cbSize", W.UINT), ("fMask", W.UINT), ("fType", W.UINT), ("fState", W.UINT), ("wID", W.UINT),
                ("hSubMenu", W.HMENU), ("hbmpChecked", W.HBITMAP), ("hbmpUnchecked", W.HBITMAP),
                ("dwItemData", ULONG_PTR), ("dwTypeData", W.LPWSTR), ("cch", W.UINT), ("hbmpItem", W.HBITMAP)]


MN_GETHMENU = 0x01E1
MIIM_STATE, MIIM_SUBMENU, MIIM_FTYPE, MIIM_STRING = 0x1, 0x4, 0x100, 0x40
MFT_SEPARATOR, MFS_DISABLED, MFS_CHECKED, MFS_HILITE = 0x800, 0x3, 0x8, 0x80
GetMenu = _fn(user32, "GetMenu", W.HMENU, W.HWND)
GetMenuItemCount = _fn(user32, "GetMenuItemCount", ctypes.c_int, W.HMENU)
GetMenuItemInfoW = _fn(user32, "GetMenuItemInfoW", W.BOOL, W.HMENU, W.UINT, W.BOOL, ctypes.POINTER(MENUITEMINFOW))
GetMenuItemRect = _fn(user32, "GetMenuItemRect", W.BOOL, W.HWND, W.HMENU, W.UINT, ctypes.POINTER(W.RECT))


# -- COM / MSAA (oleacc), loaded on first use --------------------------------------------------------------------
class GUID(ctypes.Structure):
    _fields_ = [("Data1", W.DWORD), ("Data2", W.WORD), ("Data3", W.WORD), ("Data4", ctypes.c_ubyte * 8)]

    @classmethod
    def parse(cls, text: str) -> "GUID":
        import uuid

        u = uuid.UUID(text)
        return cls(u.fields[0], u.fields[1], u.fields[2], (ctypes.c_ubyte * 8)(*u.bytes[8:]))


class VARIANT(ctypes.Structure):
    """Only what MSAA's child id needs: VT_I4 with a LONG (the union is 16 bytes on 64-bit)."""

    _fields_ = [("vt", W.USHORT), ("r1", W.WORD), ("r2", W.WORD), ("r3", W.WORD), ("lVal", W.LONG),
                ("pad", ctypes.c_byte * (ctypes.sizeof(ctypes.c_void_p) * 2 - 4))]


VT_I4 = 3
OBJID_CLIENT = -4
IID_IAccessible = "{618736e0-3c3d-11cf-810c-00aa00389b71}"


# -- jobs, processes, windows of our own -----------------------------------------------------------------------
class JOBOBJECT_BASIC_LIMIT_INFORMATION(ctypes.Structure):
    _fields_ = [("PerProcessUserTimeLimit", ctypes.c_int64), ("PerJobUserTimeLimit", ctypes.c_int64),
                ("LimitFlags", W.DWORD), ("MinimumWorkingSetSize", ctypes.c_size_t),
                ("MaximumWorkingSetSize", ctypes.c_size_t), ("ActiveProcessLimit", W.DWORD),
                ("Affinity", ULONG_PTR), ("PriorityClass", W.DWORD), ("SchedulingClass", W.DWORD)]


class IO_COUNTERS(ctypes.Structure):
    _fields_ = [(n, ctypes.c_uint64) for n in ("ReadOperationCount", "WriteOperationCount", "OtherOperationCount",
                                               "ReadTransferCount", "WriteTransferCount", "OtherTransferCount")]


class JOBOBJECT_EXTENDED_LIMIT_INFORMATION(ctypes.Structure):
    _fields_ = [("BasicLimitInformation", JOBOBJECT_BASIC_LIMIT_INFORMATION), ("IoInfo", IO_COUNTERS),
                ("ProcessMemoryLimit", ctypes.c_size_t), ("JobMemoryLimit", ctypes.c_size_t),
                ("PeakProcessMemoryUsed", ctypes.c_size_t), ("PeakJobMemoryUsed", ctypes.c_size_t)]


JobObjectExtendedLimitInformation = 9
JOB_OBJECT_LIMIT_KILL_ON_JOB_CLOSE = 0x2000
CreateJobObjectW = _fn(kernel32, "CreateJobObjectW", W.HANDLE, ctypes.c_void_p, W.LPCWSTR)
SetInformationJobObject = _fn(kernel32, "SetInformationJobObject", W.BOOL, W.HANDLE, ctypes.c_int, ctypes.c_void_p,
                              W.DWORD)
AssignProcessToJobObject = _fn(kernel32, "AssignProcessToJobObject", W.BOOL, W.HANDLE, W.HANDLE)
TerminateJobObject = _fn(kernel32, "TerminateJobObject", W.BOOL, W.HANDLE, W.UINT)
ntdll = ctypes.WinDLL("ntdll")
NtResumeProcess = _fn(ntdll, "NtResumeProcess", ctypes.c_long, W.HANDLE)

WNDPROC = ctypes.WINFUNCTYPE(LRESULT, W.HWND, W.UINT, W.WPARAM, W.LPARAM)
HWND_MESSAGE = -3
CreateWindowExW = _fn(user32, "CreateWindowExW", W.HWND, W.DWORD, W.LPCWSTR, W.LPCWSTR, W.DWORD, ctypes.c_int,
                      ctypes.c_int, ctypes.c_int, ctypes.c_int, W.HWND, W.HMENU, W.HINSTANCE, W.LPVOID)
GetMessageW = _fn(user32, "GetMessageW", W.BOOL, ctypes.POINTER(W.MSG), W.HWND, W.UINT, W.UINT)
TranslateMessage = _fn(user32, "TranslateMessage", W.BOOL, ctypes.POINTER(W.MSG))
DispatchMessageW = _fn(user32, "DispatchMessageW", LRESULT, ctypes.POINTER(W.MSG))
