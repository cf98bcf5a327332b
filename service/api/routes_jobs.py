"""``/v1/jobs``: submit (JSON or YAML), list, status, metrics, logs, cancel, resume.

Handlers that touch the database or the disk are plain ``def`` (FastAPI runs them in its
thread pool), so the event loop never waits on SQLite, Ray or files.
"""

from __future__ import annotations

import logging
from typing import Annotated

import yaml
from fastapi import APIRouter, Query, Request, Response
from fastapi.concurrency import run_in_threadpool
from gaitforge.service.api.deps import (
    Layout,
    OwnedJob,
    Owner,
    app_runner,
    app_settings,
    app_store,
    missing_job,
)
from gaitforge.service.api.files import NotServed, read_log, read_metrics
from gaitforge.service.api.problems import ProblemError, problem_responses
from gaitforge.service.api.schemas import JobList, JobStatus, LogChunk, MetricsSeries, job_status
from gaitforge.service.api.submission import (
    JSON_TYPES,
    YAML_TYPES,
    invalid_spec,
    parse_body,
)
from gaitforge.service.jobs.runner import JobStateError, LimitError
from gaitforge.service.ops import SpecError
from gaitforge.service.store import TERMINAL, JobRecord, JobState

logger = logging.getLogger(__name__)
router = APIRouter(prefix="/v1/jobs", tags=["jobs"], responses=problem_responses(401))
JOB_ERRORS = problem_responses(404, 422)

EXAMPLE_JOB = {
    "name": "stand-2d-short",
    "backend": "mujoco",
    "ppo": {"batch_env_steps": 2048, "minibatch_size": 512},
    "workers": {"num_workers": 1, "envs_per_worker": 4, "fragment_length": 128},
    "checkpoint": {"every_iters": 1},
    "stages": [{"scene": "stand-2d", "env_steps": 8192, "promote": "survival >= 0.95 over 50"}],
}
EXAMPLE_YAML = """name: stand-2d-short
backend: mujoco
workers: {num_workers: 1, envs_per_worker: 4}
stages:
  - scene: stand-2d
    env_steps: 8192
    promote: "survival >= 0.95 over 50"
"""
_JOB_SCHEMA = {"$ref": "#/components/schemas/Job"}
_SUBMIT_BODY = {
    "required": True,
    "description": "the job spec (the job file's schema) as JSON, or as the YAML of a job "
    "file (`application/yaml` or `text/yaml`), e.g.\n\n```yaml\n"
    + EXAMPLE_YAML
    + "```\n\nA stage's scene is a catalogue name or an inline scene; no paths, no code. "
    "YAML is the job's data: its documented schema and example are the mapping it parses to.",
    "content": {
        **{media: {"schema": _JOB_SCHEMA, "example": EXAMPLE_JOB} for media in JSON_TYPES},
        **{
            media: {"schema": _JOB_SCHEMA, "example": yaml.safe_load(EXAMPLE_YAML)}
            for media in YAML_TYPES[:2]
        },
    },
}


@router.post(
    "",
    status_code=201,
    response_model=JobStatus,
    summary="Submit a job",
    responses={
        201: {
            "description": "queued; its status",
            "headers": {"Location": {"description": "the job's URL", "schema": {"type": "string"}}},
        },
        **problem_responses(413, 415, 422, 429),
    },
    openapi_extra={"requestBody": _SUBMIT_BODY},
)
async def submit_job(request: Request, response: Response, owner: Owner) -> JobStatus:
    """Validate the job spec and queue it; 201 with its status (``Location``: its URL)."""
    body = await request.body()  # the size limit applies as it arrives
    settings = app_settings(request)
    spec = await run_in_threadpool(
        parse_body,
        body,
        request.headers.get("content-type"),
        settings.max_body_depth,
        settings.max_number_chars,
    )
    runner = app_runner(request)
    try:
        record = await run_in_threadpool(runner.submit, owner, spec)
    except SpecError as exc:
        raise invalid_spec(exc) from None
    except LimitError as exc:
        raise ProblemError(429, str(exc), type="urn:gaitforge:problem:job-limit") from None
    response.headers["Location"] = f"/v1/jobs/{record.id}"
    return job_status(record)


