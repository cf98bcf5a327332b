"""Dependencies of the routes: the owner's job (404 when missing or another owner's), its
directory, the runner and the store from the app's state."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Any

from fastapi import Depends, Path, Request
from gaitforge.service.api.auth import bearer, require_owner
from gaitforge.service.api.problems import FieldError, ProblemError
from gaitforge.service.jobs.layout import JobLayout
from gaitforge.service.settings import ServiceSettings
from gaitforge.service.store import JobRecord, JobStore

if TYPE_CHECKING:
    from gaitforge.service.jobs.runner import JobRunner

Owner = Annotated[str, Depends(require_owner)]
"""the authenticated caller (401 without a known bearer token)"""

JobId = Annotated[str, Path(max_length=64, description="the job's id (j- and 12 hex digits)")]


def app_settings(request: Request) -> ServiceSettings:
    """The service's settings."""
    return request.app.state.settings


def app_store(request: Request) -> JobStore:
    """The job store."""
    return request.app.state.store


def app_runner(request: Request) -> JobRunner:
    """The job runner."""
    return request.app.state.runner


async def known_query(request: Request) -> None:
    """Dependency of every route: a query parameter the route does not take is a 422 (a
    misspelt ``stat=queued`` would otherwise be ignored). On a route that needs a token,
    the caller is authenticated first: without a known token the answer is the 401, which
    tells nothing about the route's parameters (an app's dependencies run before the
    route's own)."""
    route = request.scope.get("route")
    if route is None or not request.query_params:
        return
    allowed = _query_names(route.dependant)
    unknown = sorted(set(request.query_params) - allowed)
    if unknown:
        if _needs_owner(route.dependant):
            await require_owner(request, await bearer(request))  # 401 without a known token
        message = f"unknown query parameter; allowed: {sorted(allowed) or 'none'}"
        errors = [FieldError(field=name, message=message) for name in unknown]
        raise ProblemError(422, f"{unknown[0]}: {message}", errors=errors)


def _query_names(dependant: Any) -> set[str]:
    """The query parameters ``dependant`` and its dependencies take."""
    names = {p.alias for p in dependant.query_params}
    for sub in dependant.dependencies:
        names |= _query_names(sub)
    return names


def _needs_owner(dependant: Any) -> bool:
    """``dependant`` or one of its dependencies authenticates the caller."""
    return any(sub.call is require_owner or _needs_owner(sub) for sub in dependant.dependencies)


def missing_job(job_id: str) -> ProblemError:
    """The 404 for a job that does not exist or is another owner's (the same answer)."""
    return ProblemError(404, f"no job {job_id}")


def owned_job(job_id: JobId, owner: Owner, request: Request) -> JobRecord:
    """The caller's job ``job_id`` (sync: runs in the thread pool)."""
    record = app_store(request).get(job_id, owner=owner)
    if record is None:
        raise missing_job(job_id)
    return record


OwnedJob = Annotated[JobRecord, Depends(owned_job)]


def job_layout(job: OwnedJob, request: Request) -> JobLayout:
    """The directory of the caller's job."""
    return JobLayout(app_settings(request).artifacts, job.id)


Layout = Annotated[JobLayout, Depends(job_layout)]
