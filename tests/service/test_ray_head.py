"""The service's Ray, with real heads and real fault injection: the local head listens on
loopback only (every process of it, workers and a job's driver included); a kill -9 of the
local head's GCS is noticed by a running service, which fails the running job (resumable),
stops what is left of the dead head, starts a new one and runs what is queued; a cluster
whose GCS stops answering is reported unreachable, its running job failed after
``ray_lost_after_s``, and the queued job waits and runs once the cluster answers again."""

from __future__ import annotations

import contextlib
import ipaddress
import os
import signal
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient
from gaitforge.service.api import create_app
from gaitforge.service.jobs.local_ray import HEAD_ENV, head_and_leftovers
from gaitforge.service.jobs.procs import listening_sockets, pids_naming, pids_with_env
from gaitforge.service.jobs.ray_cluster import (
    LocalHead,
    RayConnection,
    connect_ray,
    head_processes,
    read_head,
    read_token,
    stop_local_ray,
)
from gaitforge.service.jobs.runner import JobRunner, RayUnavailable, submission_id
from gaitforge.service.settings import ServiceSettings
from gaitforge.service.store import JobStore

from tests.service.api_support import TOKENS, auth, serve
from tests.service.conftest import make_tiny_job

DRIVER = (
    "import time, ray; ray.init(); ray.get(ray.remote(lambda: 1).remote()); "
    "print('up', flush=True); time.sleep(120)"
)
"""a job's driver that joins the head and has the raylet start a worker"""


def _is_loopback(host: str) -> bool:
    address = ipaddress.ip_address(host)
    if isinstance(address, ipaddress.IPv6Address) and address.ipv4_mapped is not None:
        address = address.ipv4_mapped
    return address.is_loopback


def _gcs_pid(head: LocalHead) -> int:
    """The pid of ``head``'s gcs_server."""
    pids = [p for p in head_processes(head) if _command_name(p) == "gcs_server"]
    assert len(pids) == 1, pids
    return pids[0]


