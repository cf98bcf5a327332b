"""The job runner: a queue of jobs run as Ray jobs with a fixed entrypoint, followed from a
background thread.

    runner = JobRunner(settings, store, connect_ray(settings))
    runner.start()                              # reconcile every settings.poll_interval_s
    record = runner.submit("alice", spec)       # queued; LimitError past the owner's limit
    runner.cancel(record.id, "alice")           # stops after the iteration, with a checkpoint
    runner.stop()                               # the thread only: jobs keep running on Ray

Each pass (:meth:`JobRunner.reconcile`) first checks Ray (:meth:`JobRunner.check_ray`), then
copies every running job's ``progress.json`` into its record, settles the jobs whose Ray job
ended, and starts queued jobs, oldest first, while fewer than ``max_running_jobs`` run. The
state lives in the store and on disk, so a new runner (a restarted service) re-attaches to
the jobs still running and marks those whose trainer died as failed ("trainer died: ..."),
to be resumed from their newest checkpoint.

Ray going away is noticed by the next pass: a local head whose GCS or raylet died is replaced
at once (what is left of it stopped, its running jobs failed with "the Ray head died: ...",
a new head started; ``ray_state`` is ``restarting`` meanwhile); a cluster (or a head) whose
GCS or jobs API does not answer is ``unreachable``, and its running jobs are failed once it
stays so for ``ray_lost_after_s``. Queued jobs wait for Ray to answer again; a failed job is
resumed like any other (its earlier attempt, should Ray still run it, is stopped first).
"""

from __future__ import annotations

import logging
import os
import shlex
import sys
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from gaitforge.service.jobs.layout import JobLayout
from gaitforge.service.jobs.outcome import died_reason, log_tail, outcome
from gaitforge.service.jobs.progress import read_progress
from gaitforge.service.jobs.ray_cluster import (
    RayError,
    connect_ray,
    first_line,
    gcs_problem,
    head_death,
    stop_local_ray,
)
from gaitforge.service.store import JobRecord, JobStore, utcnow

if TYPE_CHECKING:
    from gaitforge.service.jobs.ray_cluster import RayConnection
    from gaitforge.service.settings import ServiceSettings

logger = logging.getLogger(__name__)

CANCEL_GRACE_S = 120.0
"""how long a cancelled job may take to end its iteration before Ray stops it, s"""
RayState = Literal["ok", "restarting", "unreachable"]
"""``ok``; ``restarting``: a local head died and a new one starts; ``unreachable``: Ray's GCS or
jobs API does not answer (or a new head did not start)"""


class RayUnavailable(RuntimeError):
    """Ray is not up: the pass stopped before following or starting jobs (the message says
    why)."""


class LimitError(Exception):
    """The owner has as many queued and running jobs as allowed (the API answers 429)."""


class JobStateError(ValueError):
    """The job is not in a state that allows the action (the API answers 409)."""


def submission_id(job_id: str, attempt: int) -> str:
    """The Ray submission id of a job's attempt: ``gaitforge-<job id>-<attempt>``."""
    return f"gaitforge-{job_id}-{attempt}"


