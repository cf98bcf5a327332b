"""``GET /v1/jobs/{id}/events``: a job's progress as server-sent events.

A ``progress`` event (the JobStatus as JSON) at once and whenever the status changes,
looked at every ``poll_interval_s``; ``: ping`` comments keep a quiet stream alive; when the
job reaches a terminal state, its last ``progress`` and an ``end`` event (the same final
JobStatus), and the stream closes.
"""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator

from fastapi import APIRouter, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.sse import EventSourceResponse, ServerSentEvent
from gaitforge.service.api.deps import OwnedJob, app_settings, app_store
from gaitforge.service.api.problems import problem_responses
from gaitforge.service.api.schemas import JobStatus, job_status, status_json
from gaitforge.service.store import TERMINAL

router = APIRouter(prefix="/v1/jobs", tags=["jobs"], responses=problem_responses(401))
HEARTBEAT_S = 15.0
"""s of silence after which a ``: ping`` comment is sent (``app.state.heartbeat_s`` if set)"""

EVENT_ITEM_SCHEMA = {
    "type": "object",
    "description": "one event of the stream (`: ping` comments aside)",
    "required": ["event", "data"],
    "properties": {
        "event": {"type": "string", "enum": ["progress", "end"]},
        "data": {
            "type": "string",
            "description": "the job's status, as JSON",
            "contentMediaType": "application/json",
            "contentSchema": {"$ref": "#/components/schemas/JobStatus"},
        },
    },
    "additionalProperties": False,
}
"""each event as OpenAPI 3.2's ``itemSchema`` describes a stream's items"""
_EVENTS_DOC = {
    200: {
        "description": "`event: progress` with a JobStatus as `data` whenever it changes, "
        "`: ping` comments while nothing does, and a final `event: end` (the last JobStatus)",
        "content": {
            "text/event-stream": {
                "schema": {
                    "type": "array",
                    "description": "the stream read as its events in order (OpenAPI 3.2: "
                    "schema covers the stream, itemSchema each event)",
                    "items": EVENT_ITEM_SCHEMA,
                    "minItems": 1,
                },
                "itemSchema": EVENT_ITEM_SCHEMA,
                "example": 'event: progress\ndata: {"id": "j-0123456789ab", "state": "running"}'
                '\n\n: ping\n\nevent: end\ndata: {"id": "j-0123456789ab", "state": "succeeded"}'
                "\n\n",
            }
        },
    },
    **problem_responses(404, 422),
}


@router.get(
    "/{job_id}/events",
    response_class=EventSourceResponse,
    summary="Follow a job",
    responses=_EVENTS_DOC,
)
async def job_events(job: OwnedJob, request: Request) -> AsyncIterator[ServerSentEvent]:
    """The job's status as server-sent events until it ends."""
    store = app_store(request)
    interval = app_settings(request).poll_interval_s
    heartbeat = getattr(request.app.state, "heartbeat_s", HEARTBEAT_S)
    record, last, quiet = job, "", 0.0
    while True:
        status = job_status(record)
        text = status_json(status)
        if text != last:
            yield ServerSentEvent(event="progress", data=_dump(status))
            last, quiet = text, 0.0
        if record.state in TERMINAL:
            yield ServerSentEvent(event="end", data=_dump(status))
            return
        if quiet >= heartbeat:
            yield ServerSentEvent(comment="ping")
            quiet = 0.0
        if await request.is_disconnected():
            return
        await asyncio.sleep(interval)
        quiet += interval
        record = await run_in_threadpool(store.get, job.id, job.owner)
        if record is None:  # gone meanwhile: nothing more to tell
            return


def _dump(status: JobStatus) -> dict:
    return status.model_dump(mode="json")
