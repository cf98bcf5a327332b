"""The job runner on a real local Ray head, with real entry processes and SQLite: the queue
runs M jobs at a time (and one failing at run time ends ``failed`` with its error), a cancel
stops a running job with a checkpoint that loads (and Ray stops one that does not end within
the grace), a new runner re-attaches to running jobs and marks one whose trainer died as
failed, a resume brings that one to success, and nothing is marked while Ray does not
answer."""

from __future__ import annotations

import itertools
import json
import os
import threading
import time
from pathlib import Path

import pytest
from gaitforge.service.jobs.outcome import FORCED_STOP
from gaitforge.service.jobs.ray_cluster import (
    RayConnection,
    connect_ray,
    default_dashboard,
    head_processes,
    read_head,
    stop_local_ray,
)
from gaitforge.service.jobs.runner import JobRunner, JobStateError, LimitError, submission_id
from gaitforge.service.jobs.spec import SubmissionError
from gaitforge.service.settings import ServiceSettings
from gaitforge.service.store import JobRecord, JobStore


def _progress(record: JobRecord) -> dict:
    return json.loads(record.progress_json) if record.progress_json else {}


def _iterating(record: JobRecord) -> bool:
    return record.state == "running" and _progress(record).get("iteration", 0) >= 1


def _runner(settings: ServiceSettings, store: JobStore, conn: RayConnection) -> JobRunner:
    return JobRunner(settings, store, conn, evaluate_episodes=1)


def test_the_local_head_is_reattached_and_lives_in_a_session_of_its_own(
    service_settings: ServiceSettings, ray_connection: RayConnection, ray_home: Path
) -> None:
    again = connect_ray(service_settings)
    assert not again.started and again.local
    assert (again.address, again.dashboard_url) == (
        ray_connection.address,
        ray_connection.dashboard_url,
    )
    assert again.dashboard_url.startswith("http://127.0.0.1:")
    assert oct((ray_home / "ray-token").stat().st_mode & 0o777) == "0o600"
    head = read_head(ray_home)
    assert head is not None
    daemons = head_processes(head)  # gcs, raylet, dashboard, ...: a session of their own
    assert len(daemons) >= 3
    assert {os.getsid(pid) for pid in daemons} == {head.pgid} != {os.getsid(0)}
    assert not stop_local_ray(service_settings.home / "elsewhere")
    assert default_dashboard("ray://10.0.0.5:10001") == "http://10.0.0.5:8265"
    assert default_dashboard("10.0.0.5:6379") == "http://10.0.0.5:8265"
    assert default_dashboard("auto") == "http://127.0.0.1:8265"


def test_queue_runs_one_job_at_a_time_and_a_run_time_failure_ends_failed_with_its_error(
    service_settings, store, ray_connection, tiny_job, wait_job
) -> None:
    """Two jobs, the older one failing at run time: the newer one starts only once the
    older has ended, and succeeds (each job is a trainer process: seconds)."""
    settings = service_settings.model_copy(update={"max_jobs_per_owner": 2})
    runner = _runner(settings, store, ray_connection)
    ids = [runner.submit("alice", tiny_job(f"q{i}", env_steps=512)).id for i in range(2)]
    damaged = runner.layout(ids[0]).checkpoints_dir / "ckpt-000000000256"
    damaged.mkdir(parents=True)
    (damaged / "manifest.json").write_text("{ not json")  # q0's trainer resumes from it
    with pytest.raises(LimitError, match="alice has 2 queued or running"):
        runner.submit("alice", tiny_job("q2"))
    assert runner.submit("bob", tiny_job("other")).state == "queued"  # bob has his own
    runner.cancel(store.list("bob")[0][0].id, "bob")
    most_running, stop = 0, threading.Event()

    def watch() -> None:
        nonlocal most_running
        while not stop.is_set():
            most_running = max(most_running, len(store.by_state("running")))
            time.sleep(0.05)

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    runner.start()
    try:
        done = [wait_job(store, i, lambda r: r.state in ("succeeded", "failed")) for i in ids]
    finally:
        runner.stop()
        stop.set()
        watcher.join()
    assert [r.state for r in done] == ["failed", "succeeded"], [r.error for r in done]
    assert most_running == 1
    for earlier, later in itertools.pairwise(done):
        assert later.started_at >= earlier.finished_at  # oldest first, one after another
    for record in done:
        assert record.attempt == 1 and record.ray_submission_id == submission_id(record.id, 1)
    failed, succeeded = done
    assert _progress(succeeded)["phase"] == "finished"
    assert runner.layout(succeeded.id).checkpoint_names()
    assert "manifest.json" in failed.error and "not valid JSON" in failed.error
    assert _progress(failed)["phase"] == "failed"
    with pytest.raises(JobStateError):
        runner.cancel(ids[1], "alice")


