"""A pool of rollout actors on Ray that keeps every actor stepping and survives failures.

Each actor always has ``queue_depth`` (2) ``sample`` requests queued, so it starts its next
fragment the moment it returns one, without waiting for the driver's round trip (with one
request in flight a MuJoCo actor idled a quarter of its time). ``next_fragment`` waits
(``ray.wait``) for whichever fragment comes back first, queues that actor's next request
with the newest weights, and hands the fragment over with the policy version that produced
it: the learner never waits on the slowest simulator.

Failures are counted in :class:`PoolStats` and end a run only when they keep coming:
* an actor that dies (simulator segfault, lost node, out of memory) is replaced and its
  queued requests re-issued on the new actor;
* a fragment not back within ``timeout_s`` (a hung simulator) gets its actor killed and
  replaced;
* more than ``max_failures`` of those two within ``failure_window_s`` (an actor that cannot
  start: every replacement dies the same way) raise :class:`ActorFailureError` with the
  actors' own error, instead of replacing them forever;
* an actor past ``max_worker_rss_mib`` of memory or ``max_worker_steps`` env steps gets no
  new requests and is replaced once its queued ones are back (recycled, no work lost).

The same actors score reflex controller candidates (``score_candidates``, a CMA-ES
generation): one candidate per actor at a time, and a candidate whose actor dies or hangs
is re-run on its replacement, not the generation. A pool made with ``queue_depth=0`` queues
no fragments (``gaitforge tune``: candidates only).

The pool asks for no more actors than a cluster that cannot grow has CPUs (one each): on a
Ray this driver started, more raise ``SpecError`` at once (they would wait forever); on a
cluster it joined, an autoscaler may add nodes for them (a warning is logged).
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections import Counter, deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import ray
from gaitforge.workers.fragment import Fragment, StopRequested
from gaitforge.workers.gait_measure import CandidateScore, GaitMeasure
from gaitforge.workers.ray_start import start_ray
from gaitforge.workers.rollout import PolicyFactory, RolloutWorker
from gaitforge.workers.scenes import Scene
from gaitforge.workers.scenes.profiles import FidelityProfile
from gaitforge.workers.spec_io import SpecError
from ray.exceptions import RayActorError, RayError

logger = logging.getLogger(__name__)

POLL_S = 0.5
"""How often (s) ``next_fragment`` looks at the clocks of in-flight requests."""
MIN_FAILURES = 10
"""The least ``max_failures`` defaults to (see :func:`default_max_failures`)."""
FAILURE_WINDOW_S = 300.0
"""The default window (s) in which actor failures are counted."""
MAX_ERROR_CHARS = 300
"""Characters of an actor's error kept in :class:`ActorFailureError`'s message."""


class ActorFailureError(RuntimeError):
    """Rollout actors failed (died or hung) more than ``max_failures`` times within
    ``failure_window_s``: the run cannot go on. The message is one line with the first and
    the last actor's own error (e.g. the exception its constructor raised)."""


@dataclass
class PoolStats:
    """Counters since the pool started."""

    fragments: int = 0
    env_steps: int = 0
    actors_started: int = 0
    actor_deaths: int = 0
    timeouts: int = 0
    recycled: int = 0
    reissued: int = 0
    health: Counter = field(default_factory=Counter)

    def as_dict(self) -> dict:
        out = {k: v for k, v in self.__dict__.items() if k != "health"}
        out["health"] = dict(self.health)
        return out


@dataclass
class _Slot:
    """One actor and its queued requests. Its clock (``progress_at``: when it last returned a
    fragment) starts only once the actor is up (``started`` resolved): starting an actor
    takes seconds (imports, model compile) and, while its node is missing, as long as the
    node takes to come back."""

    actor: ray.actor.ActorHandle
    worker_id: int
    started: ray.ObjectRef | None = None
    requests: list[ray.ObjectRef] = field(default_factory=list)
    progress_at: float = 0.0
    retiring: bool = False

    @property
    def up(self) -> bool:
        return self.started is None


