"""SQLAlchemy engines for the store: any URL; SQLite gets WAL, foreign keys, a busy timeout
and real transactions (DDL included), with ``BEGIN IMMEDIATE`` for writers.

pysqlite's own transaction handling starts a transaction only at the first data change and
never around DDL; here the driver's is switched off and each transaction emits its own
``BEGIN``. A writer asks for ``BEGIN IMMEDIATE`` (execution option ``sqlite_begin``) so that
it takes the write lock at once and waits ``busy_timeout`` for it, rather than failing when
a read transaction would have to become a write one after another process wrote.

A new SQLite database is its owner's only: its file is made 0600 before SQLite opens it
(SQLite gives its ``-wal``, ``-shm`` and ``-journal`` files the database's mode) in folders
made 0700.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from gaitforge.service.private_files import create_private_file
from sqlalchemy import Engine, create_engine, event
from sqlalchemy.engine import Connection, make_url

BUSY_TIMEOUT_MS = 30_000
"""how long a SQLite connection waits for another's lock, ms"""
IMMEDIATE = {"sqlite_begin": "IMMEDIATE"}
"""execution options of a writing transaction (a no-op on other databases)"""


def make_engine(url: str) -> Engine:
    """An engine for ``url`` (a SQLite file's folder is made).

    Raises:
        ValueError: ``url`` is not a SQLAlchemy URL (naming ``database_url``).
    """
    try:
        parsed = make_url(url)
    except Exception as exc:  # ArgumentError and friends: one line naming the setting
        raise ValueError(f"database_url: {url!r} is not a database URL ({exc})") from None
    if parsed.get_backend_name() != "sqlite":
        return create_engine(parsed, pool_pre_ping=True)
    database = parsed.database
    if database and database != ":memory:" and not database.startswith("file:"):
        create_private_file(Path(database))
    engine = create_engine(parsed, connect_args={"check_same_thread": False})
    _sqlite_events(engine, memory=not database or database == ":memory:")
    return engine


def _sqlite_events(engine: Engine, memory: bool) -> None:
    @event.listens_for(engine, "connect")
    def _connect(dbapi_connection: Any, record: Any) -> None:
        dbapi_connection.isolation_level = None  # the driver starts no transactions itself
        cursor = dbapi_connection.cursor()
        cursor.execute(f"PRAGMA busy_timeout = {BUSY_TIMEOUT_MS}")
        cursor.execute("PRAGMA foreign_keys = ON")
        if not memory:
            cursor.execute("PRAGMA journal_mode = WAL")
            cursor.execute("PRAGMA synchronous = NORMAL")  # durable at checkpoints; WAL-safe
        cursor.close()

    @event.listens_for(engine, "begin")
    def _begin(conn: Connection) -> None:
        mode = conn.get_execution_options().get("sqlite_begin", "DEFERRED")
        if mode not in ("DEFERRED", "IMMEDIATE", "EXCLUSIVE"):
            raise ValueError(f"sqlite_begin: {mode!r}: DEFERRED, IMMEDIATE or EXCLUSIVE")
        conn.exec_driver_sql(f"BEGIN {mode}")
