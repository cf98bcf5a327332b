"""The FastAPI app: routes, the pages for people, bearer and cookie auth, problem+json
errors, the body size limit, and a lifespan that opens the store, connects Ray and runs the
job runner (unless given one)."""

from __future__ import annotations

import ipaddress
import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from importlib import metadata
from typing import TYPE_CHECKING

from fastapi import Depends, FastAPI
from fastapi.concurrency import run_in_threadpool
from gaitforge.service.api import events, pages, routes_artifacts, routes_jobs, routes_scenes
from gaitforge.service.api.auth import load_tokens, new_csrf_key
from gaitforge.service.api.deps import known_query
from gaitforge.service.api.limits import BodyLimits
from gaitforge.service.api.openapi import build_openapi
from gaitforge.service.api.problems import install_problem_handlers
from gaitforge.service.api.schemas import Health
from gaitforge.service.settings import ServiceSettings

if TYPE_CHECKING:
    from gaitforge.service.jobs.runner import JobRunner

logger = logging.getLogger(__name__)

DESCRIPTION = """Submit training jobs (validated specs: catalogue scenes or inline scenes,
never code or paths), follow them live, download checkpoints, recordings and evaluation
reports. Every endpoint but `/healthz` and the documentation (`/openapi.json`, `/docs`) needs
`Authorization: Bearer <token>`; a job is its token owner's only (another owner's job answers
404). Errors are `application/problem+json`. Paths are exact: a trailing slash is a 404, never
a redirect. A person signs in at `/` (the token in a session cookie) and follows jobs on
pages that read this API."""
TAGS = [
    {"name": "jobs", "description": "submit, list, follow, cancel and resume training jobs"},
    {"name": "artifacts", "description": "a job's checkpoints, recordings and reports"},
    {"name": "scenes", "description": "the scene catalogue and compile reports"},
    {"name": "service", "description": "liveness"},
]


def _version() -> str:
    try:
        return metadata.version("gaitforge")
    except metadata.PackageNotFoundError:
        return "0.0.0"


def check_exposure(settings: ServiceSettings) -> None:
    """Refuse to listen beyond loopback without configured tokens.

    Raises:
        ValueError: naming ``host``.
    """
    if settings.configured_tokens():
        return
    host = settings.host
    try:
        loopback = host == "localhost" or ipaddress.ip_address(host).is_loopback
    except ValueError:
        loopback = False
    if not loopback:
        raise ValueError(
            f"host: {host!r} is beyond loopback; configure tokens (GAITFORGE_TOKENS or "
            "GAITFORGE_TOKENS_FILE) to listen there"
        )


def _start_runner(settings: ServiceSettings) -> JobRunner:
    from gaitforge.service.jobs.ray_cluster import connect_ray
    from gaitforge.service.jobs.runner import JobRunner
    from gaitforge.service.store import open_store

    store = open_store(settings.db_url)
    runner = JobRunner(settings, store, connect_ray(settings))
    runner.start()
    return runner


def create_app(settings: ServiceSettings | None = None, runner: JobRunner | None = None) -> FastAPI:
    """The service's app. Without ``runner`` its lifespan opens the store, connects Ray (a
    local head unless ``ray_address``) and starts a runner, stopping it at shutdown; a given
    runner (tests) is used as it is, and its store with it.

    Raises:
        ValueError: a malformed token entry, or a non-loopback host without tokens.
    """
    settings = settings or ServiceSettings()
    check_exposure(settings)
    tokens = load_tokens(settings)

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        if runner is not None:
            yield
            return
        started = await run_in_threadpool(_start_runner, settings)
        app.state.runner, app.state.store = started, started.store
        try:
            yield
        finally:
            await run_in_threadpool(started.stop)
            started.store.close()

    app = FastAPI(
        title="gaitforge",
        version=_version(),
        description=DESCRIPTION,
        openapi_tags=TAGS,
        lifespan=lifespan,
        dependencies=[Depends(known_query)],
        redoc_url=None,
        swagger_ui_oauth2_redirect_url=None,
        redirect_slashes=False,
    )
    app.state.settings, app.state.tokens = settings, tokens
    app.state.csrf_key = new_csrf_key()
    if runner is not None:
        app.state.runner, app.state.store = runner, runner.store
    install_problem_handlers(app)
    app.add_middleware(
        BodyLimits, max_bytes=settings.max_body_bytes, timeout_s=settings.body_timeout_s
    )
    for module in (routes_jobs, events, routes_artifacts, routes_scenes, pages):
        app.include_router(module.router)

    @app.get("/healthz", response_model=Health, tags=["service"], summary="Liveness")
    async def healthz() -> Health:
        """The service is up, and where Ray stands as the job runner last found it (no auth,
        touches nothing; 200 even while Ray is down: the service itself is up)."""
        runner = getattr(app.state, "runner", None)
        return Health(version=app.version, ray=runner.ray_state if runner is not None else None)

    app.openapi = lambda: build_openapi(app)  # type: ignore[method-assign]
    return app