def _command_name(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/comm").read_text().strip()
    except OSError:
        return ""


def _wait(what: str, check: Callable[[], Any], timeout_s: float, every_s: float = 0.2) -> Any:
    """Poll ``check`` until it returns something true (returned); fail naming ``what``."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if found := check():
            return found
        time.sleep(every_s)
    pytest.fail(f"{what}: not within {timeout_s} s")


def test_the_local_head_and_its_workers_listen_on_loopback_only(
    ray_connection: RayConnection, ray_home: Path
) -> None:
    head = read_head(ray_home)
    assert head is not None and head.address.startswith("127.0.0.1:")
    client = ray_connection.client
    sid = client.submit_job(entrypoint=f'{sys.executable} -c "{DRIVER}"')
    try:
        _wait("the driver is up", lambda: "up" in client.get_job_logs(sid), 60)
        sockets = listening_sockets(head_and_leftovers(head))
    finally:
        client.stop_job(sid)
        _wait("the driver stopped", lambda: client.get_job_status(sid).is_terminal(), 60)
    commands = {s.command for s in sockets}
    assert {"gcs_server", "raylet"} <= commands, commands  # the head's servers were seen
    assert any(c.startswith("ray::") for c in commands), commands  # the agents' too
    assert len(sockets) >= 8, sockets
    beyond = [s for s in sockets if not _is_loopback(s.host)]
    assert not beyond, f"listening beyond loopback: {beyond}"


@dataclass
class OwnHome:
    """A fresh service home; ``heads`` collects the temp dirs of the heads it had."""

    path: Path
    heads: list[str] = field(default_factory=list)


@pytest.fixture
def own_home(tmp_path: Path) -> Iterator[OwnHome]:
    """A fresh service home. At the end (also on failure) its local head is stopped, and any
    process left of a head in ``heads`` is killed."""
    home = OwnHome(tmp_path / "home")
    yield home
    stop_local_ray(home.path)
    for temp_dir in home.heads:
        for pid in pids_with_env(HEAD_ENV, temp_dir) + pids_naming(temp_dir):
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)


def test_a_killed_gcs_of_the_local_head_fails_the_running_job_and_a_new_head_runs_the_queue(
    own_home: OwnHome,
) -> None:
    settings = ServiceSettings(home=own_home.path, tokens=TOKENS, poll_interval_s=0.2)
    with serve(create_app(settings)) as port:  # its lifespan starts a head in the fresh home
        old = read_head(own_home.path)
        assert old is not None
        own_home.heads.append(old.temp_dir)
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", headers=auth(), timeout=30) as api:
            health = api.get("/healthz").json()
            assert (health["status"], health["ray"]) == ("ok", "ok")
            long = api.post(
                "/v1/jobs", json=make_tiny_job("long", env_steps=10**8, every_iters=10**6)
            )
            assert long.status_code == 201, long.text
            job = f"/v1/jobs/{long.json()['id']}"
            _wait("the job iterates", lambda: (api.get(job).json()["iteration"] or 0) >= 1, 120)

            os.kill(_gcs_pid(old), signal.SIGKILL)
            seen: set[str] = set()

            def failed() -> dict | None:
                seen.add(api.get("/healthz").json()["ray"])
                status = api.get(job).json()
                return status if status["state"] != "running" else None

            status = _wait("the job is failed", failed, 60)
            assert status["state"] == "failed", status
            assert status["error"].startswith("the Ray head died: its gcs_server ended"), status
            assert [a["name"] for a in status["actions"]] == ["resume"]
            assert not pids_with_env(HEAD_ENV, old.temp_dir), "the old head's processes ended"
            assert not pids_naming(old.temp_dir)

            def ray_ok() -> bool:
                seen.add(state := api.get("/healthz").json()["ray"])
                return state == "ok"

            _wait("a new head is up", ray_ok, 60)
            assert "restarting" in seen, seen
            new = read_head(own_home.path)
            assert new is not None and new.temp_dir != old.temp_dir
            own_home.heads.append(new.temp_dir)

            queued = api.post("/v1/jobs", json=make_tiny_job("after", env_steps=512))
            assert queued.status_code == 201, queued.text
            after = f"/v1/jobs/{queued.json()['id']}"
            _wait("the new job starts", lambda: api.get(after).json()["state"] != "queued", 60)
            resumed = api.post(f"{job}/resume")
            assert resumed.status_code == 200 and resumed.json()["state"] == "queued", resumed.text


def test_an_unreachable_cluster_fails_the_running_job_later_and_the_queue_waits_for_it(
    service_settings: ServiceSettings,
    store: JobStore,
    ray_connection: RayConnection,
    ray_home: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("GAITFORGE_RAY_DASHBOARD", ray_connection.dashboard_url)
    monkeypatch.setenv("RAY_AUTH_TOKEN", read_token(ray_home))
    monkeypatch.setenv("GAITFORGE_JOB_PYTHON", sys.executable)
    lost_after = {"ray_address": ray_connection.address, "ray_lost_after_s": 1.0}
    settings = service_settings.model_copy(update=lost_after)
    cluster = connect_ray(settings)
    assert not cluster.local
    runner = JobRunner(settings, store, cluster)
    record = store.create("alice", "far", {"name": "far"})
    first = submission_id(record.id, 1)
    cluster.client.submit_job(entrypoint="sleep 120", submission_id=first)
    store.update(record.id, state="running", attempt=1, ray_submission_id=first)
    runner.layout(record.id).create()
    runner.reconcile()
    assert runner.ray_state == "ok" and store.get(record.id).state == "running"
    head = read_head(ray_home)
    assert head is not None
    gcs = _gcs_pid(head)
    os.kill(gcs, signal.SIGSTOP)  # the cluster's GCS stops answering
    try:
        with pytest.raises(RayUnavailable, match=r"the Ray cluster at .* is unreachable: its GCS"):
            runner.reconcile()
        assert runner.ray_state == "unreachable"
        assert store.get(record.id).state == "running"  # not yet: within ray_lost_after_s
        with TestClient(create_app(settings, runner)) as client:
            assert client.get("/healthz").json()["ray"] == "unreachable"
        time.sleep(settings.ray_lost_after_s)
        with pytest.raises(RayUnavailable):
            runner.reconcile()
        failed = store.get(record.id)
        assert failed.state == "failed" and failed.finished_at is not None
        assert failed.error.startswith(f"the Ray cluster at {cluster.address} is unreachable")
        assert runner.resume(record.id, "alice").state == "queued"
        with pytest.raises(RayUnavailable):
            runner.reconcile()
        assert store.get(record.id).state == "queued"  # waits for the cluster
    finally:
        os.kill(gcs, signal.SIGCONT)
    runner.reconcile()  # it answers again; the first attempt still runs there: stopped first
    assert runner.ray_state == "ok" and store.get(record.id).state == "queued"
    client = cluster.client
    _wait("the first attempt stopped", lambda: client.get_job_status(first).is_terminal(), 90)
    runner.reconcile()
    second = store.get(record.id)
    assert second.state == "running" and second.attempt == 2, second
    runner.start()
    try:  # the second attempt ends (there is no job file): nothing left running on the head
        _wait("the second attempt ended", lambda: store.get(record.id).state != "running", 60)
    finally:
        runner.stop()
