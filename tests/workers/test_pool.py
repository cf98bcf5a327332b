"""The worker pool on a real local Ray: fragments keep coming, weights and scenes reach live
actors, and crashing, hanging and NaN-ing simulators never stop the run."""

from __future__ import annotations

import functools
import threading
import time
from collections.abc import Callable, Iterator

import numpy as np
import pytest
import ray
import torch
from gaitforge.workers.fragment import StopRequested
from gaitforge.workers.policy_api import UniformExcitationPolicy
from gaitforge.workers.pool import WorkerPool
from gaitforge.workers.ray_start import start_ray
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.sim.faults import FAULTS_ENV, FaultInjection

POLICY = functools.partial(UniformExcitationPolicy, 6)  # elbow-reach has 6 muscles
ELBOW = load_scene("elbow-reach").resolved()


@pytest.fixture(scope="module", autouse=True)
def local_ray() -> Iterator[None]:
    start_ray(num_cpus=2, logging_level="ERROR")  # never a cluster already running
    yield
    ray.shutdown()


def test_an_unresolved_scene_is_refused() -> None:
    with pytest.raises(ValueError, match=r"^WorkerPool: scene 'elbow-reach' .* not resolved"):
        WorkerPool(load_scene("elbow-reach"), POLICY, num_workers=1)


@pytest.fixture
def inject(monkeypatch: pytest.MonkeyPatch) -> Callable[..., None]:
    """``inject(nan_prob=0.02)``: the actors' simulators fail so (the test hook's variable,
    which the pool passes on to its actors)."""

    def set_faults(**fault: float) -> None:
        for name, value in FaultInjection(**fault).as_environment().items():
            monkeypatch.setenv(name, value)

    return set_faults


def _collect(pool: WorkerPool, n: int) -> list[tuple[dict, int]]:
    return [pool.next_fragment(timeout_s=120) for _ in range(n)]


@pytest.fixture(scope="class")
def healthy_pool() -> Iterator[WorkerPool]:
    pool = WorkerPool(ELBOW, POLICY, num_workers=2, fragment_length=16)
    yield pool
    pool.close()


class TestHealthyActors:
    """Two actors without faults, shared by the tests that only collect fragments and push
    weights and scenes to live actors (each asserts that none was replaced); closed after
    the last of them, which frees the local Ray's two CPUs."""

    def test_fragments_arrive_with_the_policy_version_and_new_weights_reach_the_actors(
        self, healthy_pool: WorkerPool
    ) -> None:
        pool = healthy_pool
        first = _collect(pool, 4)
        assert {version for _, version in first} == {-1}
        seen = {frag.worker for frag, _ in first}
        deadline = time.monotonic() + 90  # actors start seconds apart on 2 busy cores
        while seen != {0, 1} and time.monotonic() < deadline:
            seen.add(pool.next_fragment(timeout_s=120)[0].worker)
        assert seen == {0, 1}
        policy = UniformExcitationPolicy(6)
        with torch.no_grad():
            policy.centre.fill_(0.95)  # mean excitation 0.5 before, about 0.8 after
        version = pool.set_weights(policy.state_dict())
        later = _collect(pool, 6)
        newest = [frag for frag, v in later if v == version]
        assert newest, "new weights never reached the actors"
        assert all(frag.action.mean() > 0.7 for frag in newest)
        assert pool.stats.actors_started == 2 and pool.stats.actor_deaths == 0

    def test_a_new_scene_reaches_live_actors_without_restarting_them(
        self, healthy_pool: WorkerPool
    ) -> None:
        pool = healthy_pool
        _collect(pool, 2)
        pool.set_scene(ELBOW.model_copy(update={"episode_s": 0.1}))
        # 5-step episodes: an env truncates 3 times in a 16-step fragment (once at most in
        # elbow-reach's 100-step ones); the two fragments each actor has queued come first
        for _ in range(12):
            frag, _ = pool.next_fragment(timeout_s=120)
            if frag.truncated.sum(axis=0).max() >= 2:
                break
        else:
            pytest.fail("no fragment of the new scene in 12")
        assert frag.worker in (0, 1) and pool.stats.actors_started == 2