class WorkerPool:
    """``num_workers`` Ray actors, each with ``envs_per_worker`` envs of ``scene``, which
    must be resolved (``Scene.resolved``) where it was loaded: actors on other nodes look up
    no fidelity profile (``ValueError`` otherwise)."""

    def __init__(
        self,
        scene: Scene,
        policy_factory: PolicyFactory,
        *,
        backend: str = "mujoco",
        num_workers: int | None = None,
        envs_per_worker: int = 4,
        fragment_length: int = 64,
        timeout_s: float = 300.0,
        max_worker_steps: int | None = None,
        max_worker_rss_mib: float | None = None,
        queue_depth: int = 2,
        seed: int = 0,
        max_failures: int | None = None,
        failure_window_s: float = FAILURE_WINDOW_S,
    ) -> None:
        self.scene = scene.require_resolved("WorkerPool")
        if not ray.is_initialized():
            start_ray()
        count = num_workers or default_num_workers()
        check_num_workers(count)
        self.backend = backend
        self.timeout_s = timeout_s
        self.max_failures = max_failures or default_max_failures(count)
        self.failure_window_s = failure_window_s
        self._failures: deque[tuple[float, str]] = deque()
        """(when, the actor's error) of each failure within the window"""
        self.max_worker_steps = max_worker_steps
        self.max_worker_rss_mib = max_worker_rss_mib
        self.queue_depth = queue_depth
        self.stats = PoolStats()
        self.version = -1
        self._weights: ray.ObjectRef | None = None
        self._seed = seed
        self._next_id = 0
        self._actor_class = ray.remote(num_cpus=1, max_restarts=0)(RolloutWorker)
        self._actor_kwargs = {
            "policy_factory": policy_factory,
            "backend": backend,
            "num_envs": envs_per_worker,
            "fragment_length": fragment_length,
        }
        self._slots = [self._new_slot() for _ in range(count)]
        for slot in self._slots:
            self._fill(slot)

    # ---- learner-facing API -------------------------------------------------------------

    def set_weights(self, weights: dict) -> int:
        """Put ``weights`` in the object store once; requests from now on carry them."""
        self.version += 1
        self._weights = ray.put(weights)
        return self.version

    def set_scene(self, scene: Scene, backend: str | None = None) -> None:
        """Push a new scene (curriculum stage), on ``backend`` if given, to the live actors
        without restarting them: each switches after its in-flight fragment. Replacements
        start on it."""
        self.scene = scene.require_resolved("WorkerPool.set_scene")
        if backend is not None:
            self.backend = self._actor_kwargs["backend"] = backend
        for slot in self._slots:
            slot.actor.set_scene.remote(scene, backend)

    def set_policy(self, policy_factory: PolicyFactory, weights: dict) -> int:
        """Give every actor a new policy structure and its weights; returns the version from
        which fragments come from it (requests queued before it finish on the old one)."""
        self._actor_kwargs["policy_factory"] = policy_factory
        for slot in self._slots:
            slot.actor.set_policy.remote(policy_factory)
        return self.set_weights(weights)

    def next_fragment(
        self, timeout_s: float | None = None, stop: threading.Event | None = None
    ) -> tuple[Fragment, int]:
        """The first fragment back from any actor, and the policy version that made it.

        Once ``stop`` is set no fragment is fetched and no actor replaced (the signal that
        stopped the driver may have stopped its node too, where Ray was not started by
        :func:`start_ray`, and fetching an object from it, or starting an actor on it, can
        end the driver).

        Raises:
            StopRequested: ``stop`` was set (looked at every ``POLL_S`` while waiting).
            TimeoutError: no fragment within ``timeout_s``.
        """
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        while deadline is None or time.monotonic() < deadline:
            by_ref = {ref: slot for slot in self._slots for ref in slot.requests}
            ready, _ = ray.wait(list(by_ref), num_returns=1, timeout=POLL_S)
            if stop is not None and stop.is_set():
                raise StopRequested
            if ready:
                slot = by_ref[ready[0]]
                slot.requests.remove(ready[0])
                try:
                    fragment = ray.get(ready[0])
                except RayError as exc:
                    self._on_death(slot, exc)
                    continue
                self._account(slot, fragment)
                return fragment, fragment.policy_version
            self._kill_overdue()
        raise TimeoutError(f"no fragment within {timeout_s} s")

    def score_candidates(
        self,
        candidates: list[np.ndarray],
        seeds: list[int],
        measure: GaitMeasure,
        stop: threading.Event | None = None,
    ) -> list[CandidateScore]:
        """Each candidate's score (``RolloutWorker.score``), in order: one at a time per
        actor, the next handed to whichever actor is free. A candidate whose actor dies, or
        takes over ``timeout_s`` once its actor is up, is re-run on the replacement (counted
        as a failure, as fragments are).

        Raises:
            StopRequested: ``stop`` was set.
            ActorFailureError: too many failures (see the module docstring).
        """
        pending = deque(range(len(candidates)))
        scores: list[CandidateScore | None] = [None] * len(candidates)
        running: dict[ray.ObjectRef, tuple[_Slot, int]] = {}
        while pending or running:
            busy = {id(slot) for slot, _ in running.values()}
            for slot in self._slots:
                if pending and id(slot) not in busy:
                    index = pending.popleft()
                    ref = slot.actor.score.remote(candidates[index], seeds, measure)
                    running[ref] = (slot, index)
                    slot.progress_at = time.monotonic()  # the candidate's clock
            ready, _ = ray.wait(list(running), num_returns=1, timeout=POLL_S)
            if stop is not None and stop.is_set():
                raise StopRequested
            for ref in ready:
                slot, index = running.pop(ref)
                try:
                    score = ray.get(ref)
                except RayError as exc:
                    self._on_death(slot, exc)
                    pending.appendleft(index)
                    continue
                scores[index] = score
                self.stats.env_steps += score.env_steps
            ref_of = {id(slot): ref for ref, (slot, _) in running.items()}
            busy_slots = [slot for slot, _ in running.values()]
            for slot in self._kill_overdue(busy_slots, awaited="score"):
                _, index = running.pop(ref_of[id(slot)])
                pending.appendleft(index)
        for slot in self._slots:  # a fragment's clock starts now, not before the scoring
            slot.progress_at = time.monotonic()
        return [score for score in scores if score is not None]

    @property
    def num_workers(self) -> int:
        return len(self._slots)

    def node_ids(self) -> list[str]:
        """The Ray node of each live actor (blocks until all have started)."""
        return ray.get([slot.actor.node_id.remote() for slot in self._slots], timeout=120)

    def sim_profiles(self) -> list[FidelityProfile]:
        """The fidelity profile each live actor's simulators integrate with (blocks until
        all have started)."""
        return ray.get([slot.actor.sim_profile.remote() for slot in self._slots], timeout=120)

    def close(self) -> None:
        for slot in self._slots:
            ray.kill(slot.actor)
        self._slots = []

    # ---- actors -------------------------------------------------------------------------

    def _new_slot(self) -> _Slot:
        worker_id = self._next_id
        self._next_id += 1
        actor = self._actor_class.options(**_test_hooks()).remote(
            self.scene, seed=self._seed + worker_id, worker_id=worker_id, **self._actor_kwargs
        )
        self.stats.actors_started += 1
        return _Slot(actor=actor, worker_id=worker_id, started=actor.node_id.remote())

    def _fill(self, slot: _Slot) -> None:
        """Queue requests on ``slot``'s actor up to ``queue_depth``, with the newest weights."""
        while len(slot.requests) < self.queue_depth:
            slot.requests.append(slot.actor.sample.remote(self._weights, self.version))

    def _replace(self, slot: _Slot) -> None:
        """Kill ``slot``'s actor, start a new one in its place and re-issue its requests."""
        ray.kill(slot.actor, no_restart=True)
        self.stats.reissued += len(slot.requests)
        new = self._new_slot()
        slot.actor, slot.worker_id, slot.started = new.actor, new.worker_id, new.started
        slot.requests, slot.retiring = [], False
        self._fill(slot)

    def _on_death(self, slot: _Slot, exc: Exception) -> None:
        kind = "died" if isinstance(exc, RayActorError) else "failed"
        error = actor_error(exc)
        logger.warning("rollout actor %d %s: %s", slot.worker_id, kind, error)
        self.stats.actor_deaths += 1
        self.stats.reissued += 1  # the request that failed
        self._count_failure(f"actor {slot.worker_id} {kind}: {error}")
        self._replace(slot)

    def _count_failure(self, error: str) -> None:
        """Count one actor failure; past ``max_failures`` within ``failure_window_s``, raise.

        Raises:
            ActorFailureError: naming the first and the last failure in the window.
        """
        now = time.monotonic()
        self._failures.append((now, error))
        while self._failures and now - self._failures[0][0] > self.failure_window_s:
            self._failures.popleft()
        if len(self._failures) <= self.max_failures:
            return
        first, last = self._failures[0][1], self._failures[-1][1]
        raise ActorFailureError(
            f"rollout actors failed {len(self._failures)} times in {self.failure_window_s:g} s "
            f"(more than workers.max_actor_failures {self.max_failures}); first: {first}"
            + ("" if last == first else f"; last: {last}")
        )

    def _kill_overdue(
        self, slots: list[_Slot] | None = None, awaited: str = "fragment"
    ) -> list[_Slot]:
        """Start the clock of each of ``slots`` (default: every slot) whose actor has come
        up; kill and replace each that has been up ``timeout_s`` without returning its
        ``awaited`` result (a fragment, a candidate's score). Returns the slots replaced."""
        now = time.monotonic()
        replaced = []
        for slot in self._slots if slots is None else slots:
            if not slot.up:
                done, _ = ray.wait([slot.started], timeout=0)
                if done:  # up now: its clock starts
                    slot.started, slot.progress_at = None, now
                continue
            if now - slot.progress_at > self.timeout_s:
                logger.warning(
                    "rollout actor %d: no %s in %.0f s, replacing it",
                    slot.worker_id,
                    awaited,
                    self.timeout_s,
                )
                self.stats.timeouts += 1
                self._count_failure(
                    f"actor {slot.worker_id} hung: no {awaited} in {self.timeout_s:g} s "
                    "(workers.timeout_s)"
                )
                self._replace(slot)
                replaced.append(slot)
        return replaced

    def _account(self, slot: _Slot, fragment: Fragment) -> None:
        slot.progress_at = time.monotonic()
        self.stats.fragments += 1
        self.stats.env_steps += fragment.steps
        self.stats.health.update(fragment.health)
        max_steps, max_rss = self.max_worker_steps, self.max_worker_rss_mib
        worn = (max_steps is not None and fragment.worker_steps_total >= max_steps) or (
            max_rss is not None and fragment.rss_mib > max_rss
        )
        if worn and not slot.retiring:  # no new requests: let the queued ones finish
            slot.retiring = True
            self.stats.recycled += 1
        if not slot.retiring:
            self._fill(slot)
        elif not slot.requests:  # drained: a recycle loses no work
            self._replace(slot)


