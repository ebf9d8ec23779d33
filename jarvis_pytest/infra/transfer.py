"""Host-side clients of the transfer drive (the paper's network drive): copyparty (offline default) and AList.

Both offer `list`, `walk`, `upload`, `download`, `delete` and `wait_ready`, so evaluators can check what is on
the drive whichever server runs. Paths are absolute paths on the drive (`/folder/file.txt`).
"""

from __future__ import annotations

import time
from urllib.parse import quote, unquote

import httpx

from jarvis_pytest.errors import InfrastructureError


class CopypartyClient:
    """copyparty's HTTP API: `PUT /path` uploads, `GET /dir/?ls` lists as JSON, `POST /path?delete` deletes;
    the password goes in the `PW` header."""

    flavour = "copyparty"

    def __init__(self, base_url: str, user: str, password: str, timeout: float = 30.0):
        self.base_url = base_url.rstrip("/")
        self.http = httpx.Client(base_url=self.base_url, headers={"PW": password}, timeout=timeout)

    @staticmethod
    def _url(path: str) -> str:
        return quote("/" + path.lstrip("/"))

    def _check(self, resp: httpx.Response, what: str) -> httpx.Response:
        if resp.status_code >= 400:
            raise InfrastructureError(f"transfer drive: {what} failed ({resp.status_code}): {resp.text[:200]}")
        return resp

    def wait_ready(self, timeout: float = 30.0) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                if self.http.get("/?ls", timeout=2).status_code == 200:
                    return
            except httpx.HTTPError:
                pass
            time.sleep(0.05)
        raise InfrastructureError(f"transfer drive at {self.base_url} not ready after {timeout:.0f} s")

    def list(self, folder: str = "/") -> tuple[list[str], list[str]]:
        """(sub-folders, files) of `folder`, as names."""
        url = self._url(folder).rstrip("/") + "/?ls"
        resp = self.http.get(url)
        if resp.status_code == 404:
            return [], []
        data = self._check(resp, f"listing {folder}").json()
        dirs = [httpx.URL(d["href"]).path.rstrip("/") for d in data.get("dirs", [])]
        files = [httpx.URL(f["href"]).path for f in data.get("files", [])]
        return [unquote(d) for d in dirs], [unquote(f) for f in files]

    def walk(self, folder: str = "/") -> list[str]:
        """Every file on the drive below `folder`, as absolute paths, sorted."""
        out: list[str] = []
        dirs, files = self.list(folder)
        base = "/" + folder.strip("/")
        base = "" if base == "/" else base
        out += [f"{base}/{f}" for f in files]
        for d in dirs:
            out += self.walk(f"{base}/{d}")
        return sorted(out)

    def upload(self, path: str, data: bytes) -> None:
        self._check(self.http.put(self._url(path), content=data), f"upload of {path}")

    def download(self, path: str) -> bytes:
        return self._check(self.http.get(self._url(path)), f"download of {path}").content

    def delete(self, path: str) -> None:
        self._check(self.http.post(self._url(path) + "?delete"), f"delete of {path}")

    def close(self) -> None:
        self.http.close()


class AlistClient:
    """AList/OpenList's API (`/api/auth/login` → token; `/api/fs/list`, `/api/fs/put`, `/api/fs/get`,
    `/api/fs/remove`). For users whose machine can pull an AList image; not exercised here (none can be)."""

    flavour = "alist"

    def __init__(self, base_url: str, user: str, password: str, timeout: float = 30.0):
        self.base_url = base_url.rstrip("/")
        self.user, self.password = user, password
        self.http = httpx.Client(base_url=self.base_url, timeout=timeout)

    def _api(self, method: str, path: str, **kw) -> dict:
        if "Authorization" not in self.http.headers:
            token = self._post_json("/api/auth/login", {"username": self.user, "password": self.password})["token"]
            self.http.headers["Authorization"] = token
        resp = self.http.request(method, path, **kw)
        body = resp.json() if resp.content else {}
        if resp.status_code >= 400 or body.get("code", 200) != 200:
            raise InfrastructureError(f"transfer drive (AList): {path} failed: {body.get('message', resp.text[:200])}")
        return body.get("data") or {}

    def _post_json(self, path: str, payload: dict) -> dict:
        resp = self.http.post(path, json=payload)
        body = resp.json()
        if body.get("code") != 200:
            raise InfrastructureError(f"transfer drive (AList): {path} failed: {body.get('message')}")
        return body["data"]

    def wait_ready(self, timeout: float = 30.0) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                self.http.get("/ping", timeout=2)
                return
            except httpx.HTTPError:
                time.sleep(0.1)
        raise InfrastructureError(f"transfer drive at {self.base_url} not ready after {timeout:.0f} s")

    def list(self, folder: str = "/") -> tuple[list[str], list[str]]:
        content = self._api("POST", "/api/fs/list", json={"path": folder, "refresh": True}).get("content") or []
        return ([c["name"] for c in content if c.get("is_dir")], [c["name"] for c in content if not c.get("is_dir")])

    def walk(self, folder: str = "/") -> list[str]:
        dirs, files = self.list(folder)
        base = "" if folder.strip("/") == "" else "/" + folder.strip("/")
        return sorted([f"{base}/{f}" for f in files] + [p for d in dirs for p in self.walk(f"{base}/{d}")])

    def upload(self, path: str, data: bytes) -> None:
        self._api("PUT", "/api/fs/put", content=data, headers={"File-Path": quote(path)})

    def download(self, path: str) -> bytes:
        url = self._api("POST", "/api/fs/get", json={"path": path})["raw_url"]
        return self.http.get(url).content

    def delete(self, path: str) -> None:
        folder, _, name = path.rstrip("/").rpartition("/")
        self._api("POST", "/api/fs/remove", json={"dir": folder or "/", "names": [name]})

    def close(self) -> None:
        self.http.close()


TRANSFER_CLIENTS = {"copyparty": CopypartyClient, "alist": AlistClient}