def test_crashing_simulators_are_replaced_and_collection_goes_on(
    inject, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The first actor's simulators abort its process at their first step; its replacement,
    started once the variable is gone, runs clean and collection goes on."""
    inject(abort_prob=1.0)
    pool = WorkerPool(ELBOW, POLICY, num_workers=1, fragment_length=16)
    monkeypatch.delenv(FAULTS_ENV)  # read as each actor starts: replacements start clean
    try:
        frags = [frag for frag, _ in _collect(pool, 4)]  # and collection goes on
        assert {frag.worker for frag in frags} == {1}
        assert pool.stats.actor_deaths == 1 and pool.stats.actors_started == 2
        assert pool.stats.reissued >= pool.stats.actor_deaths
    finally:
        pool.close()


def test_after_a_stop_request_nothing_is_fetched_and_no_actor_replaced() -> None:
    """A stop (a signal, which may have killed the local node too) ends the wait at once: the
    dead actor's request is neither fetched nor re-issued on a new actor."""
    pool = WorkerPool(ELBOW, POLICY, num_workers=1, fragment_length=16)
    stop = threading.Event()
    try:
        _collect(pool, 1)
        ray.kill(pool._slots[0].actor, no_restart=True)
        stop.set()
        start = time.monotonic()
        with pytest.raises(StopRequested):
            pool.next_fragment(timeout_s=120, stop=stop)
        assert time.monotonic() - start < 5
        assert pool.stats.actors_started == 1 and pool.stats.actor_deaths == 0
    finally:
        pool.close()


def test_a_hung_simulator_times_out_and_is_replaced(
    inject, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The first actor's simulators hang at their first step (for an hour); 2 s after it
    came up it is killed and replaced by one started clean, and collection goes on (a
    fragment takes about 0.05 s here)."""
    inject(hang_prob=1.0)
    pool = WorkerPool(ELBOW, POLICY, num_workers=1, fragment_length=16, timeout_s=2.0)
    monkeypatch.delenv(FAULTS_ENV)  # read as each actor starts: replacements start clean
    try:
        frags = [frag for frag, _ in _collect(pool, 4)]
        assert {frag.worker for frag in frags} == {1}
        assert pool.stats.timeouts == 1 and pool.stats.actor_deaths == 0
        assert pool.stats.actors_started == 2
    finally:
        pool.close()


def test_nan_steps_are_counted_and_never_reach_the_fragments(inject) -> None:
    inject(nan_prob=0.02)  # about 2.5 NaN steps a fragment (32 steps, 4 envs)
    pool = WorkerPool(ELBOW, POLICY, num_workers=1, fragment_length=32)
    try:
        frags = [frag for frag, _ in _collect(pool, 6)]
        assert sum(pool.stats.health.values()) >= 1
        assert all(np.isfinite(frag.obs).all() for frag in frags)
        assert all(np.isfinite(frag.reward).all() for frag in frags)
    finally:
        pool.close()


def test_worn_actors_are_recycled() -> None:
    """64 env steps a fragment, worn at 100: actor 0 gets no new request once its second
    fragment is back, returns the one it had queued and only then is replaced by actor 1,
    whose steps count from 0 (its first fragment leaves it unworn): no work lost."""
    pool = WorkerPool(ELBOW, POLICY, num_workers=1, fragment_length=16, max_worker_steps=100)
    try:
        workers: list[int] = []
        while 1 not in workers and len(workers) < 10:
            workers.append(pool.next_fragment(timeout_s=120)[0].worker)
        assert workers == [0, 0, 0, 1]
        assert pool.stats.recycled == 1 and pool.stats.actors_started == 2
        assert pool.stats.actor_deaths == 0 and pool.stats.reissued == 0
    finally:
        pool.close()


def test_a_candidate_whose_actor_dies_mid_generation_is_rerun_not_the_generation() -> None:
    """CMA-ES candidates on the pool's actors: one actor is killed once the first score is
    back (the others still running or waiting); its candidate is scored again on the
    replacement and every other score is kept."""
    no_falls = {"episode_s": 1.0, "task.min_pelvis_height": 0.01}  # every episode runs 1 s
    scene = load_scene("reflex-walk-3d", overrides=no_falls).resolved()
    policy = functools.partial(UniformExcitationPolicy, 22)
    pool = WorkerPool(scene, policy, num_workers=2, envs_per_worker=1, queue_depth=0)
    try:
        from gaitforge.workers.gait_measure import GaitMeasure
        from gaitforge.workers.scenes.reflex_parameters import DEFAULTS

        def kill_after_the_first_score() -> None:
            while pool.stats.env_steps == 0:
                time.sleep(0.01)
            ray.kill(pool._slots[0].actor, no_restart=True)

        candidates = [DEFAULTS.copy() for _ in range(16)]
        killer = threading.Thread(target=kill_after_the_first_score)
        killer.start()
        scores = pool.score_candidates(candidates, [1, 2], GaitMeasure())
        killer.join()
    finally:
        pool.close()
    assert len(scores) == 16
    assert pool.stats.actor_deaths == 1 and pool.stats.actors_started == 3
    # the same parameters on the same starts score the same wherever they ran
    costs = [s.cost for s in scores]
    assert max(costs) - min(costs) < 1e-9