class JobRunner:
    """Queues, starts, follows, cancels and resumes jobs on the Ray cluster of
    ``connection``; thread-safe (one lock around every change of a job's state)."""

    def __init__(
        self,
        settings: ServiceSettings,
        store: JobStore,
        connection: RayConnection,
        cancel_grace_s: float = CANCEL_GRACE_S,
        evaluate_episodes: int | None = None,
    ) -> None:
        self.settings = settings
        self.store = store
        self.connection = connection
        self.cancel_grace_s = cancel_grace_s
        self.evaluate_episodes = evaluate_episodes
        self.root = Path(settings.artifacts).resolve()
        self.last_error: str | None = None
        """why the newest pass failed (None: it went through)"""
        self.last_pass_at: float | None = None
        """``time.time()`` of the newest pass that went through"""
        self.ray_state: RayState = "ok"
        """where Ray stands, as the newest check found it"""
        self._unreachable_since: float | None = None
        """``time.monotonic()`` when Ray stopped answering (None: it answers)"""
        self._stopping: set[str] = set()
        """submission ids of earlier attempts asked to stop before a job's next attempt"""
        self._lock = threading.RLock()
        self._wake = threading.Event()
        self._halt = threading.Event()
        self._thread: threading.Thread | None = None

    # the background thread

    def start(self) -> None:
        """Reconcile now and then every ``settings.poll_interval_s`` in a daemon thread."""
        if self._thread is not None and self._thread.is_alive():
            return
        self._halt.clear()
        self._thread = threading.Thread(target=self._loop, name="gaitforge-runner", daemon=True)
        self._thread.start()

    def stop(self, timeout_s: float = 30.0) -> None:
        """Stop the thread (after its current pass); jobs on Ray are left running."""
        self._halt.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout_s)
            self._thread = None

    def wake(self) -> None:
        """Make the thread pass again now (a job was queued or cancelled)."""
        self._wake.set()

    def _loop(self) -> None:
        while not self._halt.is_set():
            try:
                self.reconcile()
            except Exception as exc:  # keep following: the next pass may go through
                error = first_line(exc)
                if error != self.last_error:  # once per new error, not every pass
                    logger.warning(
                        "runner pass failed: %s", error, exc_info=logger.isEnabledFor(logging.DEBUG)
                    )
                self.last_error = error
            self._wake.wait(self.settings.poll_interval_s)
            self._wake.clear()

    # actions

    def layout(self, job_id: str) -> JobLayout:
        """The files of job ``job_id``."""
        return JobLayout(self.root, job_id)

    def submit(self, owner: str, spec: dict[str, Any] | str) -> JobRecord:
        """Validate ``spec`` (a job as in a job file: a mapping, YAML or JSON text) and queue
        it for ``owner``.

        Raises:
            SpecError: the spec does not validate (naming the field), or asks for more rollout
                actors than a local head has CPUs.
            LimitError: ``owner`` has ``max_jobs_per_owner`` queued and running jobs.
        """
        from gaitforge.service.jobs.spec import prepare_submission, write_job_files

        job = prepare_submission(spec, max_num_workers=self.connection.num_cpus)
        with self._lock:
            self._check_limit(owner)
            record = self.store.create(owner, job["name"], job)
            try:
                layout = self.layout(record.id)
                layout.create()  # the owner's only (0700), before anything is written in it
                write_job_files(layout, job)
            except Exception as exc:
                self.store.update(
                    record.id, state="failed", error=f"job files: {exc}", finished_at=utcnow()
                )
                raise
        logger.info("job %s (%s) of %s queued", record.id, record.name, owner)
        self.wake()
        return record

    def cancel(self, job_id: str, owner: str | None = None) -> JobRecord | None:
        """Cancel ``owner``'s job: a queued one at once; a running one ends its iteration,
        writes a checkpoint and stops (Ray stops it after ``cancel_grace_s`` otherwise).
        None if there is no such job of ``owner``; a cancelled job is returned as it is.

        Raises:
            JobStateError: the job has succeeded or failed already.
        """
        with self._lock:
            record = self.store.get(job_id, owner=owner)
            if record is None or record.state == "cancelled":
                return record
            if record.state == "queued":
                record = self.store.update(
                    job_id, state="cancelled", cancel_requested=True, finished_at=utcnow()
                )
            elif record.state == "running":
                cancel_file = self.layout(job_id).cancel_file
                if not cancel_file.exists():
                    cancel_file.touch()
                record = self.store.update(job_id, cancel_requested=True)
            else:
                raise JobStateError(f"job {job_id} has {record.state}: nothing to cancel")
        logger.info("job %s: cancel requested", job_id)
        self.wake()
        return record

    def resume(self, job_id: str, owner: str | None = None) -> JobRecord | None:
        """Queue ``owner``'s failed or cancelled job again; its next attempt goes on from the
        newest checkpoint in its run directory (from the start if there is none). None if
        there is no such job of ``owner``.

        Raises:
            JobStateError: the job is queued, running or has succeeded.
            LimitError: ``owner`` has ``max_jobs_per_owner`` queued and running jobs.
        """
        with self._lock:
            record = self.store.get(job_id, owner=owner)
            if record is None:
                return None
            if record.state not in ("failed", "cancelled"):
                raise JobStateError(
                    f"job {job_id} is {record.state}: only a failed or cancelled job resumes"
                )
            self._check_limit(record.owner)
            self.layout(job_id).cancel_file.unlink(missing_ok=True)
            record = self.store.update(
                job_id, state="queued", error=None, cancel_requested=False, finished_at=None
            )
        logger.info("job %s queued again (resume)", job_id)
        self.wake()
        return record

    def _check_limit(self, owner: str) -> None:
        limit = self.settings.max_jobs_per_owner
        if self.store.count_active(owner) >= limit:
            raise LimitError(
                f"{owner} has {limit} queued or running jobs (the limit); "
                "wait for one to end or cancel one"
            )

    # reconciling

    def reconcile(self) -> None:
        """One pass: check Ray (:meth:`check_ray`), follow every running job, then start
        queued jobs while there is room.

        Raises:
            RayUnavailable: Ray is not up (see :meth:`check_ray`).
            Exception: Ray's jobs API failed (nothing is marked on the way).
        """
        self.check_ray()
        with self._lock:
            running = 0
            for record in self.store.by_state("running"):
                running += self._follow(record)
            queued = self.store.by_state("queued")
            while queued and running < self.settings.max_running_jobs:
                self._start(queued.pop(0))
                running += 1
        self.last_error, self.last_pass_at = None, time.time()

    def check_ray(self) -> None:
        """Check that Ray is up, and act when it is not: a local head whose GCS or raylet
        died is replaced (:meth:`_replace_dead_head`); a cluster (or a head) that does not
        answer its health check within ``ray_probe_timeout_s`` is ``unreachable``, and once it
        stays so for ``ray_lost_after_s`` the running jobs are failed, resumable. Sets
        :attr:`ray_state`.

        Raises:
            RayUnavailable: Ray is not up (yet).
        """
        if self.connection.local:
            died = head_death(Path(self.settings.home))
            if died is not None:
                self._replace_dead_head(f"the Ray head died: {died}")
        problem = gcs_problem(self.connection.dashboard_url, self.settings.ray_probe_timeout_s)
        if problem is None:
            if self.ray_state != "ok":
                logger.info("Ray at %s answers again", self.connection.address)
            self.ray_state, self._unreachable_since = "ok", None
            return
        what = "the local Ray head" if self.connection.local else "the Ray cluster"
        reason = f"{what} at {self.connection.address} is unreachable: {problem}"
        now = time.monotonic()
        if self._unreachable_since is None:
            self._unreachable_since = now
            lost_after = self.settings.ray_lost_after_s
            logger.warning("%s; running jobs fail if it stays so for %.0f s", reason, lost_after)
        self.ray_state = "unreachable"
        lost_for = now - self._unreachable_since
        if lost_for >= self.settings.ray_lost_after_s:
            self._fail_running(f"{reason} (for {lost_for:.0f} s)")
        raise RayUnavailable(reason)

    def _replace_dead_head(self, reason: str) -> None:
        """Stop what is left of the dead local head (its workers and trainers too), fail its
        running jobs with ``reason`` and start a new head (about 7 s; the lock is not held
        meanwhile, so that the API goes on queueing).

        Raises:
            RayUnavailable: the new head did not start (``ray_state``: ``unreachable``).
        """
        self.ray_state = "restarting"
        logger.warning("%s; stopping what is left of it and starting a new head", reason)
        stop_local_ray(Path(self.settings.home))  # its trainers end (with a checkpoint) first
        self._fail_running(reason)
        try:
            connection = connect_ray(self.settings)
        except RayError as exc:
            self.ray_state = "unreachable"
            raise RayUnavailable(f"{reason}; a new head did not start: {exc}") from None
        with self._lock:
            self.connection = connection
        logger.info("a new local Ray head is up: %s", connection.address)

    def _fail_running(self, reason: str) -> None:
        """Mark every running job failed with ``reason`` (one being cancelled: cancelled),
        its newest progress copied; each can be resumed from its newest checkpoint."""
        with self._lock:
            for record in self.store.by_state("running"):
                state = "cancelled" if record.cancel_requested else "failed"
                fields: dict[str, Any] = {"state": state, "error": reason, "finished_at": utcnow()}
                progress = read_progress(self.layout(record.id).progress_file)
                if progress is not None:
                    fields["progress_json"] = progress.model_dump_json()
                if self.store.update_if(record.id, ["running"], **fields) is not None:
                    logger.warning("job %s %s: %s", record.id, state, reason)

    def _job_info(self, sid: str) -> Any | None:
        """Ray's ``JobDetails`` of submission ``sid``; None if Ray has no such job."""
        try:
            return self.connection.client.get_job_info(sid)
        except RuntimeError as exc:
            if "status code 404" in str(exc):
                return None
            raise

    def _follow(self, record: JobRecord) -> bool:
        """Copy the running job's progress; settle it if its Ray job ended. True if it still
        runs."""
        sid = record.ray_submission_id or submission_id(record.id, record.attempt)
        info = self._job_info(sid)
        layout = self.layout(record.id)
        progress = read_progress(layout.progress_file)
        status = None if info is None else str(info.status.value)
        if status in ("PENDING", "RUNNING"):
            if progress is not None and progress.model_dump_json() != record.progress_json:
                self.store.update_if(
                    record.id, ["running"], progress_json=progress.model_dump_json()
                )
            if record.cancel_requested:
                self._stop_after_grace(layout, sid)
            return True
        fields = outcome(record, info, progress, lambda: self._died(layout, sid, info))
        if progress is not None:
            fields["progress_json"] = progress.model_dump_json()
        self.store.update_if(record.id, ["running"], finished_at=utcnow(), **fields)
        logger.info(
            "job %s %s%s",
            record.id,
            fields["state"],
            f": {fields['error']}" if fields.get("error") else "",
        )
        return False

    def _stop_after_grace(self, layout: JobLayout, sid: str) -> None:
        try:
            waited = time.time() - layout.cancel_file.stat().st_mtime
        except FileNotFoundError:
            layout.cancel_file.touch()
            return
        if waited > self.cancel_grace_s:
            logger.warning("%s: no clean stop %.0f s after the cancel; Ray stops it", sid, waited)
            self.connection.client.stop_job(sid)

    def _died(self, layout: JobLayout, sid: str, info: Any | None) -> str:
        def ray_logs() -> str:
            return self.connection.client.get_job_logs(sid)

        tail = log_tail(layout.log_file, ray_logs if info is not None else None)
        return died_reason(sid, info, tail)

    def _start(self, record: JobRecord) -> None:
        """Submit the queued job's next attempt as a Ray job and mark it running."""
        attempt = record.attempt + 1
        sid = submission_id(record.id, attempt)
        layout = self.layout(record.id)
        previous = record.ray_submission_id
        if previous and previous != sid and self._still_runs(previous):
            return  # its earlier attempt is stopping; started in a later pass
        if self._job_info(sid) is None:  # else: submitted before a crash; adopt it
            layout.progress_file.unlink(missing_ok=True)  # the last attempt's: stale now
            layout.cancel_file.unlink(missing_ok=True)
            self.connection.client.submit_job(
                entrypoint=self.entrypoint(layout),
                submission_id=sid,
                runtime_env={"env_vars": {"GAITFORGE_JOB_ID": record.id, "PYTHONUNBUFFERED": "1"}},
                metadata={"gaitforge_job": record.id, "owner": record.owner},
            )
        self.store.update(
            record.id,
            state="running",
            attempt=attempt,
            ray_submission_id=sid,
            started_at=utcnow(),
            finished_at=None,
            error=None,
        )
        logger.info("job %s started (attempt %d, Ray job %s)", record.id, attempt, sid)

    def _still_runs(self, sid: str) -> bool:
        """Whether Ray still runs submission ``sid`` (an earlier attempt of a job failed while
        Ray did not answer); if so, ask Ray to stop it (its trainer checkpoints)."""
        info = self._job_info(sid)
        if info is None or info.status.is_terminal():
            self._stopping.discard(sid)
            return False
        if sid not in self._stopping:
            logger.warning("%s still runs on Ray: stopped before the next attempt starts", sid)
            self._stopping.add(sid)
        self.connection.client.stop_job(sid)
        return True

    def entrypoint(self, layout: JobLayout) -> str:
        """The fixed command a job runs: the entry module on the job's directory, with
        ``GAITFORGE_JOB_PYTHON`` (default: this interpreter on a local head, ``python`` on a
        cluster, as found on the PATH of its head node)."""
        default = sys.executable if self.connection.local else "python"
        python = os.environ.get("GAITFORGE_JOB_PYTHON") or default
        command = [python, "-m", "gaitforge.service.jobs.entry", "--job-dir", str(layout.dir)]
        if self.evaluate_episodes is not None:
            command += ["--evaluate-episodes", str(self.evaluate_episodes)]
        return shlex.join(command)
