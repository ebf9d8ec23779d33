"""The desktop's windows: readiness (the shell's taskbar shown and drawn), the window list, the application
windows a launch waits for, and which window is which: a window is named by its id (a title can be shown by two
windows, e.g. two WordPads on one file), the foreground is checked to be one of the window's own (it, or a dialog
it shows), and bringing a window to the front waits until it is."""

from __future__ import annotations

import ctypes

from . import win32 as w

SHELL_CLASSES = {"Shell_TrayWnd", "Progman", "WorkerW", "#32769", "Shell_SecondaryTrayWnd"}
NOT_APPLICATIONS = SHELL_CLASSES | {"#32768", "tooltips_class32", "IME", "MSCTFIME UI", "SysShadow"}


def taskbar() -> int:
    """The shell's taskbar window (Wine's explorer with `/desktop=shell`, or Windows' own), 0 if none."""
    return w.FindWindowW("Shell_TrayWnd", None) or 0


def readiness(screen) -> dict[str, bool]:
    """What /health reports: the taskbar exists, is visible, and is drawn."""
    bar = taskbar()
    details = {"taskbar": bool(bar), "taskbar shown": bool(bar) and bool(w.IsWindowVisible(bar))}
    details["painted"] = details["taskbar shown"] and screen.painted(w.window_rect(bar))
    return details


def windows() -> list[dict]:
    """The visible top-level windows in z-order (topmost first), the desktop and the taskbar left out; `pid` is the
    process that owns each (a menu's is the program's whose menu it is)."""
    fg = w.GetForegroundWindow() or 0
    out = []
    for hwnd in w.top_level_windows():
        if not w.IsWindowVisible(hwnd):
            continue
        cls = w.class_name(hwnd)
        box = w.window_rect(hwnd)
        if cls in SHELL_CLASSES or box[2] <= 0 or box[3] <= 0:
            continue
        out.append({"id": int(hwnd), "title": w.window_text(hwnd), "class": cls, "box": box, "focused": hwnd == fg,
                    "pid": window_pid(hwnd)})
    return out


# -- which window: identity, and the windows that are its own ---------------------------------------------------
def window_pid(hwnd: int) -> int:
    """The id of the process that owns a window (0 when the window is gone)."""
    pid = w.W.DWORD()
    w.GetWindowThreadProcessId(hwnd, ctypes.byref(pid))
    return int(pid.value)


def process_started(pid: int) -> int:
    """When a process started (FILETIME ticks; 0 when it cannot be read): what makes one window newer than
    another (window handles are no age: Wine reuses freed ones)."""
    handle = w.OpenProcess(w.PROCESS_QUERY_LIMITED_INFORMATION, False, pid) if pid else 0
    if not handle:
        return 0
    try:
        times = [w.W.FILETIME() for _ in range(4)]
        if not w.GetProcessTimes(handle, *(ctypes.byref(t) for t in times)):
            return 0
        return (times[0].dwHighDateTime << 32) | times[0].dwLowDateTime
    finally:
        w.CloseHandle(handle)


def process_running(pid: int) -> bool:
    """Whether process `pid` still runs (False when it ended or cannot be looked at)."""
    handle = w.OpenProcess(w.PROCESS_QUERY_LIMITED_INFORMATION, False, pid) if pid else 0
    if not handle:
        return False
    try:
        code = w.W.DWORD()
        return bool(w.GetExitCodeProcess(handle, ctypes.byref(code))) and code.value == w.STILL_ACTIVE
    finally:
        w.CloseHandle(handle)


def describe(hwnd: int) -> dict:
    """{"id", "title", "class", "pid"} of a window (0 for none)."""
    if not hwnd:
        return {"id": 0, "title": "", "class": "", "pid": 0}
    return {"id": int(hwnd), "title": w.window_text(hwnd), "class": w.class_name(hwnd), "pid": window_pid(hwnd)}


