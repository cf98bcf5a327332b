"""The ``jobs`` table: one row per submitted job, its state and its newest progress.

Times are timezone-aware UTC ``datetime`` objects in Python on every database (SQLite keeps
them as naive UTC text; :class:`UTCDateTime` puts the zone back when reading).
"""

from __future__ import annotations

import secrets
from datetime import UTC, datetime
from typing import Literal, get_args

from sqlalchemy import DateTime, Index, Text
from sqlalchemy.engine import Dialect
from sqlalchemy.types import TypeDecorator
from sqlmodel import Field, SQLModel

JobState = Literal["queued", "running", "succeeded", "failed", "cancelled"]
JOB_STATES: tuple[str, ...] = get_args(JobState)
TERMINAL: frozenset[str] = frozenset({"succeeded", "failed", "cancelled"})
"""states a job does not leave by itself (``failed`` and ``cancelled`` may be resumed)"""
ACTIVE: frozenset[str] = frozenset({"queued", "running"})
"""states that count against an owner's limit"""


def utcnow() -> datetime:
    """Now, timezone-aware UTC."""
    return datetime.now(UTC)


def new_job_id() -> str:
    """``j-`` and 12 random hex digits (48 bits)."""
    return f"j-{secrets.token_hex(6)}"


class UTCDateTime(TypeDecorator):
    """A timezone-aware UTC ``datetime`` on any database; naive values are refused."""

    impl = DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            raise ValueError(f"naive datetime {value!r}: give a timezone-aware one (UTC)")
        value = value.astimezone(UTC)
        return value.replace(tzinfo=None) if dialect.name == "sqlite" else value

    def process_result_value(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)


class JobRecord(SQLModel, table=True):
    """A job: who submitted it, its validated spec, where it stands and its newest progress."""

    __tablename__ = "jobs"
    __table_args__ = (Index("ix_jobs_owner_state", "owner", "state"),)

    id: str = Field(default_factory=new_job_id, primary_key=True, max_length=32)
    """``j-`` + 12 hex digits"""
    owner: str = Field(index=True, max_length=200)
    """the owner of the token that submitted it"""
    name: str = Field(max_length=200)
    """the job's ``name``"""
    state: str = Field(default="queued", max_length=16)
    """one of :data:`JOB_STATES`"""
    spec_json: str = Field(sa_type=Text)
    """the validated job (``prepare_submission``'s result) as JSON"""
    created_at: datetime = Field(default_factory=utcnow, sa_type=UTCDateTime)
    started_at: datetime | None = Field(default=None, sa_type=UTCDateTime)
    """when its newest attempt started running"""
    finished_at: datetime | None = Field(default=None, sa_type=UTCDateTime)
    updated_at: datetime = Field(default_factory=utcnow, sa_type=UTCDateTime)
    attempt: int = 0
    """0 until first started; +1 at each start (a resume starts a new attempt)"""
    ray_submission_id: str | None = Field(default=None, max_length=200)
    cancel_requested: bool = False
    error: str | None = Field(default=None, sa_type=Text)
    """why it failed (one line)"""
    progress_json: str | None = Field(default=None, sa_type=Text)
    """the newest ``JobProgress`` as JSON (schema version 2)"""