def test_cancel_stops_a_running_job_with_a_checkpoint_and_a_queued_one_at_once(
    service_settings, store, ray_connection, tiny_job, wait_job
) -> None:
    from gaitforge.learner.checkpoint import load_checkpoint

    runner = _runner(service_settings, store, ray_connection)
    record = runner.submit("alice", tiny_job("long", env_steps=10**8, every_iters=10**6))
    queued = runner.submit("alice", tiny_job("waits"))
    runner.start()
    try:
        assert runner.cancel(queued.id, "alice").state == "cancelled"
        assert runner.cancel(record.id, "bob") is None  # another owner's: not found
        wait_job(store, record.id, _iterating)
        assert runner.cancel(record.id, "alice").cancel_requested
        cancelled = wait_job(store, record.id, lambda r: r.state != "running")
    finally:
        runner.stop()
    assert cancelled.state == "cancelled" and cancelled.error is None
    assert _progress(cancelled)["phase"] == "stopped"
    layout = runner.layout(record.id)
    names = layout.checkpoint_names()
    assert names and _progress(cancelled)["checkpoint"] == names[-1]
    _, meta = load_checkpoint(layout.checkpoints_dir / names[-1])
    assert meta.env_steps > 0
    assert store.get(queued.id).attempt == 0  # never started


def test_a_new_runner_reattaches_marks_a_dead_trainer_failed_and_resume_finishes_it(
    service_settings, store, ray_connection, tiny_job, wait_job
) -> None:
    """``dies`` is stopped as soon as it iterates (whether or not ``kept`` does yet), so that
    a budget of 8 iterations outlasts the stop and its resume has little left to train."""
    settings = service_settings.model_copy(update={"max_running_jobs": 2})
    first = _runner(settings, store, ray_connection)
    kept = first.submit("alice", tiny_job("kept", env_steps=6144, every_iters=4)).id
    dies = first.submit("alice", tiny_job("dies", env_steps=2048, every_iters=100)).id
    first.start()
    try:
        wait_job(store, dies, _iterating)
        assert store.get(kept).state == "running"
    finally:
        first.stop()  # the service goes away; its jobs run on
    client = ray_connection.client
    client.stop_job(submission_id(dies, 1))  # behind the runner's back
    while not client.get_job_status(submission_id(dies, 1)).is_terminal():
        time.sleep(0.1)
    assert str(client.get_job_status(submission_id(kept, 1)).value) == "RUNNING"
    seen = _progress(store.get(kept)).get("iteration", 0)

    second = _runner(settings, store, ray_connection)
    second.start()
    try:
        wait_job(store, kept, lambda r: _progress(r).get("iteration", 0) > seen)  # followed
        died = wait_job(store, dies, lambda r: r.state != "running")
        assert died.state == "failed" and died.error.startswith("trainer died: "), died.error
        assert "stopped" in died.error and _progress(died)["phase"] == "stopped"
        assert second.layout(dies).checkpoint_names()  # written on the way out
        with pytest.raises(JobStateError):
            second.resume(kept, "alice")
        assert second.resume(dies, "alice").state == "queued"
        finished = wait_job(store, dies, lambda r: r.attempt == 2 and r.state != "running")
        kept_record = wait_job(store, kept, lambda r: r.state != "running")
    finally:
        second.stop()
    assert kept_record.state == "succeeded" and kept_record.attempt == 1
    assert finished.state == "succeeded", finished.error
    assert finished.ray_submission_id == submission_id(dies, 2) and finished.error is None
    assert _progress(finished)["env_steps"] >= 2048
    assert "resumed at iteration" in second.layout(dies).log_file.read_text()