@router.get("", response_model=JobList, summary="List jobs", responses=problem_responses(422))
def list_jobs(
    request: Request,
    owner: Owner,
    state: Annotated[JobState | None, Query(description="only jobs in this state")] = None,
    offset: Annotated[int, Query(ge=0, le=1_000_000_000, description="jobs to skip")] = 0,
    limit: Annotated[int, Query(ge=1, le=200, description="jobs per page")] = 50,
) -> JobList:
    """The caller's jobs, newest first, a page at a time."""
    records, total = app_store(request).list(owner, state=state, offset=offset, limit=limit)
    return JobList(items=[job_status(r) for r in records], total=total, offset=offset, limit=limit)


@router.get("/{job_id}", response_model=JobStatus, summary="Job status", responses=JOB_ERRORS)
def get_job(job: OwnedJob) -> JobStatus:
    """State, stage and promotion progress, env steps, steps/s, metrics, health, error."""
    return job_status(job)


@router.get(
    "/{job_id}/metrics",
    response_model=MetricsSeries,
    summary="Metrics per iteration",
    responses=JOB_ERRORS,
)
def get_metrics(
    job: OwnedJob,
    layout: Layout,
    since: Annotated[
        int | None, Query(ge=0, le=1_000_000_000, description="only iterations after this one")
    ] = None,
    limit: Annotated[int, Query(ge=1, le=100_000, description="points at most")] = 10_000,
) -> MetricsSeries:
    """The job's metrics, one point per PPO iteration (for plotting); page on with
    ``since=last_iteration``."""
    try:
        points = read_metrics(layout.dir, layout.metrics_file, since)[:limit]
    except NotServed as exc:
        raise _not_served(job.id, "metrics", exc) from None
    last = points[-1].get("iteration") if points else since
    return MetricsSeries(job_id=job.id, since=since, points=points, last_iteration=last)


@router.get("/{job_id}/logs", response_model=LogChunk, summary="Job log", responses=JOB_ERRORS)
def get_logs(
    job: OwnedJob,
    layout: Layout,
    offset: Annotated[int, Query(ge=0, le=1 << 50, description="byte to start at")] = 0,
    limit: Annotated[int, Query(ge=1, le=1 << 20, description="bytes to read at most")] = 65536,
) -> LogChunk:
    """Bytes of the trainer's log from ``offset``; follow by asking again at ``next_offset``
    until ``eof``."""
    ended = job.state in TERMINAL  # looked at before reading: the log is whole then
    try:
        text, next_offset, at_end = read_log(layout.dir, layout.log_file, offset, limit)
    except NotServed as exc:
        raise _not_served(job.id, "log", exc) from None
    return LogChunk(offset=offset, next_offset=next_offset, text=text, eof=ended and at_end)


def _not_served(job_id: str, what: str, exc: NotServed) -> ProblemError:
    """The 404 for a job file that is a link (or under one): logged, never read."""
    logger.warning("job %s: %s", job_id, exc)
    return ProblemError(404, f"job {job_id}'s {what} is not a plain file; not served")


@router.post(
    "/{job_id}/cancel",
    response_model=JobStatus,
    summary="Cancel a job",
    responses=problem_responses(404, 409, 422),
)
def cancel_job(job: OwnedJob, owner: Owner, request: Request) -> JobStatus:
    """A queued job is cancelled at once; a running one stops cleanly after its iteration,
    keeping a final checkpoint (state ``cancelled`` once it has)."""
    return job_status(_act(request, "cancel", job.id, owner))


@router.post(
    "/{job_id}/resume",
    response_model=JobStatus,
    summary="Resume a job",
    responses=problem_responses(404, 409, 422),
)
def resume_job(job: OwnedJob, owner: Owner, request: Request) -> JobStatus:
    """A failed or cancelled job with a checkpoint is queued again, to go on from it."""
    return job_status(_act(request, "resume", job.id, owner))


def _act(request: Request, action: str, job_id: str, owner: str) -> JobRecord:
    """``runner.cancel`` or ``runner.resume``: 409 when the job's state does not allow it."""
    runner = app_runner(request)
    try:
        record = getattr(runner, action)(job_id, owner)
    except LimitError as exc:
        raise ProblemError(429, str(exc), type="urn:gaitforge:problem:job-limit") from None
    except JobStateError as exc:
        raise ProblemError(409, str(exc)) from None
    if record is None:
        raise missing_job(job_id)
    return record
