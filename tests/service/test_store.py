"""The job store on real SQLite files: CRUD, owners kept apart, pages, compare-and-set,
concurrent writers, and a database written at schema version 1 migrated with its rows."""

from __future__ import annotations

import json
import threading
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest
from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext
from gaitforge.service.settings import ServiceSettings
from gaitforge.service.store import (
    CURRENT_SCHEMA_VERSION,
    JobRecord,
    JobStore,
    open_store,
    utcnow,
)
from gaitforge.service.store.engine import make_engine
from gaitforge.service.store.migrations import migrate, schema_version
from sqlalchemy import inspect, text
from sqlmodel import SQLModel


@pytest.fixture
def store(tmp_path: Path) -> JobStore:
    store = open_store(f"sqlite:///{tmp_path}/db/jobs.db")
    yield store
    store.close()


def test_create_get_update_and_owners_apart(store: JobStore) -> None:
    record = store.create("alice", "stand", {"name": "stand", "stages": []})
    assert record.id.startswith("j-") and len(record.id) == 14
    assert (record.state, record.attempt, record.cancel_requested) == ("queued", 0, False)
    assert record.created_at.tzinfo is UTC
    got = store.get(record.id, owner="alice")
    assert got is not None and json.loads(got.spec_json) == {"name": "stand", "stages": []}
    assert got.created_at == record.created_at and got.created_at.tzinfo is UTC
    assert store.get(record.id, owner="bob") is None
    assert store.get("j-000000000000") is None

    started = datetime(2026, 1, 2, 3, 4, 5, tzinfo=UTC) + timedelta(hours=1)
    updated = store.update(record.id, state="running", attempt=1, started_at=started)
    assert updated.updated_at > record.updated_at
    again = store.get(record.id)
    assert (again.state, again.attempt, again.started_at) == ("running", 1, started)
    assert store.count_active("alice") == 1 and store.count_active("bob") == 0
    assert [r.id for r in store.by_state("running")] == [record.id]
    with pytest.raises(KeyError):
        store.update("j-000000000000", state="failed")
    with pytest.raises(ValueError, match="state"):
        store.update(record.id, state="exploded")
    with pytest.raises(ValueError, match="owner_x"):
        store.update(record.id, owner_x="bob")


def test_naive_times_are_refused(store: JobStore) -> None:
    record = store.create("alice", "stand", {})
    with pytest.raises(Exception, match="naive datetime"):
        store.update(record.id, started_at=datetime(2026, 1, 1))


def test_update_if_is_a_compare_and_set(store: JobStore) -> None:
    record = store.create("alice", "stand", {})
    assert store.update_if(record.id, ["running"], state="failed") is None
    assert store.get(record.id).state == "queued"
    done = store.update_if(record.id, ["queued"], state="cancelled", finished_at=utcnow())
    assert done is not None and done.state == "cancelled"
    assert store.count_active("alice") == 0


def test_pages_newest_first_filtered_by_state_and_owner(store: JobStore) -> None:
    ids = [store.create("alice", f"job{i}", {}).id for i in range(7)]
    store.create("bob", "other", {})
    store.update(ids[0], state="failed")
    page, total = store.list("alice", offset=0, limit=3)
    assert total == 7 and [r.id for r in page] == ids[::-1][:3]
    page, total = store.list("alice", offset=6, limit=3)
    assert total == 7 and [r.id for r in page] == [ids[0]]
    page, total = store.list("alice", state="failed")
    assert total == 1 and page[0].id == ids[0]
    assert store.list("bob")[1] == 1 and store.list(None)[1] == 8
    for bad in ({"state": "nope"}, {"offset": -1}, {"limit": 0}, {"limit": 10_000}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            store.list("alice", **bad)


def test_wal_and_busy_timeout(store: JobStore) -> None:
    with store.engine.connect() as conn:
        assert conn.exec_driver_sql("PRAGMA journal_mode").scalar() == "wal"
        assert conn.exec_driver_sql("PRAGMA busy_timeout").scalar() >= 1000


def test_two_stores_on_one_file_write_concurrently(tmp_path: Path) -> None:
    """Writers in threads through two engines (as the runner and the API would) wait for the
    write lock instead of failing with 'database is locked'."""
    url = f"sqlite:///{tmp_path}/jobs.db"
    stores = [open_store(url), open_store(url)]
    record = stores[0].create("alice", "stand", {})
    errors: list[BaseException] = []

    def work(store: JobStore, n: int) -> None:
        try:
            for i in range(20):
                store.create("alice", f"j{n}-{i}", {"i": i})
                store.update(record.id, attempt=n * 100 + i)
        except BaseException as exc:
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(stores[i % 2], i)) for i in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert not errors, errors
    assert stores[1].list("alice")[1] == 81
    for store in stores:
        store.close()


