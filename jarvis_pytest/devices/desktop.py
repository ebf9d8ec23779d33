"""The host-side client of a desktop device's control server (httpx, one keep-alive connection pool)."""

from __future__ import annotations

import json
import time

import httpx

from jarvis_pytest.devices.actions import Action
from jarvis_pytest.devices.base import ActionOutcome, CommandResult, Observation
from jarvis_pytest.devices.protocol import (A11yTree, ActionResult, ClipboardText, FocusRequest, Health,
                                            LaunchRequest, LaunchResponse, OpenRequest, PathInfo, RunRequest,
                                            RunResponse, ScreenSize, WindowList)
from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.http_client import http_client


LAUNCH_WINDOW_WAIT = 20.0  # seconds `launch` waits for the application's window


def png_size(png: bytes) -> tuple[int, int]:
    """Width and height from a PNG header (no decoding)."""
    return int.from_bytes(png[16:20], "big"), int.from_bytes(png[20:24], "big")


class DesktopDevice:
    """A desktop device (Ubuntu now; Windows later with the same server) reached at `base_url` on 127.0.0.1."""

    def __init__(self, base_url: str, platform: str = "ubuntu", timeout: float = 30.0):
        self.platform = platform
        self.names_windows = platform == "windows"  # its server names windows by id (`launch_window`, `focus_window`)
        self.base_url = base_url.rstrip("/")
        self.http = http_client(base_url=self.base_url, timeout=timeout)

    def __repr__(self) -> str:
        return f"DesktopDevice({self.base_url!r}, platform={self.platform!r})"

    def _request(self, method: str, path: str, *, timeout: float | None = None, **kw) -> httpx.Response:
        try:
            return self.http.request(method, path, timeout=timeout or self.http.timeout, **kw)
        except httpx.HTTPError as exc:
            raise InfrastructureError(f"{self.platform} device at {self.base_url} did not answer {method} {path}: "
                                      f"{exc.__class__.__name__}: {exc}") from exc

    @staticmethod
    def _error(resp: httpx.Response) -> str:
        """The server's `{"error": ...}` message (or the raw body of an answer that is not the server's)."""
        try:
            return str(resp.json()["error"])
        except (ValueError, KeyError, TypeError):
            return resp.text[:500] or f"HTTP {resp.status_code}"

    def _ok(self, resp: httpx.Response) -> httpx.Response:
        if resp.status_code >= 400:
            raise InfrastructureError(f"{self.platform} device: {resp.request.method} {resp.request.url.path} "
                                      f"failed ({resp.status_code}): {self._error(resp)}")
        return resp

    def health(self) -> Health:
        return Health.model_validate(self._ok(self._request("GET", "/health", timeout=5)).json())

    def screenshot(self) -> bytes:
        return self._ok(self._request("GET", "/screenshot")).content

    def a11y_tree(self, max_nodes: int = 2000, timeout: float = 5.0, showing_only: bool = True) -> dict:
        """`{"tree": {...}, "nodes": n, "truncated": bool, "elapsed_ms": t}` (see `server/a11y.py`)."""
        params = {"max_nodes": max_nodes, "timeout": timeout, "all": int(not showing_only)}
        resp = self._ok(self._request("GET", "/a11y", params=params, timeout=timeout + 10))
        return A11yTree.model_validate_json(resp.content).model_dump()

    def observe(self, *, a11y: bool = False) -> Observation:
        png = self.screenshot()
        w, h = png_size(png)
        tree = None
        if a11y:
            tree = json.dumps(self.a11y_tree())
        return Observation(platform=self.platform, screenshot_png=png, width=w, height=h, a11y_tree=tree)

    def act(self, action: Action) -> ActionOutcome:
        t0 = time.perf_counter()
        resp = self._request("POST", "/action", content=action.model_dump_json(),
                             headers={"Content-Type": "application/json"},
                             timeout=max(30.0, float(getattr(action, "seconds", 0)) + 30))
        if 400 <= resp.status_code < 500:  # the device refused the action: the agent's error, not ours
            return ActionOutcome(ok=False, error=self._error(resp), elapsed_ms=(time.perf_counter() - t0) * 1000)
        result = ActionResult.model_validate(self._ok(resp).json())
        return ActionOutcome(ok=result.ok, error=result.error, elapsed_ms=result.elapsed_ms)

    def screen_size(self) -> tuple[int, int]:
        s = ScreenSize.model_validate(self._ok(self._request("GET", "/screen_size")).json())
        return s.width, s.height

    def upload(self, path: str, data: bytes) -> None:
        self._ok(self._request("PUT", "/files", params={"path": path}, content=data))

    def download(self, path: str) -> bytes:
        return self._ok(self._request("GET", "/files", params={"path": path})).content

    def run(self, command: str, *, timeout: float = 60.0, user: str | None = None) -> CommandResult:
        req = RunRequest(command=command, user=user, timeout=timeout)
        resp = self._request("POST", "/run", content=req.model_dump_json(), timeout=timeout + 10,
                             headers={"Content-Type": "application/json"})
        r = RunResponse.model_validate(self._ok(resp).json())
        return CommandResult(returncode=r.returncode, stdout=r.stdout, stderr=r.stderr, fault=r.fault)

    def launch(self, app: str, *args: str, window_wait: float = LAUNCH_WINDOW_WAIT) -> bool:
        """Start `app` with `args`; return once the desktop shows a new application window or an existing one
        changed its title (True: the next screenshot shows the app), or after `window_wait` seconds without
        either (False). Splash screens do not count. `window_wait=0` returns at once."""
        return self.launch_window(app, *args, window_wait=window_wait).window

    def launch_window(self, app: str, *args: str, window_wait: float = LAUNCH_WINDOW_WAIT) -> LaunchResponse:
        """`launch`, answered with the window: whether one showed, and its `id` where the device names windows
        (Windows; None elsewhere)."""
        req = LaunchRequest(app=app, args=list(args), window_wait=window_wait)
        resp = self._request("POST", "/launch", content=req.model_dump_json(), timeout=window_wait + 30,
                             headers={"Content-Type": "application/json"})
        return LaunchResponse.model_validate(self._ok(resp).json())

    def exists(self, path: str) -> bool:
        """Whether a file or folder exists at `path` on the device."""
        resp = self._ok(self._request("GET", "/exists", params={"path": path}))
        return PathInfo.model_validate(resp.json()).exists

    def open(self, path: str, *, window_wait: float = LAUNCH_WINDOW_WAIT) -> bool:
        """Open a file or folder with the device's default application; like `launch`, True once its window
        shows."""
        return self.open_window(path, window_wait=window_wait).window

    def open_window(self, path: str, *, window_wait: float = LAUNCH_WINDOW_WAIT) -> LaunchResponse:
        """`open`, answered with the window, like `launch_window`."""
        req = OpenRequest(path=path, window_wait=window_wait)
        resp = self._request("POST", "/open", content=req.model_dump_json(), timeout=window_wait + 30,
                             headers={"Content-Type": "application/json"})
        return LaunchResponse.model_validate(self._ok(resp).json())

    def focus(self, title: str, *, timeout: float = 5.0) -> bool:
        """Bring the application window whose title shows `title` (a substring, or a whole title with `*` for any
        text, case-insensitive) to the front; False when none showed within
        `timeout` seconds."""
        return self.focus_window(title, timeout=timeout) is not None

    def focus_window(self, title: str | None = None, *, id: int | None = None, timeout: float = 5.0) -> dict | None:
        """Bring a window to the front: the one whose title shows `title` (of several, on Windows, the newest), or
        the one `id` names (Windows; with `title`, once it shows it). On Windows a foreground that is already the
        window's own (it, a menu it opened, a dialog it shows) is left as it is, and the answer has `id`, `title`,
        `pid` of the window, `changed` (whether the foreground had to move) and `before` (the foreground window
        then). None when no such window showed within `timeout` seconds; `{"error": ...}` when the device could
        not bring it to the front."""
        req = FocusRequest(title=title, id=id, timeout=timeout)
        resp = self._request("POST", "/focus", content=req.model_dump_json(exclude_defaults=True),
                             headers={"Content-Type": "application/json"}, timeout=timeout + 30)
        if resp.status_code == 404:
            return None
        if resp.status_code == 409:
            return {"error": self._error(resp)}
        return self._ok(resp).json()

    def windows(self) -> list[dict]:
        """The visible top-level windows: id, title, class, box [x, y, w, h], focused."""
        resp = self._ok(self._request("GET", "/windows"))
        return [w.model_dump(by_alias=True) for w in WindowList.model_validate(resp.json()).windows]

    def clipboard(self) -> str:
        return ClipboardText.model_validate(self._ok(self._request("GET", "/clipboard")).json()).text

    def set_clipboard(self, text: str) -> None:
        self._ok(self._request("PUT", "/clipboard", content=ClipboardText(text=text).model_dump_json(),
                               headers={"Content-Type": "application/json"}))

    def close(self) -> None:
        self.http.close()

    def __enter__(self) -> "DesktopDevice":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


HEALTH_WAIT = 1.0    # seconds a readiness request lets the server hold its answer until the device is ready
RETRY_PAUSE = 0.1    # seconds before asking again when no server answered yet, or one that answers at once (the
                     # control server starts before the desktop it waits for, so this delays no device)


def wait_ready(base_url: str, timeout: float) -> None:
    """Ask /health until the desktop is up (each ask held by the server up to a second, `?wait=`, so a boot
    costs about one request a second); raise InfrastructureError after `timeout` seconds."""
    deadline = time.monotonic() + timeout
    last = "no answer"
    with http_client(base_url=base_url, timeout=HEALTH_WAIT + 5.0) as http:
        while (left := deadline - time.monotonic()) > 0:
            try:
                data = http.get("/health", params={"wait": f"{min(HEALTH_WAIT, left):.2f}"}).json()
                if data.get("desktop"):
                    return
                last = f"desktop not up yet: {data.get('details')}"
            except (httpx.HTTPError, ValueError) as exc:
                last = f"{exc.__class__.__name__}"
            time.sleep(RETRY_PAUSE)
    raise InfrastructureError(f"device at {base_url} not ready after {timeout:.0f} s ({last})")
