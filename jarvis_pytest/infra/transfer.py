"""Host-side clients of the transfer drive (the paper's network drive): copyparty (offline default) and AList.

Both implement `TransferClient` — `list`, `walk`, `upload`, `download`, `delete`, `mkdir`, `wait_ready` — so
evaluators can check what is on the drive whichever server runs. Paths are absolute paths on the drive
(`/data/report.xlsx`); `upload` creates missing folders and overwrites an existing file. A missing file raises
`FileNotFoundError`; any other failure raises `InfrastructureError` naming the request.
"""

from __future__ import annotations

import posixpath
import time
from typing import Protocol, runtime_checkable
from urllib.parse import quote, unquote

import httpx

from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.http_client import http_client


@runtime_checkable
class TransferClient(Protocol):
    """What evaluators and the harness may call on a transfer drive."""

    flavour: str
    base_url: str

    def wait_ready(self, timeout: float = 30.0) -> None: ...

    def list(self, folder: str = "/") -> tuple[list[str], list[str]]: ...

    def walk(self, folder: str = "/") -> list[str]: ...

    def upload(self, path: str, data: bytes) -> None: ...

    def download(self, path: str) -> bytes: ...

    def delete(self, path: str) -> None: ...

    def mkdir(self, path: str) -> None: ...

    def close(self) -> None: ...


def drive_path(path: str) -> str:
    """`path` as a normalised absolute drive path (`a//b/` → `/a/b`)."""
    return posixpath.normpath("/" + path.strip("/"))


def check_empty(drive: TransferClient) -> None:
    """Raise InfrastructureError unless the drive holds only an empty `/data`, as a new drive does."""
    root, data = drive.list("/"), drive.list("/data")
    if root != (["data"], []) or data != ([], []):
        raise InfrastructureError(f"transfer drive at {drive.base_url} is not empty: / holds {root}, /data {data}")


class _Drive:
    """What both flavours share: the HTTP client, error messages, `walk` over `list`, polling for readiness."""

    flavour = "?"

    def __init__(self, base_url: str, timeout: float):
        self.base_url = base_url.rstrip("/")
        self.http = http_client(base_url=self.base_url, timeout=timeout)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.base_url!r})"

    def _request(self, method: str, url: str, what: str, **kw) -> httpx.Response:
        try:
            resp = self.http.request(method, url, **kw)
        except httpx.HTTPError as exc:
            raise InfrastructureError(f"transfer drive ({self.flavour}) at {self.base_url}: {what} got no answer: "
                                      f"{exc.__class__.__name__}: {exc}") from exc
        if resp.status_code == 404:
            raise FileNotFoundError(f"transfer drive: {what}: not found")
        if resp.status_code >= 400:
            raise InfrastructureError(f"transfer drive ({self.flavour}) at {self.base_url}: {what} failed "
                                      f"({resp.status_code}): {resp.text[:200]}")
        return resp

    def _answers(self) -> bool:
        raise NotImplementedError

    def wait_ready(self, timeout: float = 30.0) -> None:
        """Return once the drive answers an authenticated listing; raise InfrastructureError after `timeout`."""
        deadline = time.monotonic() + timeout
        last = "no answer"
        while True:
            try:
                if self._answers():
                    return
                last = "answered, but not yet with a listing"
            except (httpx.HTTPError, ValueError, InfrastructureError, FileNotFoundError) as exc:
                last = f"{exc.__class__.__name__}: {exc}"
            if time.monotonic() >= deadline:
                raise InfrastructureError(f"transfer drive at {self.base_url} not ready after {timeout:.0f} s ({last})")
            time.sleep(0.05)

    def list(self, folder: str = "/") -> tuple[list[str], list[str]]:
        raise NotImplementedError

    def walk(self, folder: str = "/") -> list[str]:
        """Every file below `folder` (a missing folder holds none), as absolute drive paths, sorted."""
        base = drive_path(folder).rstrip("/")
        try:
            dirs, files = self.list(folder)
        except FileNotFoundError:
            return []
        out = [f"{base}/{f}" for f in files]
        for d in dirs:
            out += self.walk(f"{base}/{d}")
        return sorted(out)

    def close(self) -> None:
        self.http.close()