def test_a_version_1_database_migrates_with_its_rows(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path}/old.db"
    engine = make_engine(url)
    assert migrate(engine, target=1) == 1
    with engine.begin() as conn:
        assert "progress_json" not in {c["name"] for c in inspect(conn).get_columns("jobs")}
        conn.execute(
            text(
                "INSERT INTO jobs (id, owner, name, state, spec_json, created_at, updated_at, "
                "attempt, cancel_requested, error) VALUES ('j-0123456789ab', 'alice', 'old', "
                "'failed', '{\"name\": \"old\"}', '2026-01-02 03:04:05.000000', "
                "'2026-01-02 03:04:06.000000', 2, 0, 'trainer died: out of memory')"
            )
        )
    engine.dispose()

    store = open_store(url)
    with store.engine.connect() as conn:
        assert schema_version(conn) == CURRENT_SCHEMA_VERSION == 2
        indexes = {i["name"] for i in inspect(conn).get_indexes("jobs")}
        assert "ix_jobs_owner_state" in indexes
        # the migrated schema is the models' schema: nothing for autogenerate to add
        only_jobs = {"include_name": lambda name, kind, parent: kind != "table" or name == "jobs"}
        context = MigrationContext.configure(conn, opts=only_jobs)
        assert compare_metadata(context, SQLModel.metadata) == []
    old = store.get("j-0123456789ab", owner="alice")
    assert isinstance(old, JobRecord)
    assert (old.name, old.state, old.attempt, old.progress_json) == ("old", "failed", 2, None)
    assert old.error == "trainer died: out of memory"
    assert old.created_at == datetime(2026, 1, 2, 3, 4, 5, tzinfo=UTC)
    store.update(old.id, progress_json='{"phase": "failed"}')
    assert json.loads(store.get(old.id).progress_json) == {"phase": "failed"}
    store.close()
    assert open_store(url).get(old.id) is not None  # opening again migrates nothing


def test_a_newer_schema_is_refused(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path}/new.db"
    store = open_store(url)
    with store.engine.begin() as conn:
        conn.execute(
            text("INSERT INTO gaitforge_schema VALUES (99, 'future', '2030-01-01 00:00:00')")
        )
    store.close()
    with pytest.raises(RuntimeError, match="newer"):
        open_store(url)


def test_settings_defaults_environment_and_tokens(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("GAITFORGE_HOME", str(tmp_path / "home"))
    monkeypatch.setenv("GAITFORGE_PORT", "9001")
    monkeypatch.setenv("GAITFORGE_TOKENS", "alice:tok-alice-0123456789, bob:tok-bob-0123456789")
    tokens_file = tmp_path / "tokens"
    tokens_file.write_text("# owners\ncarol:tok-carol-0123456789  # ops\n\n")
    settings = ServiceSettings(tokens_file=tokens_file)
    assert settings.port == 9001 and settings.home == tmp_path / "home"
    assert settings.db_url == f"sqlite:///{tmp_path}/home/gaitforge.db"
    assert settings.artifacts == tmp_path / "home" / "artifacts"
    assert settings.token_map() == {
        "tok-alice-0123456789": "alice",
        "tok-bob-0123456789": "bob",
        "tok-carol-0123456789": "carol",
    }
    with pytest.raises(ValueError, match="tokens"):
        ServiceSettings(tokens="alice")
    with pytest.raises(ValueError, match="port"):
        ServiceSettings(port=70000)
