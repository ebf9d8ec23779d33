"""Request and response models of the control server, shared by the server (inside a device) and the client."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid")


class Health(_Model):
    ok: bool = True
    desktop: bool  # the window manager and the desktop are running
    details: dict[str, bool] = Field(default_factory=dict)


class ScreenSize(_Model):
    width: int
    height: int


class ActionResult(_Model):
    ok: bool
    error: str | None = None
    elapsed_ms: float = 0.0


class A11yTree(_Model):
    """The accessibility tree: nested `{"role", "name", "box", "states", "text"?, "children"?}` nodes."""

    tree: dict | None
    nodes: int
    truncated: bool  # a node, depth or time limit cut the tree short
    elapsed_ms: float = 0.0


class RunRequest(_Model):
    command: str = Field(min_length=1)
    user: str | None = Field(default=None, description="`root` runs through sudo; default: the desktop user")
    timeout: float = Field(default=60.0, gt=0, le=3600)


class RunResponse(_Model):
    returncode: int
    stdout: str
    stderr: str
    fault: str | None = Field(default=None, description="set when the device failed to start a program the command "
                              "names although it exists (a fault of the device, not of the command): what ran is "
                              "incomplete and says nothing about the command")


class LaunchRequest(_Model):
    app: str = Field(min_length=1)
    args: list[str] = Field(default_factory=list)
    window_wait: float = Field(default=0.0, ge=0.0, le=120.0,
                               description="seconds to wait for a new application window or a changed title")


class LaunchResponse(_Model):
    ok: bool = True
    window: bool = Field(default=False, description="a new window (or a changed title) showed within the wait")
    id: int | None = Field(default=None, description="that window, where the device names windows (Windows)")


class ErrorResponse(_Model):
    error: str


class OpenRequest(_Model):
    """POST /open: open a file or folder with its default application."""

    path: str = Field(min_length=1)
    window_wait: float = Field(default=0.0, ge=0.0, le=120.0)


class FocusRequest(_Model):
    """POST /focus: bring the application window whose title contains `title` to the front; on Windows also a
    window named by its `id` (with `title`: once it shows that title), and a foreground that is already the
    window's own (it, its menu, a dialog it shows) is left as it is. One of `title` and `id` is needed."""

    title: str | None = Field(default=None, min_length=1)
    id: int | None = Field(default=None, description="a window id (`launch`, `windows`); Windows only")
    timeout: float = Field(default=5.0, ge=0.0, le=60.0, description="seconds to wait for such a window")


class PathInfo(_Model):
    """GET /exists?path=: whether the path exists on the device, and what it is."""

    exists: bool
    kind: str | None = Field(default=None, description="file, dir or other; null when missing")


class WindowInfo(_Model):
    id: int
    title: str
    class_: str = Field(alias="class")
    box: list[int]  # x, y, width, height on the screen
    focused: bool = False
    pid: int | None = None  # the process that owns the window, where the device says (Windows)

    model_config = ConfigDict(extra="forbid", populate_by_name=True)


class WindowList(_Model):
    """GET /windows: the visible top-level windows."""

    windows: list[WindowInfo]


class ClipboardText(_Model):
    """GET /clipboard (the clipboard's text) and PUT /clipboard (set it)."""

    text: str
