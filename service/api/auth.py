"""Authentication: each token belongs to an owner; compared in constant time.

Tokens come from the settings (``tokens``, ``tokens_file``). With none configured the
service uses one token for the owner ``local``, generated once into ``{home}/token``
(mode 0600), where the CLI client finds it.

A request carries its token as ``Authorization: Bearer <token>``, or, from the pages a
person opens in a browser (``service.api.pages``), in the session cookie that signing in
sets (``HttpOnly``, ``SameSite=Strict``). A request that changes something (not GET or
HEAD) on a cookie alone must also carry the session's CSRF token in ``X-CSRF-Token``
(:func:`csrf_token`; the pages put it in their forms and requests): a cross-site form or
script can send neither.
"""

from __future__ import annotations

import hmac
import logging
import os
import secrets
from typing import Annotated

from fastapi import Request, Security
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from gaitforge.service.api.problems import ProblemError
from gaitforge.service.private_files import make_private_dir
from gaitforge.service.settings import LOCAL_OWNER, ServiceSettings

logger = logging.getLogger(__name__)

bearer = HTTPBearer(
    auto_error=False,
    scheme_name="bearer",
    description="`Authorization: Bearer <token>`; each token belongs to one owner",
)
_CHALLENGE = 'Bearer realm="gaitforge"'
SESSION_COOKIE = "gaitforge_session"
CSRF_HEADER = "X-CSRF-Token"
READ_ONLY_METHODS = frozenset({"GET", "HEAD"})


def load_tokens(settings: ServiceSettings) -> dict[str, str]:
    """token -> owner: the configured tokens, else the local token (generated if missing).

    Raises:
        ValueError: a malformed token entry (naming ``tokens`` or the file and line).
    """
    tokens = settings.token_map()
    if tokens:
        return tokens
    return {local_token(settings): LOCAL_OWNER}


def local_token(settings: ServiceSettings) -> str:
    """The token in ``settings.token_file``, written there (mode 0600) if it does not exist."""
    path = settings.token_file
    if path.exists():
        token = path.read_text().strip()
        if token:
            return token
    make_private_dir(path.parent)
    token = secrets.token_urlsafe(32)
    tmp = path.with_name(f".{path.name}.{os.getpid()}")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w") as f:
        f.write(token + "\n")
    os.replace(tmp, path)
    logger.info("generated a token for owner %r in %s", LOCAL_OWNER, path)
    return token


def owner_of(token: str, tokens: dict[str, str]) -> str | None:
    """The owner of ``token``, comparing it with every configured token (no early exit)."""
    given = token.encode()
    found = None
    for known, owner in tokens.items():
        if hmac.compare_digest(given, known.encode()):
            found = owner
    return found


Credentials = Annotated[HTTPAuthorizationCredentials | None, Security(bearer)]


def csrf_token(request: Request, session: str) -> str:
    """The CSRF token of a cookie session (its token ``session``): a keyed hash, with the
    app's key (:func:`new_csrf_key`, made anew at each start)."""
    key: bytes = request.app.state.csrf_key
    return hmac.new(key, session.encode(), "sha256").hexdigest()


def new_csrf_key() -> bytes:
    """A fresh key for :func:`csrf_token`."""
    return secrets.token_bytes(32)


def session_owner(request: Request) -> str | None:
    """The owner of the request's session cookie, or None (no cookie, or an unknown token)."""
    session = request.cookies.get(SESSION_COOKIE)
    return None if session is None else owner_of(session, request.app.state.tokens)


async def require_owner(request: Request, credentials: Credentials) -> str:
    """Dependency: the owner of the request's bearer token or session cookie, else 401 with
    a challenge; a cookie session's request that changes something needs its CSRF token
    too, else 403 (async: it only compares strings, no thread-pool hop)."""
    if credentials is None:
        return _cookie_owner(request)
    owner = owner_of(credentials.credentials, request.app.state.tokens)
    if owner is None:
        raise ProblemError(
            401,
            "unknown bearer token",
            headers={"WWW-Authenticate": f'{_CHALLENGE}, error="invalid_token"'},
        )
    return owner


def _cookie_owner(request: Request) -> str:
    """The owner of the request's session cookie (see :func:`require_owner`)."""
    session = request.cookies.get(SESSION_COOKIE)
    if session is None:
        raise ProblemError(401, "missing bearer token", headers={"WWW-Authenticate": _CHALLENGE})
    owner = owner_of(session, request.app.state.tokens)
    if owner is None:
        raise ProblemError(
            401, "unknown session: sign in again", headers={"WWW-Authenticate": _CHALLENGE}
        )
    if request.method not in READ_ONLY_METHODS:
        given = request.headers.get(CSRF_HEADER, "")
        if not hmac.compare_digest(given.encode(), csrf_token(request, session).encode()):
            raise ProblemError(403, f"a signed-in browser's request needs its {CSRF_HEADER}")
    return owner