def default_num_workers() -> int:
    """The cluster's CPUs less one for the learner (at least one)."""
    return max(1, int(ray.cluster_resources().get("CPU", 2)) - 1)


def default_max_failures(num_workers: int) -> int:
    """Actor failures a pool of ``num_workers`` replaces within its window: twice the actors
    (a lost node takes all of its actors at once), at least :data:`MIN_FAILURES`."""
    return max(MIN_FAILURES, 2 * num_workers)


def check_num_workers(num_workers: int) -> None:
    """Refuse more actors than a Ray this driver started has CPUs (one CPU each: the others
    would wait forever); on a cluster it joined, where an autoscaler may add nodes, warn.

    Raises:
        SpecError: one line naming ``workers.num_workers``, the CPUs and what is allowed.
    """
    cpus = int(ray.cluster_resources().get("CPU", 0))
    if num_workers <= cpus:
        return
    if _started_here():
        raise SpecError(
            f"workers.num_workers: {num_workers} rollout actors need {num_workers} CPUs (one "
            f"each); this machine's Ray has {cpus}: at most {cpus} (or leave it out: the "
            "CPUs less one)"
        )
    logger.warning(
        "%d rollout actors need %d CPUs; the Ray cluster has %d now: the others wait for "
        "nodes (an autoscaler's)",
        num_workers,
        num_workers,
        cpus,
    )


