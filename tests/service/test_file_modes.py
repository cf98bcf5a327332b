"""What the service keeps is its owner's only: a fresh home, the SQLite database and its
``-wal``/``-shm`` files, the artifact root, ``jobs/`` and a job's folder (0700 folders, 0600
files), and the local head's ``ray.json`` and ``ray.lock`` (real SQLite, a real runner)."""

from __future__ import annotations

import stat
from pathlib import Path

from gaitforge.service.api.auth import local_token
from gaitforge.service.jobs.ray_cluster import STATE_FILE, RayConnection
from gaitforge.service.jobs.runner import JobRunner
from gaitforge.service.settings import ServiceSettings
from gaitforge.service.store import open_store

from tests.service.conftest import make_tiny_job


def _mode(path: Path) -> str:
    return oct(stat.S_IMODE(path.stat().st_mode))


def test_a_fresh_home_its_database_and_a_jobs_folder_are_the_owners_only(
    tmp_path: Path, ray_connection: RayConnection, ray_home: Path
) -> None:
    home = tmp_path / "service" / "home"  # neither folder exists yet
    settings = ServiceSettings(home=home)
    store = open_store(settings.db_url)
    try:
        runner = JobRunner(settings, store, ray_connection)
        record = runner.submit("alice", make_tiny_job())
        store.update(record.id, error="written through the WAL")
        database = home / "gaitforge.db"
        files = sorted(home.glob("gaitforge.db*"))
        assert {p.name for p in files} >= {"gaitforge.db", "gaitforge.db-wal", "gaitforge.db-shm"}
        layout = runner.layout(record.id)
        folders = [tmp_path / "service", home, settings.artifacts, layout.dir.parent, layout.dir]
        assert {str(p): _mode(p) for p in folders} == {str(p): "0o700" for p in folders}
        assert {p.name: _mode(p) for p in files} == {p.name: "0o600" for p in files}
        assert layout.job_file.is_file() and database.stat().st_size > 0
    finally:
        store.close()
    for name in (STATE_FILE, "ray.lock", "ray-token"):  # the local head's, in its home
        assert _mode(ray_home / name) == "0o600", name


def test_the_generated_token_and_the_home_it_makes_are_the_owners_only(tmp_path: Path) -> None:
    home = tmp_path / "fresh" / "home"  # as `gaitforge serve` on a new home, without tokens
    token = local_token(ServiceSettings(home=home))
    assert token and (home / "token").read_text().strip() == token
    assert [_mode(p) for p in (tmp_path / "fresh", home)] == ["0o700", "0o700"]
    assert _mode(home / "token") == "0o600"
