"""``GaitforgeClient``: the REST API over httpx, one method per endpoint.

    client = GaitforgeClient("http://127.0.0.1:8765", token=resolve_token())
    job = client.submit({"name": "tiny", "stages": [{"scene": "elbow-reach", "env_steps": 1000}]})
    for event, status in client.events(job["id"]):   # server-sent events until the job ends
        ...
    client.download(job["id"], "checkpoints", "latest", Path("out"))   # sha256 verified

Errors: :class:`ApiError` for every answer that is not a success (its ``str`` is one line:
``title: detail (field: message; ...)`` from the problem+json body) and
:class:`ServerUnreachable` when nothing answers at ``server``.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx

DEFAULT_SERVER = "http://127.0.0.1:8765"
ARTIFACT_KINDS = ("checkpoints", "recordings", "reports")
SHA_HEADER = "X-Content-SHA256"
CHUNK_BYTES = 1 << 20
SSE_READ_S = 60.0
"""s without a byte on an event stream (the service pings every 15 s) before reconnecting"""


class ClientError(Exception):
    """Something the client could not do; ``str`` is one line."""


class ServerUnreachable(ClientError):
    """No service answers at the server's address."""


class ApiError(ClientError):
    """The service answered with an error (``application/problem+json`` when it is ours);
    ``str``: ``404 Not Found: no job j-... (field: message; ...)``.

    Attributes:
        status: the HTTP status code.
        title, detail: the problem's title and detail.
        errors: ``[{"field": ..., "message": ...}]`` for a 422.
    """

    def __init__(self, status: int, title: str, detail: str = "", errors: list | None = None):
        self.status, self.title, self.detail = status, title, detail
        self.errors = errors or []
        fields = "; ".join(f"{e.get('field', '?')}: {e.get('message', '')}" for e in self.errors)
        text = f"{title}: {detail}" if detail and detail != title else title
        text = text if text.startswith("HTTP ") else f"{status} {text}"
        super().__init__(f"{text} ({fields})" if fields and fields not in text else text)

    @classmethod
    def from_response(cls, response: httpx.Response) -> ApiError:
        """The error an error response describes (problem+json, else its status and text)."""
        try:
            body = response.json()
        except (ValueError, UnicodeDecodeError):
            body = None
        if not isinstance(body, dict):
            text = " ".join(response.text.split())[:200]
            return cls(response.status_code, f"HTTP {response.status_code}", text)
        detail = body.get("detail", "")
        if not isinstance(detail, str):  # FastAPI's own {"detail": [...]}
            detail = json.dumps(detail)[:300]
        return cls(
            response.status_code,
            str(body.get("title") or f"HTTP {response.status_code}"),
            detail,
            body.get("errors") if isinstance(body.get("errors"), list) else None,
        )


class DigestMismatch(ClientError):
    """A download's sha256 differs from the one the service sent."""


def resolve_token(
    token: str | None = None, token_file: Path | None = None, home: Path | None = None
) -> str | None:
    """The bearer token: ``token``, else ``$GAITFORGE_TOKEN``, else the first line of
    ``token_file`` / ``$GAITFORGE_TOKEN_FILE`` (the token alone; ``#`` lines skipped), else
    ``{home}/token`` (home from ``ServiceSettings``, where the service writes the token it
    generates); None if there is none.

    Raises:
        ClientError: a token file that was named but cannot be read.
    """
    token = token or os.environ.get("GAITFORGE_TOKEN")
    if token:
        return token.strip()
    named = token_file or (Path(p) if (p := os.environ.get("GAITFORGE_TOKEN_FILE")) else None)
    if named is None:
        from gaitforge.service.settings import ServiceSettings

        default = ServiceSettings(home=home) if home else ServiceSettings()
        if not default.token_file.is_file():
            return None
        named = default.token_file
    try:
        lines = [line.strip() for line in named.read_text().splitlines()]
    except OSError as exc:
        raise ClientError(f"token file {named}: {exc.strerror}") from None
    return next((line for line in lines if line and not line.startswith("#")), None)