def _started_here() -> bool:
    """Whether this process started the Ray it is connected to (``ray.init`` with no cluster
    to join): then no autoscaler can add nodes. Read from Ray's worker state (no public API
    says it); False where that is not there."""
    worker = getattr(getattr(ray, "_private", None), "worker", None)
    node = getattr(worker, "_global_node", None)
    return bool(getattr(node, "ray_init_cluster", False))


def actor_error(exc: BaseException) -> str:
    """An actor's failure in one line: the exception its own code raised (in its constructor
    or a task) where Ray passes it on, else the last line of Ray's message."""
    cause: object = exc
    seen = 0
    while isinstance(cause, BaseException) and seen < 10:
        if not isinstance(cause, RayError):
            text = f"{type(cause).__name__}: {cause}"
            return _one_line(text)
        cause = getattr(cause, "cause", None) or cause.__cause__
        seen += 1
    lines = [line.strip() for line in str(exc).splitlines() if line.strip()]
    return _one_line(lines[-1] if lines else type(exc).__name__)


def _one_line(text: str) -> str:
    text = " ".join(text.split())
    return text if len(text) <= MAX_ERROR_CHARS else text[:MAX_ERROR_CHARS] + "..."


__all__ = [
    "ActorFailureError",
    "PoolStats",
    "WorkerPool",
    "actor_error",
    "check_num_workers",
    "default_max_failures",
    "default_num_workers",
]


def _test_hooks() -> dict[str, Any]:
    """Actor options passing this process's fault injection on to the actors (a test hook:
    ``workers.sim.faults``); none when no test asks for it."""
    from gaitforge.workers.sim.faults import FAULTS_ENV

    if not os.environ.get(FAULTS_ENV):
        return {}
    return {"runtime_env": {"env_vars": {FAULTS_ENV: os.environ[FAULTS_ENV]}}}
