"""Shared fixtures of the service tests: one local Ray head for the whole session (one per
pytest-xdist worker; a head takes ~7 s to start), tiny job specs and a store in ``tmp_path``.

    def test_x(ray_connection, service_settings, store, tiny_job):
        runner = JobRunner(service_settings, store, ray_connection, evaluate_episodes=1)
        record = runner.submit("alice", tiny_job(env_steps=512))

``service_home`` is a service home whose ``ray.json`` points at the session's head, so that a
service started on it (``gaitforge serve``, ``connect_ray``) re-attaches instead of starting a
head of its own; do not ``--stop-ray`` it (that stops the shared head).
"""

from __future__ import annotations

import shutil
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from gaitforge.service.jobs.ray_cluster import (
    STATE_FILE,
    TOKEN_FILE,
    RayConnection,
    connect_ray,
    stop_local_ray,
)
from gaitforge.service.settings import ServiceSettings
from gaitforge.service.store import JobRecord, JobStore, open_store


@pytest.fixture(scope="session")
def ray_home(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """The home of the session's local Ray head (``ray.json``, ``ray-token``); the head is
    started by :func:`ray_connection` on first use and stopped at the session's end."""
    home = tmp_path_factory.mktemp("ray-home")
    yield home
    stop_local_ray(home)


@pytest.fixture(scope="session")
def ray_connection(ray_home: Path) -> RayConnection:
    """A connection to the session's local Ray head (token-authenticated jobs API)."""
    return connect_ray(ServiceSettings(home=ray_home, ray_address=None))


@pytest.fixture
def service_home(tmp_path: Path, ray_connection: RayConnection, ray_home: Path) -> Path:
    """A fresh service home that re-attaches to the session's Ray head."""
    home = tmp_path / "home"
    home.mkdir()
    for name in (STATE_FILE, TOKEN_FILE):
        shutil.copy2(ray_home / name, home / name)
    return home


@pytest.fixture
def service_settings(service_home: Path) -> ServiceSettings:
    """Settings on ``service_home``: passes every 0.2 s, 1 job at a time, 8 per owner."""
    return ServiceSettings(home=service_home, poll_interval_s=0.2, max_running_jobs=1)


@pytest.fixture
def store(service_settings: ServiceSettings) -> Iterator[JobStore]:
    """The job store of ``service_settings`` (SQLite in the service home)."""
    job_store = open_store(service_settings.db_url)
    yield job_store
    job_store.close()


def make_tiny_job(
    name: str = "tiny", env_steps: int = 1024, every_iters: int = 2, **extra: Any
) -> dict[str, Any]:
    """A job spec (as submitted) training stand-2d in-process: 2 envs, PPO batches of 256 env
    steps (2 minibatches, 1 epoch), a checkpoint every ``every_iters`` iterations, a
    ``env_steps`` budget (1024: 4 iterations, about 1 s of training on this machine)."""
    return {
        "name": name,
        "backend": "mujoco",
        "network": {"hidden": [32, 32]},
        "ppo": {"batch_env_steps": 256, "minibatch_size": 128, "epochs": 1},
        "workers": {"num_workers": 0, "envs_per_worker": 2, "fragment_length": 64},
        "checkpoint": {"every_iters": every_iters},
        "stages": [{"scene": "stand-2d", "scene_set": {"control_hz": 25}, "env_steps": env_steps}],
        **extra,
    }


@pytest.fixture
def tiny_job() -> Callable[..., dict[str, Any]]:
    """:func:`make_tiny_job`, as a fixture."""
    return make_tiny_job


def wait_for(
    store: JobStore, job_id: str, done: Callable[[JobRecord], bool], timeout_s: float = 60.0
) -> JobRecord:
    """Poll ``store`` until job ``job_id``'s record satisfies ``done``; fail after
    ``timeout_s`` naming the state it was in."""
    deadline = time.monotonic() + timeout_s
    record = store.get(job_id)
    while time.monotonic() < deadline:
        record = store.get(job_id)
        assert record is not None
        if done(record):
            return record
        time.sleep(0.1)
    pytest.fail(
        f"job {job_id}: still {record.state if record else None} after {timeout_s} s "
        f"(error: {record.error if record else None})"
    )


@pytest.fixture
def wait_job() -> Callable[..., JobRecord]:
    """:func:`wait_for`, as a fixture: ``wait_job(store, job_id, done, timeout_s=60)``."""
    return wait_for
