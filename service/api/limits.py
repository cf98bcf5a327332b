"""Request body limits, enforced on the stream.

Size: a declared ``Content-Length`` over the limit is refused before reading; a body sent
without one (chunked) is counted as it arrives and refused (413) the moment it passes the
limit. Time: once the app starts reading a body, the whole of it must arrive within
``timeout_s``; a body that stalls (``Content-Length: 100`` and 2 bytes sent) or trickles is
answered 408 with ``Connection: close`` (uvicorn has no timeout for a request body: its
``timeout_keep_alive`` only covers the wait between requests).
"""

from __future__ import annotations

import anyio
from gaitforge.service.api.problems import problem_response
from starlette.exceptions import HTTPException
from starlette.requests import Request
from starlette.types import ASGIApp, Message, Receive, Scope, Send


class BodyTooLarge(HTTPException):
    """The request body passed the limit (answered 413 by the problem handlers)."""

    def __init__(self, limit: int) -> None:
        super().__init__(status_code=413, detail=f"request body over {limit} bytes")


class BodyTimeout(HTTPException):
    """The request body did not arrive in time (answered 408, the connection closed)."""

    def __init__(self, timeout_s: float) -> None:
        super().__init__(
            status_code=408,
            detail=f"the request body did not arrive within {timeout_s:g} s",
            headers={"Connection": "close"},
        )


class BodyLimits:
    """ASGI middleware: at most ``max_bytes`` of request body per request, all of it within
    ``timeout_s`` of the app's first read."""

    def __init__(self, app: ASGIApp, max_bytes: int, timeout_s: float) -> None:
        self.app = app
        self.max_bytes = max_bytes
        self.timeout_s = timeout_s

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        declared = _content_length(scope)
        if declared is not None and not 0 <= declared <= self.max_bytes:
            if declared < 0:
                response = problem_response(Request(scope), 400, "bad Content-Length header")
            else:
                detail = BodyTooLarge(self.max_bytes).detail
                response = problem_response(Request(scope), 413, detail)
            await response(scope, receive, send)
            return
        received = 0
        deadline: float | None = None
        body_done = False

        async def limited() -> Message:
            nonlocal received, deadline, body_done
            if body_done:  # then only a disconnect is awaited (an event stream's whole life)
                return await receive()
            if deadline is None:
                deadline = anyio.current_time() + self.timeout_s
            with anyio.move_on_after(deadline - anyio.current_time()) as waiting:
                message = await receive()
            if waiting.cancelled_caught:
                raise BodyTimeout(self.timeout_s)
            if message["type"] != "http.request" or not message.get("more_body", False):
                body_done = True
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > self.max_bytes:
                    raise BodyTooLarge(self.max_bytes)
            return message

        await self.app(scope, limited, send)


def _content_length(scope: Scope) -> int | None:
    """The declared body length (None: not declared; -1: not a number)."""
    for key, value in scope.get("headers", ()):
        if key == b"content-length":
            return int(value) if value.isdigit() else -1
    return None
