"""The accessibility tree from window handles: every top-level window (EnumWindows, z-order) and its child
controls (EnumChildWindows), with class, text, rectangle and state, menus read through their HMENU, and MSAA
(`AccessibleObjectFromWindow(OBJID_CLIENT)`) names and values where oleacc answers. Nodes have the Ubuntu
server's shape `{"role", "name", "box": [x, y, w, h], "states": [...], "text"?, "children"?}` plus `class`.

Under Wine there is no UI Automation; menus and dialogs are windows, so their controls show here, while the
buttons of a toolbar are drawn by one window and do not.
"""

from __future__ import annotations

import ctypes
import threading
import time

from . import win32 as w

MAX_TEXT = 200
CALL_TIMEOUT_MS = 200  # one WM_GETTEXT to a window of another program; a hung program costs this much
_LOCK = threading.Lock()

ROLES = {
    "#32770": "dialog", "#32768": "menu", "Edit": "text", "RICHEDIT50W": "text", "RichEdit20W": "text",
    "RichEdit20A": "text", "RICHEDIT": "text", "Static": "label", "ComboBox": "combo box",
    "ComboBoxEx32": "combo box", "ListBox": "list", "ComboLBox": "list", "SysListView32": "list",
    "SysTreeView32": "tree", "msctls_statusbar32": "status bar", "ToolbarWindow32": "tool bar",
    "ReBarWindow32": "tool bar", "SysTabControl32": "page tab list", "msctls_progress32": "progress bar",
    "msctls_trackbar32": "slider", "ScrollBar": "scroll bar", "SysHeader32": "table column header",
    "msctls_updown32": "spin button", "SysLink": "link", "Shell_TrayWnd": "panel", "SysPager": "panel",
    "tooltips_class32": "tool tip",
}
TASKBAR_CLASS = "Shell_TrayWnd"  # Wine's (and Windows') taskbar
ACCESS_KEY_ROLES = {"push button", "check box", "radio button", "label", "panel"}
TEXT_CLASSES = {"Edit", "RICHEDIT50W", "RichEdit20W", "RichEdit20A", "RICHEDIT", "ComboBox", "ComboBoxEx32"}
ES_MULTILINE, ES_PASSWORD, ES_READONLY = 0x4, 0x20, 0x800


def _button_role(style: int) -> str:
    kind = style & 0xF
    if kind in (2, 3, 5, 6):
        return "check box"
    if kind in (4, 9):
        return "radio button"
    if kind == 7:
        return "panel"
    return "push button"


class _Msaa:
    """IAccessible of a window's client area through raw COM vtable calls (oleacc), if it loads."""

    def __init__(self):
        self.ok = False
        try:
            self.oleacc = ctypes.WinDLL("oleacc")
            self.ole32 = ctypes.WinDLL("ole32")
            self.oleaut32 = ctypes.WinDLL("oleaut32")
        except OSError:
            return
        self.AccessibleObjectFromWindow = w._fn(self.oleacc, "AccessibleObjectFromWindow", ctypes.c_long, w.W.HWND,
                                                w.W.DWORD, ctypes.POINTER(w.GUID), ctypes.POINTER(ctypes.c_void_p))
        self.CoInitializeEx = w._fn(self.ole32, "CoInitializeEx", ctypes.c_long, ctypes.c_void_p, w.W.DWORD)
        self.SysFreeString = w._fn(self.oleaut32, "SysFreeString", None, ctypes.c_void_p)
        self.iid = w.GUID.parse(w.IID_IAccessible)
        # COM methods by vtable index; ctypes passes the interface pointer as the hidden first argument
        proto = ctypes.WINFUNCTYPE(ctypes.c_long, w.VARIANT, ctypes.POINTER(ctypes.c_void_p))
        self.get_name, self.get_value = proto(10, "get_accName"), proto(11, "get_accValue")
        self.release = ctypes.WINFUNCTYPE(w.W.ULONG)(2, "Release")
        self.ok = True
        self._initialised = threading.local()

    def _bstr(self, method, obj) -> str:
        out = ctypes.c_void_p()
        child = w.VARIANT(vt=w.VT_I4, lVal=0)
        if method(obj, child, ctypes.byref(out)) != 0 or not out.value:
            return ""
        try:
            return ctypes.wstring_at(out.value)
        finally:
            self.SysFreeString(out.value)

    def name_value(self, hwnd: int) -> tuple[str, str]:
        """(name, value) of the window's client object; empty strings where MSAA gives nothing."""
        if not self.ok:
            return "", ""
        if not getattr(self._initialised, "done", False):
            self.CoInitializeEx(None, 0)  # COINIT_MULTITHREADED, once per request thread
            self._initialised.done = True
        obj = ctypes.c_void_p()
        if self.AccessibleObjectFromWindow(hwnd, w.OBJID_CLIENT & 0xFFFFFFFF, ctypes.byref(self.iid),
                                           ctypes.byref(obj)) != 0 or not obj.value:
            return "", ""
        try:
            return self._bstr(self.get_name, obj), self._bstr(self.get_value, obj)
        finally:
            self.release(obj)


