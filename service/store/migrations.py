"""Schema migrations: numbered steps written with alembic ``Operations`` on a
``MigrationContext`` (no ini or env files), applied in order inside one transaction, each
recorded in the table ``gaitforge_schema`` (version, description, applied_at).

A step describes the schema as it was at its version (its own column lists), never the
current models, so that an old database always goes through the same steps. To change the
schema: add a step at the end; never edit one that has shipped.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

from alembic.migration import MigrationContext
from alembic.operations import Operations
from gaitforge.service.store.engine import IMMEDIATE
from gaitforge.service.store.models import UTCDateTime, utcnow
from sqlalchemy import (
    Boolean,
    Column,
    Engine,
    Integer,
    MetaData,
    String,
    Table,
    Text,
    func,
    inspect,
    select,
)
from sqlalchemy.engine import Connection

logger = logging.getLogger(__name__)

VERSION_TABLE = Table(
    "gaitforge_schema",
    MetaData(),
    Column("version", Integer, primary_key=True, autoincrement=False),
    Column("description", String(200), nullable=False),
    Column("applied_at", UTCDateTime, nullable=False),
)


@dataclass(frozen=True)
class Migration:
    version: int
    description: str
    upgrade: Callable[[Operations], None]


def _jobs_table(op: Operations) -> None:
    op.create_table(
        "jobs",
        Column("id", String(32), primary_key=True),
        Column("owner", String(200), nullable=False),
        Column("name", String(200), nullable=False),
        Column("state", String(16), nullable=False),
        Column("spec_json", Text, nullable=False),
        Column("created_at", UTCDateTime, nullable=False),
        Column("started_at", UTCDateTime, nullable=True),
        Column("finished_at", UTCDateTime, nullable=True),
        Column("updated_at", UTCDateTime, nullable=False),
        Column("attempt", Integer, nullable=False),
        Column("ray_submission_id", String(200), nullable=True),
        Column("cancel_requested", Boolean, nullable=False),
        Column("error", Text, nullable=True),
    )
    op.create_index("ix_jobs_owner", "jobs", ["owner"])


def _progress_and_owner_state(op: Operations) -> None:
    op.add_column("jobs", Column("progress_json", Text, nullable=True))
    op.create_index("ix_jobs_owner_state", "jobs", ["owner", "state"])


MIGRATIONS: tuple[Migration, ...] = (
    Migration(1, "jobs table", _jobs_table),
    Migration(2, "jobs.progress_json; index on (owner, state)", _progress_and_owner_state),
)
CURRENT_SCHEMA_VERSION = MIGRATIONS[-1].version


def schema_version(conn: Connection) -> int:
    """The version of the schema behind ``conn`` (0: an empty database)."""
    if not inspect(conn).has_table(VERSION_TABLE.name):
        return 0
    return int(conn.execute(select(func.max(VERSION_TABLE.c.version))).scalar() or 0)


def migrate(engine: Engine, target: int = CURRENT_SCHEMA_VERSION) -> int:
    """Bring the database to schema version ``target`` (default: current) in one
    transaction (on SQLite holding the write lock, so that two processes do not both
    migrate); returns the version it is at.

    Raises:
        RuntimeError: the database was written by a newer gaitforge (its version is higher
            than this one knows).
    """
    with engine.connect().execution_options(**IMMEDIATE) as conn, conn.begin():
        VERSION_TABLE.create(conn, checkfirst=True)
        current = schema_version(conn)
        if current > CURRENT_SCHEMA_VERSION:
            raise RuntimeError(
                f"database_url: schema version {current} is newer than this gaitforge "
                f"knows ({CURRENT_SCHEMA_VERSION}); upgrade gaitforge"
            )
        op = Operations(MigrationContext.configure(conn))
        for step in MIGRATIONS:
            if current < step.version <= target:
                logger.info("database schema: migrating to %d (%s)", step.version, step.description)
                step.upgrade(op)
                conn.execute(
                    VERSION_TABLE.insert().values(
                        version=step.version, description=step.description, applied_at=utcnow()
                    )
                )
                current = step.version
        return current
