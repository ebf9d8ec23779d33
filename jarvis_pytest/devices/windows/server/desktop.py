"""The desktop's windows: readiness (the shell's taskbar shown and drawn), the window list, and the application
windows a launch waits for."""

from __future__ import annotations

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
    """The visible top-level windows in z-order (topmost first), the desktop and the taskbar left out."""
    fg = w.GetForegroundWindow() or 0
    out = []
    for hwnd in w.top_level_windows():
        if not w.IsWindowVisible(hwnd):
            continue
        cls = w.class_name(hwnd)
        box = w.window_rect(hwnd)
        if cls in SHELL_CLASSES or box[2] <= 0 or box[3] <= 0:
            continue
        out.append({"id": int(hwnd), "title": w.window_text(hwnd), "class": cls, "box": box, "focused": hwnd == fg})
    return out


def focus(title: str) -> dict | None:
    """Bring to the front the visible application window whose title shows `title` (`control_http.title_matches`);
    the window as {"id", "title"}, or None when none shows."""
    from jarvis_pytest.devices.control_http import title_matches

    for hwnd, text in sorted(app_windows().items()):
        if title_matches(title, text):
            if w.IsIconic(hwnd):
                w.ShowWindow(hwnd, w.SW_RESTORE)
            w.SetForegroundWindow(hwnd)
            return {"id": hwnd, "title": text}
    return None


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
