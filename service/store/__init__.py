"""The job store: SQLModel tables on SQLite (WAL) or any SQLAlchemy URL, with migrations.

store = open_store(settings.db_url)       # engine made, schema migrated to current
record = store.create("alice", "stand-2d", spec)
store.update(record.id, state="running", attempt=1, started_at=utcnow())
"""

from __future__ import annotations

from gaitforge.service.store.engine import make_engine
from gaitforge.service.store.jobs import JobStore
from gaitforge.service.store.migrations import CURRENT_SCHEMA_VERSION, migrate
from gaitforge.service.store.models import (
    ACTIVE,
    JOB_STATES,
    TERMINAL,
    JobRecord,
    JobState,
    new_job_id,
    utcnow,
)

__all__ = [
    "ACTIVE",
    "CURRENT_SCHEMA_VERSION",
    "JOB_STATES",
    "TERMINAL",
    "JobRecord",
    "JobState",
    "JobStore",
    "new_job_id",
    "open_store",
    "utcnow",
]


def open_store(url: str) -> JobStore:
    """A store on the database at ``url`` (any SQLAlchemy URL), its schema migrated to
    :data:`CURRENT_SCHEMA_VERSION`.

    Raises:
        ValueError: ``url`` is not a database URL.
        RuntimeError: the database's schema is newer than this gaitforge.
    """
    engine = make_engine(url)
    migrate(engine)
    return JobStore(engine)
