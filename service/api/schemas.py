"""The API's response models (each with an example) and :func:`job_status`, which builds a
job's status from its store record and the progress the runner copied into it."""

from __future__ import annotations

import json
import logging
from datetime import UTC, datetime
from typing import Any, Literal

from gaitforge.service.jobs.progress import JobProgress, StageProgress
from gaitforge.service.store import JobRecord
from pydantic import BaseModel, ConfigDict, Field, ValidationError

logger = logging.getLogger(__name__)

_T0 = "2026-11-22T21:40:00Z"
_STATUS_EXAMPLE: dict[str, Any] = {
    "id": "j-0123456789ab",
    "name": "stand-2d",
    "state": "running",
    "phase": "training",
    "stage": {
        "index": 0,
        "name": "stand-2d",
        "scene": "stand-2d",
        "count": 1,
        "env_steps": 122880,
        "budget_env_steps": 5000000,
        "promote": [
            {
                "rule": "survival >= 0.95 over 100 episodes",
                "metric": "survival",
                "op": ">=",
                "target": 0.95,
                "window": 100,
                "episodes": 100,
                "value": 0.41,
                "passing": False,
            }
        ],
    },
    "iteration": 30,
    "env_steps": 122880,
    "steps_per_s": 2150.0,
    "metrics": {
        "return": 41.2,
        "speed": 0.02,
        "fall_rate": 0.59,
        "survival": 0.41,
        "reward_terms": {"alive": 1.0, "effort": -0.12},
    },
    "health": {"nan_state": 0, "unstable": 1},
    "error": None,
    "cancel_requested": False,
    "attempt": 1,
    "latest_checkpoint": "ckpt-000000122880",
    "created_at": _T0,
    "started_at": "2026-11-22T21:40:02Z",
    "finished_at": None,
    "updated_at": "2026-11-22T21:41:00Z",
    "progress_age_s": 0.8,
    "links": {"self": "/v1/jobs/j-0123456789ab", "events": "/v1/jobs/j-0123456789ab/events"},
    "actions": [{"name": "cancel", "method": "POST", "href": "/v1/jobs/j-0123456789ab/cancel"}],
}


def _examples(*examples: dict[str, Any]) -> ConfigDict:
    return ConfigDict(json_schema_extra={"examples": list(examples)})


class Action(BaseModel):
    """Something the caller may do to the job now."""

    name: Literal["cancel", "resume"]
    method: Literal["POST"] = "POST"
    href: str


class JobStatus(BaseModel):
    """Where a job stands: state, stage and promotion progress, speed, metrics, errors."""

    model_config = _examples(_STATUS_EXAMPLE)

    id: str = Field(description="j- and 12 hex digits")
    name: str = Field(description="the job spec's name")
    state: Literal["queued", "running", "succeeded", "failed", "cancelled"]
    phase: str | None = Field(
        default=None, description="the trainer's phase: starting, training, evaluating, ..."
    )
    stage: StageProgress | None = Field(
        default=None, description="the current curriculum stage and its promotion rules"
    )
    iteration: int | None = Field(default=None, description="PPO iterations done")
    env_steps: int = Field(default=0, description="env steps sampled in the whole job")
    steps_per_s: float | None = Field(default=None, description="env steps per second, recent")
    metrics: dict[str, Any] = Field(
        default_factory=dict,
        description="latest episode metrics: return, distance, speed (m/s), fall_rate, "
        "survival, length (s), reward_terms, lr, losses",
    )
    health: dict[str, Any] = Field(
        default_factory=dict, description="simulator health counters (cause -> episodes)"
    )
    error: str | None = Field(default=None, description="why it failed (one line)")
    cancel_requested: bool = False
    attempt: int = Field(description="0 until first started; +1 per start or resume")
    latest_checkpoint: str | None = Field(default=None, description="newest checkpoint's name")
    created_at: datetime
    started_at: datetime | None = None
    finished_at: datetime | None = None
    updated_at: datetime
    progress_age_s: float | None = Field(
        default=None, description="s since the trainer last wrote its progress"
    )
    links: dict[str, str] = Field(description="related resources (paths)")
    actions: list[Action] = Field(description="what may be done to the job now")


class JobList(BaseModel):
    """One page of the caller's jobs, newest first."""

    model_config = _examples({"items": [_STATUS_EXAMPLE], "total": 1, "offset": 0, "limit": 50})

    items: list[JobStatus]
    total: int = Field(description="jobs matching the filter, over all pages")
    offset: int
    limit: int


class MetricsSeries(BaseModel):
    """Per-iteration metrics (metrics.jsonl) after iteration ``since``."""

    model_config = _examples(
        {
            "job_id": "j-0123456789ab",
            "since": 0,
            "points": [{"iteration": 1, "env_steps": 4096, "return": 12.5, "survival": 0.1}],
            "last_iteration": 1,
        }
    )

    job_id: str
    since: int | None = Field(description="only iterations after this one (None: all)")
    points: list[dict[str, Any]] = Field(description="one object per iteration, in order")
    last_iteration: int | None = Field(description="give as since to get only newer points")


