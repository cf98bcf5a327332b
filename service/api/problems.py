"""Errors as RFC 9457 problem details (``application/problem+json``), for every error the app
answers: its own (:class:`ProblemError`), Starlette's 404 and 405 (``Allow``: the methods of
every route of the path), request validation (422, with ``errors: [{field, message}]``),
input nested past Python's recursion limit anywhere in the request's handling (400, one log
line, no traceback) and anything unexpected (500, logged).

A problem stays small whatever was sent: at most :data:`MAX_FIELD_ERRORS` field errors (one
more entry counts the others), and the detail, field names and messages cut short.
"""

from __future__ import annotations

import logging
from http import HTTPStatus
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from fastapi.routing import iter_route_contexts
from pydantic import BaseModel, ConfigDict, Field
from starlette.exceptions import HTTPException as StarletteHTTPException

logger = logging.getLogger(__name__)

PROBLEM_JSON = "application/problem+json"
_LOCATIONS = ("body", "query", "path", "header", "cookie")
MAX_FIELD_ERRORS = 50
"""field errors listed in one problem; the others are counted in one more entry (a backstop:
a job spec's errors come listed 20 at most, ``workers.spec_io.MAX_PROBLEMS``)"""
MAX_DETAIL_CHARS = 2000
"""characters of a problem's detail (and of a field error's message)"""
MAX_FIELD_CHARS = 200
"""characters of a field error's field name"""


class FieldError(BaseModel):
    """One bad field of a request: its dotted path and what is wrong with it."""

    field: str = Field(description="dotted path of the field, e.g. stages.0.scene")
    message: str = Field(description="what is wrong and what is allowed (one line)")


class Problem(BaseModel):
    """An error (RFC 9457 problem details)."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "type": "about:blank",
                    "title": "Not Found",
                    "status": 404,
                    "detail": "no job j-0123456789ab",
                    "instance": "/v1/jobs/j-0123456789ab",
                }
            ]
        }
    )

    type: str = Field(default="about:blank", description="URI naming the kind of problem")
    title: str = Field(description="short summary of the kind of problem")
    status: int = Field(ge=100, le=599, description="the HTTP status code")
    detail: str | None = Field(default=None, description="what went wrong, this time")
    instance: str | None = Field(default=None, description="the request path")
    errors: list[FieldError] | None = Field(
        default=None, description="422 only: each bad field of the request"
    )


class ProblemError(Exception):
    """Raised by handlers to answer with a problem (status, detail, optional field errors)."""

    def __init__(
        self,
        status: int,
        detail: str,
        *,
        type: str = "about:blank",
        errors: list[FieldError] | None = None,
        headers: dict[str, str] | None = None,
    ) -> None:
        super().__init__(detail)
        self.status = status
        self.detail = detail
        self.type = type
        self.errors = errors
        self.headers = headers


def problem_response(
    request: Request,
    status: int,
    detail: str | None,
    *,
    type: str = "about:blank",
    errors: list[FieldError] | None = None,
    headers: dict[str, str] | None = None,
) -> JSONResponse:
    """The problem+json response for ``status`` (title: the status phrase), kept small
    (:func:`bounded_errors`, the detail cut at :data:`MAX_DETAIL_CHARS`)."""
    problem = Problem(
        type=type,
        title=_phrase(status),
        status=status,
        detail=None if detail is None else _cut(detail, MAX_DETAIL_CHARS),
        instance=request.url.path,
        errors=None if errors is None else bounded_errors(errors),
    )
    return JSONResponse(
        problem.model_dump(mode="json", exclude_none=True),
        status_code=status,
        media_type=PROBLEM_JSON,
        headers=headers,
    )


def bounded_errors(errors: list[FieldError]) -> list[FieldError]:
    """The first :data:`MAX_FIELD_ERRORS` of ``errors``, fields and messages cut short, and
    one more entry counting the others (a request of many bad fields must not come back as
    a larger answer)."""
    kept = [
        FieldError(field=_cut(e.field, MAX_FIELD_CHARS), message=_cut(e.message, MAX_DETAIL_CHARS))
        for e in errors[:MAX_FIELD_ERRORS]
    ]
    if len(errors) > MAX_FIELD_ERRORS:
        more = len(errors) - MAX_FIELD_ERRORS
        kept.append(FieldError(field="body", message=f"{more} more problems not listed"))
    return kept


def _cut(text: str, limit: int) -> str:
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


def _phrase(status: int) -> str:
    try:
        return HTTPStatus(status).phrase
    except ValueError:
        return "Error"


def validation_errors(raw: list[dict[str, Any]]) -> list[FieldError]:
    """FastAPI's validation errors as ``{field, message}`` (``query.limit`` -> ``limit``)."""
    out = []
    for e in raw:
        loc = [str(p) for p in e.get("loc", ())]
        if loc and loc[0] in _LOCATIONS:
            loc = loc[1:] or loc[:1]
        message = str(e.get("msg", "invalid")).removeprefix("Value error, ")
        out.append(FieldError(field=".".join(loc) or "request", message=message))
    return out