_MSAA: _Msaa | None = None


def msaa() -> _Msaa:
    global _MSAA
    if _MSAA is None:
        _MSAA = _Msaa()
    return _MSAA


def focus_window() -> tuple[int, int]:
    """(foreground top-level window, focused control) of the desktop."""
    fg = w.GetForegroundWindow() or 0
    info = w.GUITHREADINFO(cbSize=ctypes.sizeof(w.GUITHREADINFO))
    tid = w.GetWindowThreadProcessId(fg, None) if fg else 0
    if tid and w.GetGUIThreadInfo(tid, ctypes.byref(info)):
        return fg, info.hwndFocus or 0
    return fg, 0


def menu_items(hmenu: int, hwnd: int | None, limit: int) -> list[dict]:
    """The items of a menu (a menu bar when `hwnd` owns it), as `menu item` nodes."""
    out = []
    count = w.GetMenuItemCount(hmenu)
    for i in range(max(0, min(count, limit))):
        buf = ctypes.create_unicode_buffer(256)
        info = w.MENUITEMINFOW(cbSize=ctypes.sizeof(w.MENUITEMINFOW),
                               fMask=w.MIIM_STATE | w.MIIM_SUBMENU | w.MIIM_FTYPE | w.MIIM_STRING,
                               dwTypeData=ctypes.cast(buf, w.W.LPWSTR), cch=255)
        if not w.GetMenuItemInfoW(hmenu, i, True, ctypes.byref(info)):
            continue
        if info.fType & w.MFT_SEPARATOR:
            node = {"role": "separator", "name": "", "states": []}
        else:
            states = ["enabled", "sensitive"] if not info.fState & w.MFS_DISABLED else []
            if info.fState & w.MFS_CHECKED:
                states.append("checked")
            if info.fState & w.MFS_HILITE:
                states.append("selected")
            label = buf.value.split("\t")[0]
            node = {"role": "menu" if info.hSubMenu else "menu item", "states": states,
                    "name": label.replace("&&", "\0").replace("&", "").replace("\0", "&")}
            if label != node["name"]:
                node["label"] = label  # with its access key marked, e.g. "&File"
            if "\t" in buf.value:
                node["shortcut"] = buf.value.split("\t", 1)[1]
        r = w.W.RECT()
        if hwnd is not None and w.GetMenuItemRect(hwnd, hmenu, i, ctypes.byref(r)):
            node["box"] = [r.left, r.top, r.right - r.left, r.bottom - r.top]
            node["states"] += ["visible", "showing"]
        out.append(node)
    return out


def taskbar_button_name(button: int) -> str:
    """What a button of Wine's taskbar shows: it draws the title of the window whose handle is its control id
    (programs/explorer/systray.c, `add_taskbar_button`), or "Start" (id 0); its own window text is empty."""
    target = w.GetDlgCtrlID(button) & 0xFFFFFFFF
    if not target:
        return "Start"
    return w.window_text(target, CALL_TIMEOUT_MS) if w.IsWindow(target) else ""


