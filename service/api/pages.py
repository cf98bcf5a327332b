"""Pages a person opens in a browser: sign in with a token, the jobs list, one page per job
that follows it live (``service.api.page_html``). Server-rendered from the same store and
status as the REST API; the job page's script reads that API with the session cookie.

- ``GET /``: the signed-in owner's jobs (state, stage, progress, age), else the sign-in form.
- ``POST /signin`` (form field ``token``): sets the session cookie (the token itself,
  ``HttpOnly``, ``SameSite=Strict``, ``Secure`` over https) and goes to ``/``; a wrong token
  answers 401 with the form again, a form from another site's page 403.
- ``POST /signout`` (form field ``csrf``): clears the cookie.
- ``GET /jobs/{job_id}``: the job's page; another owner's job, or none, is a 404 page.

Every page is sent with a Content-Security-Policy that allows only the service itself and
the page's own script and style (by nonce): nothing is fetched from outside. The pages are
not part of the REST API's OpenAPI document.
"""

from __future__ import annotations

import hmac
import secrets
from html import escape
from typing import Annotated
from urllib.parse import parse_qs, urlsplit

from fastapi import APIRouter, Depends, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import HTMLResponse, RedirectResponse, Response
from gaitforge.service.api import page_html
from gaitforge.service.api.auth import SESSION_COOKIE, csrf_token, owner_of, session_owner
from gaitforge.service.api.deps import JobId, app_store
from gaitforge.service.api.schemas import job_status

router = APIRouter(include_in_schema=False)

JOBS_SHOWN = 200
"""the newest jobs the list shows"""
FORM_LIMIT_BYTES = 4096
"""a sign-in or sign-out form's body at most"""

PageOwner = Annotated[str | None, Depends(session_owner)]


def _session_csrf(request: Request) -> str:
    """The CSRF token of the request's session (a signed-in page's)."""
    return csrf_token(request, request.cookies[SESSION_COOKIE])


def _page(
    title: str, body: str, nonce: str, owner: str | None, csrf: str = "", status: int = 200
) -> HTMLResponse:
    """``body`` in the layout (``owner`` signed in, their session's ``csrf`` in its sign-out
    form), with the headers every page carries."""
    html = page_html.layout(title, body, nonce, owner, csrf)
    response = HTMLResponse(html, status_code=status)
    response.headers.update(
        {
            "Content-Security-Policy": (
                f"default-src 'self'; script-src 'nonce-{nonce}'; style-src 'nonce-{nonce}'; "
                "img-src 'self' data:; media-src 'self'; connect-src 'self'; "
                "frame-ancestors 'none'; form-action 'self'; base-uri 'none'"
            ),
            "X-Content-Type-Options": "nosniff",
            "Referrer-Policy": "same-origin",
            "Cache-Control": "no-store",
        }
    )
    return response


@router.get("/", response_class=HTMLResponse)
async def jobs_page(request: Request, owner: PageOwner) -> HTMLResponse:
    """The owner's jobs, newest first; the sign-in form without a session."""
    nonce = secrets.token_urlsafe(16)
    if owner is None:
        return _page("sign in", page_html.sign_in_body(), nonce, None)
    records, _ = await run_in_threadpool(app_store(request).list, owner, None, 0, JOBS_SHOWN)
    jobs = [job_status(record) for record in records]
    csrf = _session_csrf(request)
    return _page("jobs", page_html.jobs_body(jobs, csrf, nonce), nonce, owner, csrf)


@router.post("/signin")
async def sign_in(request: Request) -> Response:
    """Check the form's token; set the session cookie and go to the jobs list. A form sent
    from another site's page is refused (its ``Origin`` is not this service): no signing a
    person in as someone else."""
    if _cross_site(request):
        return Response("sign in from the service's own page", status_code=403)
    token = (await _form(request)).get("token", "")
    owner = owner_of(token, request.app.state.tokens) if token else None
    if owner is None:
        body = page_html.sign_in_body("unknown token")
        return _page("sign in", body, secrets.token_urlsafe(16), None, status=401)
    response = RedirectResponse("/", status_code=303)
    response.set_cookie(
        SESSION_COOKIE,
        token,
        httponly=True,
        samesite="strict",
        secure=request.url.scheme == "https",
        path="/",
    )
    return response


@router.post("/signout")
async def sign_out(request: Request) -> Response:
    """Clear the session cookie (the form carries the session's CSRF token)."""
    session = request.cookies.get(SESSION_COOKIE)
    given = (await _form(request)).get("csrf", "")
    if session is None or not hmac.compare_digest(
        given.encode(), csrf_token(request, session).encode()
    ):
        return Response("sign-out needs the page's form", status_code=403)
    response = RedirectResponse("/", status_code=303)
    response.delete_cookie(SESSION_COOKIE, path="/")
    return response


@router.get("/jobs/{job_id}", response_class=HTMLResponse)
async def job_page(job_id: JobId, request: Request, owner: PageOwner) -> Response:
    """The job's page, for its owner; a 404 page for any other job id."""
    if owner is None:
        return RedirectResponse("/", status_code=303)
    nonce, csrf = secrets.token_urlsafe(16), _session_csrf(request)
    record = await run_in_threadpool(app_store(request).get, job_id, owner)
    if record is None:
        body = f"<h2>No job {escape(job_id)}</h2>"
        return _page("no such job", body, nonce, owner, csrf, status=404)
    body = page_html.job_body(job_status(record), csrf, nonce)
    return _page(record.name, body, nonce, owner, csrf)


def _cross_site(request: Request) -> bool:
    """The request's ``Origin`` names another host than the one it was sent to, or hides it
    (``null``: the pages' ``Referrer-Policy: same-origin`` lets their own forms send it)."""
    origin = request.headers.get("origin")
    return origin is not None and urlsplit(origin).netloc != request.headers.get("host")


async def _form(request: Request) -> dict[str, str]:
    """The request's urlencoded form, one value a field (a body over ``FORM_LIMIT_BYTES``
    reads as empty)."""
    body = await request.body()
    if len(body) > FORM_LIMIT_BYTES:
        return {}
    fields = parse_qs(body.decode("utf-8", "replace"), keep_blank_values=True)
    return {name: values[0] for name, values in fields.items()}