def belongs_to(hwnd: int, target: int) -> bool:
    """Whether `hwnd` (the foreground window, say) is `target` or one of its own windows: a dialog or message box
    it owns (its chain of owners reaches `target`), or a dialog of the same process without an owner. Another
    window of the same title, or another program's window, is not."""
    if not hwnd or not target:
        return False
    # The owner chain by GW_OWNER: GetAncestor(GA_ROOTOWNER) walks it only through WS_POPUP windows, and WordPad's
    # "Date and time" dialog is an owned window without that style.
    owner = hwnd
    for _ in range(32):
        if owner == target:
            return True
        up = w.GetWindow(owner, w.GW_OWNER) or 0
        if not up:
            break
        owner = up
    return owner == hwnd and w.class_name(hwnd) == "#32770" and window_pid(hwnd) == window_pid(target) != 0


def shows(hwnd: int) -> bool:
    return bool(hwnd) and bool(w.IsWindow(hwnd)) and bool(w.IsWindowVisible(hwnd))


def newest(title: str) -> int | None:
    """The visible application window whose title shows `title` (`control_http.title_matches`); of several, the
    one whose program started last (the one opened for the work at hand: an older window may show the same file
    under the same title), then the topmost."""
    from jarvis_pytest.devices.control_http import title_matches

    found = [hwnd for hwnd, text in app_windows().items() if title_matches(title, text)]  # z-order, topmost first
    if not found:
        return None
    started = {hwnd: process_started(window_pid(hwnd)) for hwnd in found}
    return max(found, key=lambda hwnd: (started[hwnd], -found.index(hwnd)))


def front_of(target: int) -> int:
    """The window of `target` to activate: its last active popup (a dialog it shows, which disables it), else
    itself."""
    popup = w.GetLastActivePopup(target) or 0
    return popup if popup != target and shows(popup) else target


def bring_to_front(target: int, timeout: float = 3.0, settle: int = 3) -> bool:
    """Make `target` (or the dialog it shows) the foreground window and wait until the foreground is one of its
    own windows in `settle` successive looks 30 ms apart (activation crosses threads: it is not done when
    SetForegroundWindow returns, and a program that started a moment ago may still activate its own window);
    asked again while another window holds the foreground. False when it is not so within `timeout` s."""
    import time

    if w.IsIconic(target):
        w.ShowWindow(target, w.SW_RESTORE)
    deadline = time.monotonic() + timeout
    seen, asked = 0, 0.0
    while True:
        fg = w.GetForegroundWindow() or 0
        if belongs_to(fg, target):
            seen += 1
            if seen >= settle:
                return True
        else:
            seen = 0
            if time.monotonic() - asked >= 0.5:
                w.SetForegroundWindow(front_of(target))
                asked = time.monotonic()
        if time.monotonic() >= deadline or not shows(target):
            return False
        time.sleep(0.03)


def app_windows() -> dict[int, str]:
    """The visible application windows, id → title (menus, tooltips and the shell do not count)."""
    found = {}
    for hwnd in w.top_level_windows():
        if not w.IsWindowVisible(hwnd):
            continue
        if w.class_name(hwnd) in NOT_APPLICATIONS or w.GetWindowLongW(hwnd, w.GWL_EXSTYLE) & w.WS_EX_TOOLWINDOW:
            continue
        box = w.window_rect(hwnd)
        if box[2] > 0 and box[3] > 0:
            found[int(hwnd)] = w.window_text(hwnd)
    return found


def new_window(before: dict[int, str], seconds: float, pid: int = 0) -> int | None:
    """What a launch of process `pid` waits for (`control_http.wait_for_window`), as the window: within `seconds`,
    the id of a new application window (the process's own first, then the topmost), else of one whose title changed
    (a file opened into a window that was there); None after `seconds` without either. Another process's title
    change counts only once `pid` has ended (it handed its file to a program that was running): a window of an
    earlier launch still loading its own file is not this launch's (two WordPads on one file took the first's id
    for the second's). `pid` 0 (none known): every change counts."""
    import time

    deadline = time.monotonic() + seconds
    while seconds and time.monotonic() < deadline:
        time.sleep(0.05)
        now = app_windows()
        new = [hwnd for hwnd in now if hwnd not in before]
        changed = [hwnd for hwnd, title in now.items() if hwnd in before and before[hwnd] != title]
        if pid:
            new.sort(key=lambda hwnd: window_pid(hwnd) != pid)
            changed = [hwnd for hwnd in changed if window_pid(hwnd) == pid or not process_running(pid)]
        if new or changed:
            return (new or changed)[0]
    return None
