"""Dependencies of the routes: the owner's job (404 when missing or another owner's), its
directory, the runner and the store from the app's state."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated

from fastapi import Depends, Path, Request
from gaitforge.service.api.auth import require_owner
from gaitforge.service.api.problems import ProblemError
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