def tree(max_nodes: int = 2000, max_depth: int = 30, timeout: float = 5.0, showing_only: bool = True) -> dict:
    """The desktop's window tree as nested dicts; `truncated` says whether a limit cut it short."""
    from .screen import virtual_screen

    deadline = time.monotonic() + timeout
    count = 0
    truncated = False
    fg, focus = focus_window()
    acc = msaa()

    def describe(hwnd: int, top: bool) -> dict:
        cls = w.class_name(hwnd)
        style = w.GetWindowLongW(hwnd, w.GWL_STYLE) & 0xFFFFFFFF
        visible = bool(w.IsWindowVisible(hwnd))
        if cls == "Button":
            role = _button_role(style)
        elif cls in ROLES:
            role = ROLES[cls]
        elif top:
            role = "frame" if style & w.WS_CAPTION == w.WS_CAPTION else "window"
        else:
            role = "panel"
        raw = w.window_text(hwnd, CALL_TIMEOUT_MS)
        if cls == "Button" and not raw and w.class_name(w.GetParent(hwnd) or 0) == TASKBAR_CLASS:
            raw = taskbar_button_name(hwnd)
        name, text = raw, None
        if cls in TEXT_CLASSES:
            name, text = "", ("" if style & ES_PASSWORD else raw)
        states = []
        if w.IsWindowEnabled(hwnd):
            states += ["enabled", "sensitive"]
        if visible:
            states += ["visible", "showing"]
        if w.IsIconic(hwnd):
            states.append("iconified")
        if hwnd == focus:
            states += ["focused"]
        if hwnd == fg:
            states.append("active")
        if (role == "text" and not style & ES_READONLY) or (role == "combo box" and style & 0x3 in (1, 2)):
            states.append("editable")  # an edit control, or a combo box with an edit field (not a drop-down list)
        if cls == "Edit" and style & ES_MULTILINE:
            states.append("multi line")
        if role in ("check box", "radio button"):
            checked = w.ULONG_PTR()
            if w.SendMessageTimeoutW(hwnd, w.BM_GETCHECK, 0, 0, w.SMTO_ABORTIFHUNG, CALL_TIMEOUT_MS,
                                     ctypes.byref(checked)) and checked.value == 1:
                states.append("checked")
        if not top and role not in ("panel", "tool tip") and visible:
            m_name, m_value = acc.name_value(hwnd)
            if m_name and not name:
                name = m_name
            if m_value and text is None and role != "push button":
                text = m_value
        label = name
        if role in ACCESS_KEY_ROLES and "&" in name:  # "&Save" is shown as "Save" with S underlined
            name = name.replace("&&", "\0").replace("&", "").replace("\0", "&")
        node = {"role": role, "name": name, "class": cls, "box": w.window_rect(hwnd), "states": sorted(set(states))}
        if label != name:
            node["label"] = label  # the text with its access key marked, e.g. "&Save"
        if text:
            node["text"] = text[:MAX_TEXT]
        return node

    def walk(hwnd: int, depth: int, top: bool) -> dict | None:
        nonlocal count, truncated
        if count >= max_nodes or time.monotonic() > deadline:
            truncated = True
            return None
        count += 1
        node = describe(hwnd, top)
        kids: list[dict] = []
        if top:
            menu = w.GetMenu(hwnd) if w.GetWindowLongW(hwnd, w.GWL_STYLE) & w.WS_CHILD == 0 else 0
            if menu and depth < max_depth:
                items = menu_items(menu, hwnd, max(0, max_nodes - count - 1))
                if items:
                    count += 1 + len(items)
                    kids.append({"role": "menu bar", "name": "", "box": node["box"], "states": ["showing"],
                                 "children": items})
            if node["class"] == "#32768" and depth < max_depth:  # an open popup menu: its items
                result = w.ULONG_PTR()
                if w.SendMessageTimeoutW(hwnd, w.MN_GETHMENU, 0, 0, w.SMTO_ABORTIFHUNG, CALL_TIMEOUT_MS,
                                         ctypes.byref(result)) and result.value:
                    items = menu_items(result.value, None, max(0, max_nodes - count))
                    count += len(items)
                    kids += items
        children = w.child_windows(hwnd)
        if depth >= max_depth:
            truncated = truncated or bool(children)
        else:
            for child in children:
                if showing_only and not w.IsWindowVisible(child):
                    continue
                sub = walk(child, depth + 1, False)
                if sub is None:
                    break
                kids.append(sub)
        if kids:
            node["children"] = kids
        return node

    with _LOCK:
        t0 = time.monotonic()
        x, y, cx, cy = virtual_screen()
        root = {"role": "desktop frame", "name": "Desktop", "class": "#32769", "box": [x, y, cx, cy],
                "states": ["enabled", "showing", "visible"]}
        count = 1
        kids = []
        for hwnd in w.top_level_windows():
            if showing_only and not w.IsWindowVisible(hwnd):
                continue
            sub = walk(hwnd, 1, True)
            if sub is None:
                break
            kids.append(sub)
        if kids:
            root["children"] = kids
        elapsed = time.monotonic() - t0
    return {"tree": root, "nodes": count, "truncated": truncated, "elapsed_ms": round(elapsed * 1000, 1)}
