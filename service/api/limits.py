"""A request body size limit, enforced on the stream: a declared ``Content-Length`` over the
limit is refused before reading; a body sent without one (chunked) is counted as it arrives
and refused (413) the moment it passes the limit."""

from __future__ import annotations

from gaitforge.service.api.problems import problem_response
from starlette.exceptions import HTTPException
from starlette.requests import Request
from starlette.types import ASGIApp, Message, Receive, Scope, Send


class BodyTooLarge(HTTPException):
    """The request body passed the limit (answered 413 by the problem handlers)."""

    def __init__(self, limit: int) -> None:
        super().__init__(status_code=413, detail=f"request body over {limit} bytes")


class BodySizeLimit:
    """ASGI middleware: at most ``max_bytes`` of request body per request."""

    def __init__(self, app: ASGIApp, max_bytes: int) -> None:
        self.app = app
        self.max_bytes = max_bytes

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

        async def limited() -> Message:
            nonlocal received
            message = await receive()
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