async def _on_problem(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, ProblemError)
    return problem_response(
        request, exc.status, exc.detail, type=exc.type, errors=exc.errors, headers=exc.headers
    )


async def _on_http(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, StarletteHTTPException)
    detail = exc.detail if isinstance(exc.detail, str) else _phrase(exc.status_code)
    headers = exc.headers
    if exc.status_code == 405:  # Starlette's Allow names the first route of the path only
        headers = {**(headers or {}), "Allow": allowed_methods(request)}
    return problem_response(request, exc.status_code, detail, headers=headers)


def allowed_methods(request: Request) -> str:
    """The methods of every route of the request's path (``GET /v1/jobs`` and ``POST
    /v1/jobs`` are two routes), for a 405's ``Allow``."""
    path, root = request.scope["path"], request.scope.get("root_path", "")
    if root and path.startswith(f"{root}/"):
        path = path[len(root) :]
    methods: set[str] = set()
    for route in iter_route_contexts(request.app.routes):  # included routers' too
        pattern = getattr(route, "path_regex", None)
        if pattern is not None and pattern.match(path):
            methods |= route.methods or set()
    return ", ".join(sorted(methods))


async def _on_validation(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, RequestValidationError)
    errors = validation_errors(list(exc.errors()))
    detail = "; ".join(f"{e.field}: {e.message}" for e in errors)
    return problem_response(request, 422, detail, errors=errors)


async def _on_recursion(request: Request, exc: Exception) -> JSONResponse:
    logger.warning("%s %s: input nested too deeply (%s)", request.method, request.url.path, exc)
    return problem_response(request, 400, "the request is nested too deeply to handle")


async def _on_crash(request: Request, exc: Exception) -> JSONResponse:
    logger.exception("%s %s failed", request.method, request.url.path, exc_info=exc)
    return problem_response(request, 500, "internal error (logged by the service)")


def install_problem_handlers(app: FastAPI) -> None:
    """Answer every error of ``app`` as problem+json."""
    app.add_exception_handler(ProblemError, _on_problem)
    app.add_exception_handler(StarletteHTTPException, _on_http)
    app.add_exception_handler(RequestValidationError, _on_validation)
    app.add_exception_handler(RecursionError, _on_recursion)
    app.add_exception_handler(Exception, _on_crash)


def problem_responses(*codes: int) -> dict[int | str, dict[str, Any]]:
    """OpenAPI ``responses`` entries for ``codes``, each a :class:`Problem` with an example."""
    return {code: _problem_doc(code) for code in codes}


_DESCRIPTIONS = {
    400: "the request is malformed (or nested too deeply to handle)",
    401: "no or an unknown bearer token",
    404: "no such job (or another owner's), artifact or scene",
    409: "the job is not in a state that allows this",
    413: "the request body is larger than the service accepts",
    422: "the request or job spec is invalid (each bad field named in errors)",
    429: "the owner has as many queued and running jobs as allowed",
}
_EXAMPLES: dict[int, dict[str, Any]] = {
    401: {"detail": "missing bearer token", "instance": "/v1/jobs"},
    404: {"detail": "no job j-0123456789ab", "instance": "/v1/jobs/j-0123456789ab"},
    409: {"detail": "job j-0123456789ab is running", "instance": "/v1/jobs/j-0123456789ab/resume"},
    413: {"detail": "request body over 1000000 bytes", "instance": "/v1/jobs"},
    422: {
        "type": "urn:gaitforge:problem:invalid-job-spec",
        "detail": "stages.0.scene: unknown scene 'walk-9d'",
        "instance": "/v1/jobs",
        "errors": [{"field": "stages.0.scene", "message": "unknown scene 'walk-9d'"}],
    },
    429: {
        "type": "urn:gaitforge:problem:job-limit",
        "detail": "owner alice has 8 queued or running jobs (the limit)",
        "instance": "/v1/jobs",
    },
}


def _problem_doc(code: int) -> dict[str, Any]:
    example = {"type": "about:blank", "title": _phrase(code), "status": code}
    example.update(_EXAMPLES.get(code, {"detail": _phrase(code), "instance": "/v1/jobs"}))
    return {
        "description": _DESCRIPTIONS.get(code, _phrase(code)),
        "content": {
            PROBLEM_JSON: {
                "schema": {"$ref": "#/components/schemas/Problem"},
                "example": example,
            }
        },
    }
