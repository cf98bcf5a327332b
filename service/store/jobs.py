"""The job store: create, find, page through and update :class:`JobRecord` rows.

Every call is its own short transaction (writers take SQLite's write lock at once, see
``engine``); the records returned are detached copies, safe to use from any thread.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from typing import Any

from gaitforge.service.store.engine import IMMEDIATE
from gaitforge.service.store.models import ACTIVE, JOB_STATES, JobRecord, utcnow
from sqlalchemy import Engine, func
from sqlmodel import Session, col, select

MAX_PAGE = 500
"""the most records one :meth:`JobStore.list` call returns"""
_FIELDS = frozenset(JobRecord.model_fields) - {"id", "created_at"}


class JobStore:
    """Jobs in the database behind ``engine`` (schema already migrated: ``open_store``)."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine

    def _session(self) -> Session:
        return Session(self.engine, expire_on_commit=False)

    def create(self, owner: str, name: str, spec: dict[str, Any]) -> JobRecord:
        """A new queued job of ``owner`` (attempt 0) holding ``spec`` (JSON-able)."""
        record = JobRecord(owner=owner, name=name, state="queued", spec_json=json.dumps(spec))
        with self._session() as session:
            session.connection(execution_options=IMMEDIATE)
            session.add(record)
            session.commit()
        return record

    def get(self, job_id: str, owner: str | None = None) -> JobRecord | None:
        """The job ``job_id``; None if there is none, or (``owner`` given) it is another
        owner's."""
        with self._session() as session:
            record = session.get(JobRecord, job_id)
        if record is None or (owner is not None and record.owner != owner):
            return None
        return record

    def list(
        self, owner: str | None, state: str | None = None, offset: int = 0, limit: int = 50
    ) -> tuple[list[JobRecord], int]:
        """A page of ``owner``'s jobs (None: every owner's), newest first, and how many
        there are in all (with the ``state`` filter).

        Raises:
            ValueError: a bad ``state``, ``offset`` or ``limit`` (naming it).
        """
        if state is not None and state not in JOB_STATES:
            raise ValueError(f"state: {state!r}: one of {', '.join(JOB_STATES)}")
        if offset < 0:
            raise ValueError(f"offset: {offset}: must be 0 or more")
        if not 1 <= limit <= MAX_PAGE:
            raise ValueError(f"limit: {limit}: must be in 1..{MAX_PAGE}")
        where = []
        if owner is not None:
            where.append(JobRecord.owner == owner)
        if state is not None:
            where.append(JobRecord.state == state)
        query = select(JobRecord).where(*where)
        count = select(func.count()).select_from(JobRecord).where(*where)
        query = query.order_by(col(JobRecord.created_at).desc(), col(JobRecord.id).desc())
        with self._session() as session:
            total = int(session.exec(count).one())
            items = list(session.exec(query.offset(offset).limit(limit)).all())
        return items, total

    def count_active(self, owner: str) -> int:
        """``owner``'s queued and running jobs."""
        query = (
            select(func.count())
            .select_from(JobRecord)
            .where(JobRecord.owner == owner, col(JobRecord.state).in_(ACTIVE))
        )
        with self._session() as session:
            return int(session.exec(query).one())

    def by_state(self, *states: str) -> list[JobRecord]:
        """Every job in one of ``states`` (all owners), oldest first."""
        query = (
            select(JobRecord)
            .where(col(JobRecord.state).in_(states))
            .order_by(col(JobRecord.created_at), col(JobRecord.id))
        )
        with self._session() as session:
            return list(session.exec(query).all())

    def update(self, job_id: str, **fields: Any) -> JobRecord:
        """Set ``fields`` of job ``job_id`` (and ``updated_at``); returns the new record.

        Raises:
            KeyError: no job ``job_id``.
            ValueError: a field that is not a column (or is ``id``/``created_at``), or a bad
                ``state``.
        """
        record = self.update_if(job_id, None, **fields)
        assert record is not None
        return record

    def update_if(
        self, job_id: str, states: Iterable[str] | None, **fields: Any
    ) -> JobRecord | None:
        """:meth:`update`, only if the job is in one of ``states`` (None: any) when the write
        lock is held: a compare-and-set; None if it was not (nothing written).

        Raises:
            KeyError: no job ``job_id``.
            ValueError: as :meth:`update`.
        """
        unknown = set(fields) - _FIELDS
        if unknown:
            raise ValueError(f"{', '.join(sorted(unknown))}: not a field one can update")
        if "state" in fields and fields["state"] not in JOB_STATES:
            raise ValueError(f"state: {fields['state']!r}: one of {', '.join(JOB_STATES)}")
        with self._session() as session:
            session.connection(execution_options=IMMEDIATE)
            record = session.get(JobRecord, job_id)
            if record is None:
                raise KeyError(job_id)
            if states is not None and record.state not in set(states):
                return None
            for key, value in fields.items():
                setattr(record, key, value)
            record.updated_at = fields.get("updated_at") or utcnow()
            session.add(record)
            session.commit()
        return record

    def close(self) -> None:
        """Close the engine's connections."""
        self.engine.dispose()