class Artifact(BaseModel):
    """A downloadable file of a job."""

    name: str
    kind: Literal["checkpoints", "recordings", "reports"]
    size_bytes: int = Field(description="bytes (a checkpoint: its files, before zipping)")
    modified_at: datetime
    media_type: str = Field(description="what the download is: application/zip, video/mp4, ...")
    href: str = Field(description="the download's path")


class ArtifactList(BaseModel):
    """A job's checkpoints, recordings or evaluation reports, oldest first."""

    model_config = _examples(
        {
            "job_id": "j-0123456789ab",
            "kind": "checkpoints",
            "items": [
                {
                    "name": "ckpt-000000122880",
                    "kind": "checkpoints",
                    "size_bytes": 61234,
                    "modified_at": _T0,
                    "media_type": "application/zip",
                    "href": "/v1/jobs/j-0123456789ab/checkpoints/ckpt-000000122880",
                }
            ],
        }
    )

    job_id: str
    kind: Literal["checkpoints", "recordings", "reports"]
    items: list[Artifact]


class LogChunk(BaseModel):
    """Bytes ``offset`` to ``next_offset`` of the job's log, as text."""

    model_config = _examples(
        {"offset": 0, "next_offset": 42, "text": "iteration 1: return 12.5\n", "eof": False}
    )

    offset: int
    next_offset: int = Field(description="give as offset to read on")
    text: str = Field(description="UTF-8 (bad bytes replaced); never splits a character")
    eof: bool = Field(description="the job has ended and this is the end of its log")


class Health(BaseModel):
    """The service is up, and where the Ray that runs its jobs stands."""

    model_config = _examples({"status": "ok", "version": "0.1.0", "ray": "ok"})

    status: Literal["ok"] = "ok"
    version: str
    ray: Literal["ok", "restarting", "unreachable"] | None = Field(
        default=None,
        description="ok; restarting: the local Ray head died, its running jobs failed "
        "(resumable) and a new head starts; unreachable: Ray's GCS or jobs API does not "
        "answer (queued jobs wait; running ones fail after ray_lost_after_s); null: no job "
        "runner yet",
    )


def read_record_progress(record: JobRecord) -> JobProgress | None:
    """The progress the runner copied into ``record`` (None: none yet or unreadable)."""
    if not record.progress_json:
        return None
    try:
        return JobProgress.model_validate_json(record.progress_json)
    except (ValidationError, ValueError) as exc:
        logger.warning("job %s: unreadable progress: %s", record.id, exc)
        return None


def job_status(record: JobRecord, now: datetime | None = None) -> JobStatus:
    """The API's view of ``record`` (its progress included)."""
    progress = read_record_progress(record)
    base = f"/v1/jobs/{record.id}"
    links = {"self": base}
    links.update({k: f"{base}/{k}" for k in ("metrics", "events", "logs")})
    links.update({k: f"{base}/{k}" for k in ("checkpoints", "recordings", "reports")})
    checkpoint = progress.checkpoint if progress else None
    if checkpoint:
        links["latest_checkpoint"] = f"{base}/checkpoints/{checkpoint}"
    actions = []
    if record.state in ("queued", "running"):
        actions.append(Action(name="cancel", href=f"{base}/cancel"))
    elif record.state in ("failed", "cancelled"):
        actions.append(Action(name="resume", href=f"{base}/resume"))
    metrics = dict(progress.metrics) if progress else {}
    health = metrics.pop("health", None) or {}
    age = None
    if progress is not None:
        now = now or datetime.now(UTC)
        age = max(0.0, (now - progress.updated_at).total_seconds())
    return JobStatus(
        id=record.id,
        name=record.name,
        state=record.state,  # type: ignore[arg-type]
        phase=progress.phase if progress else None,
        stage=progress.stage if progress else None,
        iteration=progress.iteration if progress else None,
        env_steps=progress.env_steps if progress else 0,
        steps_per_s=progress.steps_per_s if progress else None,
        metrics=metrics,
        health=health if isinstance(health, dict) else {},
        error=record.error or (progress.error if progress else None),
        cancel_requested=record.cancel_requested,
        attempt=record.attempt,
        latest_checkpoint=checkpoint,
        created_at=record.created_at,
        started_at=record.started_at,
        finished_at=record.finished_at,
        updated_at=record.updated_at,
        progress_age_s=age,
        links=links,
        actions=actions,
    )


def status_json(status: JobStatus) -> str:
    """``status`` as JSON without its times of writing (to tell whether anything changed)."""
    content = status.model_dump(mode="json", exclude={"progress_age_s", "updated_at"})
    return json.dumps(content, sort_keys=True)