def test_a_running_job_ray_does_not_know_is_failed_at_once(
    service_settings, store, ray_connection
) -> None:
    record = store.create("alice", "ghost", {"name": "ghost"})
    store.update(record.id, state="running", attempt=1, ray_submission_id="gaitforge-gone-1")
    runner = _runner(service_settings, store, ray_connection)
    runner.reconcile()
    ghost = store.get(record.id)
    assert ghost.state == "failed" and ghost.finished_at is not None
    assert ghost.error.startswith("trainer died: Ray has no job gaitforge-gone-1")
    assert runner.last_error is None and runner.last_pass_at is not None


def test_a_cancel_not_honoured_within_the_grace_is_stopped_by_ray(
    service_settings, store, ray_connection, wait_job
) -> None:
    record = store.create("alice", "deaf", {"name": "deaf"})
    sid = submission_id(record.id, 1)
    ray_connection.client.submit_job(entrypoint="sleep 120", submission_id=sid)
    store.update(record.id, state="running", attempt=1, ray_submission_id=sid)
    runner = JobRunner(service_settings, store, ray_connection, cancel_grace_s=0.5)
    runner.layout(record.id).dir.mkdir(parents=True)
    runner.start()
    try:
        runner.cancel(record.id, "alice")
        cancelled = wait_job(store, record.id, lambda r: r.state != "running", timeout_s=30)
    finally:
        runner.stop()
    assert cancelled.state == "cancelled"
    assert cancelled.error == FORCED_STOP
    assert str(ray_connection.client.get_job_status(sid).value) == "STOPPED"


def test_while_ray_does_not_answer_nothing_is_marked(
    service_settings, store, ray_connection, ray_home
) -> None:
    from gaitforge.service.jobs.ray_cluster import jobs_client, read_token

    record = store.create("alice", "cut-off", {"name": "cut-off"})
    store.update(record.id, state="running", attempt=1, ray_submission_id="gaitforge-x-1")
    client = jobs_client(ray_connection.dashboard_url, read_token(ray_home))
    client._address = "http://127.0.0.1:9"  # the discard port: connection refused
    cut_off = RayConnection(ray_connection.address, client._address, client, False, True)
    runner = JobRunner(service_settings, store, cut_off)
    with pytest.raises(Exception, match=r"Connection refused|Max retries"):
        runner.reconcile()
    runner.start()
    time.sleep(0.5)
    runner.stop()
    assert runner.last_error is not None
    assert store.get(record.id).state == "running"


def test_a_cluster_address_connects_to_its_jobs_api_with_the_token_from_the_environment(
    service_settings, store, ray_connection, ray_home, monkeypatch
) -> None:
    from gaitforge.service.jobs.ray_cluster import read_token

    monkeypatch.setenv("GAITFORGE_RAY_DASHBOARD", ray_connection.dashboard_url)
    monkeypatch.setenv("RAY_AUTH_TOKEN", read_token(ray_home))
    settings = service_settings.model_copy(update={"ray_address": ray_connection.address})
    cluster = connect_ray(settings)
    assert (cluster.local, cluster.started) == (False, False)
    assert cluster.address == ray_connection.address
    cluster.client.list_jobs()  # authenticated
    runner = JobRunner(settings, store, cluster)
    assert runner.entrypoint(runner.layout("j-0")).startswith("python -m gaitforge.service.")
    monkeypatch.setenv("GAITFORGE_JOB_PYTHON", "/opt/venv/bin/python")
    assert runner.entrypoint(runner.layout("j-0")).startswith("/opt/venv/bin/python -m ")


def test_a_job_asking_for_more_actors_than_the_local_head_has_cpus_is_refused(
    service_settings, store, ray_connection, tiny_job
) -> None:
    """Such actors would wait for CPUs for ever: the submission names the field and the
    head's CPUs, and nothing is queued."""
    runner = _runner(service_settings, store, ray_connection)
    assert ray_connection.num_cpus is not None
    spec = tiny_job("greedy")
    spec["workers"]["num_workers"] = ray_connection.num_cpus + 1
    with pytest.raises(SubmissionError, match=r"workers\.num_workers") as err:
        runner.submit("alice", spec)
    assert str(ray_connection.num_cpus) in str(err.value)
    assert store.list("alice")[0] == []