class CopypartyClient(_Drive):
    """copyparty's HTTP API: `GET /dir/?ls` lists as JSON; `PUT /path` (header `Replace` to overwrite) uploads;
    `POST /dir/` with `act=mkdir` makes a folder; `POST /path?delete` deletes. The password goes in header `PW`."""

    flavour = "copyparty"

    def __init__(self, base_url: str, user: str, password: str, timeout: float = 30.0):
        super().__init__(base_url, timeout)
        self.http.headers["PW"] = password  # copyparty logs in by password alone (no --usernames)

    @staticmethod
    def _url(path: str) -> str:
        return quote(drive_path(path))

    def _answers(self) -> bool:
        resp = self.http.get("/?ls", timeout=2)
        return resp.status_code == 200 and "perms" in resp.json() and bool(resp.json()["perms"])

    def list(self, folder: str = "/") -> tuple[list[str], list[str]]:
        """(sub-folder names, file names) of `folder`; FileNotFoundError when it does not exist."""
        url = self._url(folder).rstrip("/") + "/?ls"
        data = self._request("GET", url, f"listing {folder}").json()
        dirs = [unquote(httpx.URL(d["href"]).path).rstrip("/") for d in data.get("dirs", [])]
        files = [unquote(httpx.URL(f["href"]).path) for f in data.get("files", [])]
        return sorted(dirs), sorted(files)

    def upload(self, path: str, data: bytes) -> None:
        self._request("PUT", self._url(path), f"upload of {path}", content=data, headers={"Replace": "1"})

    def download(self, path: str) -> bytes:
        return self._request("GET", self._url(path), f"download of {path}").content

    def delete(self, path: str) -> None:
        self._request("POST", self._url(path) + "?delete", f"delete of {path}")

    def mkdir(self, path: str) -> None:
        parent, name = posixpath.split(drive_path(path))
        self._request("POST", quote(parent.rstrip("/") + "/"), f"mkdir {path}",
                      files={"act": (None, "mkdir"), "name": (None, name)})


class AlistClient(_Drive):
    """AList/OpenList's API: `POST /api/auth/login` → token in `Authorization`; `/api/fs/list`, `PUT /api/fs/put`
    (header `File-Path`), `/api/fs/get` (→ `raw_url`), `/api/fs/remove`, `/api/fs/mkdir`. Written from AList's
    documented API; not exercised here (no AList image can be pulled on this machine)."""

    flavour = "alist"

    def __init__(self, base_url: str, user: str, password: str, timeout: float = 30.0):
        super().__init__(base_url, timeout)
        self.user, self.password = user, password

    def login(self) -> None:
        self.http.headers.pop("Authorization", None)
        body = self._request("POST", "/api/auth/login", "login",
                             json={"username": self.user, "password": self.password}).json()
        if body.get("code") != 200:
            raise InfrastructureError(f"transfer drive (alist) at {self.base_url}: login of {self.user!r} failed: "
                                      f"{body.get('message')}")
        self.http.headers["Authorization"] = body["data"]["token"]

    def api(self, method: str, path: str, what: str, **kw) -> dict:
        """One call of AList's JSON API (logging in first when needed); returns its `data`."""
        if "Authorization" not in self.http.headers:
            self.login()
        body = self._request(method, path, what, **kw).json()
        code = body.get("code", 200)
        if code == 404 or "not found" in str(body.get("message", "")).lower():
            raise FileNotFoundError(f"transfer drive: {what}: {body.get('message')}")
        if code != 200:
            raise InfrastructureError(f"transfer drive (alist) at {self.base_url}: {what} failed "
                                      f"(code {code}): {body.get('message')}")
        return body.get("data") or {}

    def _answers(self) -> bool:
        return self.http.get("/ping", timeout=2).status_code == 200

    def list(self, folder: str = "/") -> tuple[list[str], list[str]]:
        data = self.api("POST", "/api/fs/list", f"listing {folder}",
                        json={"path": drive_path(folder), "refresh": True})
        content = data.get("content") or []
        return (sorted(c["name"] for c in content if c.get("is_dir")),
                sorted(c["name"] for c in content if not c.get("is_dir")))

    def upload(self, path: str, data: bytes) -> None:
        self.api("PUT", "/api/fs/put", f"upload of {path}", content=data,
                 headers={"File-Path": quote(drive_path(path)), "Content-Type": "application/octet-stream"})

    def download(self, path: str) -> bytes:
        url = self.api("POST", "/api/fs/get", f"download of {path}", json={"path": drive_path(path)})["raw_url"]
        return self._request("GET", url, f"download of {path}").content

    def delete(self, path: str) -> None:
        folder, name = posixpath.split(drive_path(path))
        self.api("POST", "/api/fs/remove", f"delete of {path}", json={"dir": folder, "names": [name]})

    def mkdir(self, path: str) -> None:
        self.api("POST", "/api/fs/mkdir", f"mkdir {path}", json={"path": drive_path(path)})


TRANSFER_CLIENTS: dict[str, type[_Drive]] = {"copyparty": CopypartyClient, "alist": AlistClient}