class GaitforgeClient:
    """The service's REST API (``/v1``); each method returns the parsed JSON answer."""

    def __init__(
        self, server: str = DEFAULT_SERVER, token: str | None = None, timeout_s: float = 30.0
    ) -> None:
        self.server = server.rstrip("/")
        headers = {"Authorization": f"Bearer {token}"} if token else {}
        self.http = httpx.Client(base_url=self.server, headers=headers, timeout=timeout_s)

    def close(self) -> None:
        self.http.close()

    def __enter__(self) -> GaitforgeClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def request(self, method: str, path: str, **kwargs: Any) -> httpx.Response:
        """One request; errors raised as :class:`ApiError` / :class:`ServerUnreachable`."""
        try:
            response = self.http.request(method, path, **kwargs)
        except httpx.TransportError as exc:
            raise self.unreachable(exc) from None
        if response.is_error:
            raise ApiError.from_response(response)
        return response

    def unreachable(self, exc: Exception) -> ServerUnreachable:
        """The one-line error for a transport failure (names the server)."""
        reason = str(exc).strip() or type(exc).__name__
        if isinstance(exc, httpx.ConnectError):
            reason = "connection refused or no route (is `gaitforge serve` running?)"
        return ServerUnreachable(f"no gaitforge service at {self.server}: {reason}")

    def get(self, path: str, **params: Any) -> Any:
        clean = {k: v for k, v in params.items() if v is not None}
        return self.request("GET", path, params=clean).json()

    def health(self) -> dict:
        return self.get("/healthz")

    def submit(self, spec: dict | str) -> dict:
        """POST /v1/jobs: a job spec (a mapping, or YAML/JSON text) -> the job's status."""
        if isinstance(spec, str):
            return self.request(
                "POST", "/v1/jobs", content=spec, headers={"Content-Type": "application/yaml"}
            ).json()
        return self.request("POST", "/v1/jobs", json=spec).json()

    def jobs(self, state: str | None = None, offset: int = 0, limit: int = 50) -> dict:
        return self.get("/v1/jobs", state=state, offset=offset, limit=limit)

    def status(self, job_id: str) -> dict:
        return self.get(f"/v1/jobs/{job_id}")

    def metrics(self, job_id: str) -> dict:
        return self.get(f"/v1/jobs/{job_id}/metrics")

    def logs(self, job_id: str, offset: int = 0) -> dict:
        return self.get(f"/v1/jobs/{job_id}/logs", offset=offset)

    def cancel(self, job_id: str) -> dict:
        return self.request("POST", f"/v1/jobs/{job_id}/cancel").json()

    def resume(self, job_id: str) -> dict:
        return self.request("POST", f"/v1/jobs/{job_id}/resume").json()

    def artifacts(self, job_id: str, kind: str) -> dict:
        """GET /v1/jobs/{id}/{kind}, kind one of checkpoints, recordings, reports."""
        return self.get(f"/v1/jobs/{job_id}/{kind}")

    def scenes(self) -> Any:
        return self.get("/v1/scenes")

    def scene(self, name: str) -> dict:
        return self.get(f"/v1/scenes/{name}")

    def events(self, job_id: str) -> Iterator[tuple[str, Any]]:
        """GET /v1/jobs/{id}/events: ``(event, data)`` per server-sent event (data parsed as
        JSON where it is), until the stream ends."""
        try:
            with self.http.stream(
                "GET", f"/v1/jobs/{job_id}/events", timeout=httpx.Timeout(30.0, read=SSE_READ_S)
            ) as response:
                if response.is_error:
                    response.read()
                    raise ApiError.from_response(response)
                yield from parse_sse(response.iter_lines())
        except httpx.TransportError as exc:
            raise self.unreachable(exc) from None

    def download(self, job_id: str, kind: str, name: str, path: Path) -> tuple[int, str]:
        """GET /v1/jobs/{id}/{kind}/{name} streamed into ``path``; returns (bytes, sha256).

        Raises:
            DigestMismatch: the sha256 of what arrived differs from ``X-Content-SHA256``
                (``path`` is removed).
        """
        digest, size = hashlib.sha256(), 0
        path.parent.mkdir(parents=True, exist_ok=True)
        part = path.with_name(path.name + ".part")
        try:
            with self.http.stream("GET", f"/v1/jobs/{job_id}/{kind}/{name}") as response:
                if response.is_error:
                    response.read()
                    raise ApiError.from_response(response)
                expected = response.headers.get(SHA_HEADER, "").lower()
                with part.open("wb") as f:
                    for chunk in response.iter_bytes(CHUNK_BYTES):
                        f.write(chunk)
                        digest.update(chunk)
                        size += len(chunk)
        except httpx.TransportError as exc:
            part.unlink(missing_ok=True)
            raise self.unreachable(exc) from None
        except BaseException:
            part.unlink(missing_ok=True)
            raise
        if not expected:
            part.unlink()
            raise DigestMismatch(f"{kind}/{name}: the service sent no {SHA_HEADER} header")
        if digest.hexdigest() != expected:
            part.unlink()
            raise DigestMismatch(
                f"{kind}/{name}: sha256 {digest.hexdigest()} differs from the service's {expected}"
            )
        part.replace(path)
        return size, expected


def parse_sse(lines: Iterator[str]) -> Iterator[tuple[str, Any]]:
    """Server-sent events from text lines: ``(event, data)``, ``event`` defaulting to
    ``message``; ``data`` lines joined and parsed as JSON where they are JSON."""
    event, data = "message", []
    for line in lines:
        if not line:
            if data or event != "message":
                text = "\n".join(data)
                try:
                    yield event, json.loads(text) if text else None
                except ValueError:
                    yield event, text
            event, data = "message", []
        elif line.startswith(":"):
            continue
        else:
            key, _, value = line.partition(":")
            value = value.removeprefix(" ")
            if key == "event":
                event = value
            elif key == "data":
                data.append(value)
