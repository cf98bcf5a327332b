"""The worker pool on a real local Ray when its actors cannot run: actors that die on
creation, every one (a seed the environment refuses), end the run with their own error
after ``max_failures`` within the window instead of being replaced forever; and a pool
asking for more actors than its local Ray has CPUs is refused at once."""

from __future__ import annotations

import functools
import time
from collections.abc import Iterator

import pytest
import ray
from gaitforge.workers.policy_api import UniformExcitationPolicy
from gaitforge.workers.pool import ActorFailureError, WorkerPool, default_max_failures
from gaitforge.workers.ray_start import start_ray
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.spec_io import SpecError

POLICY = functools.partial(UniformExcitationPolicy, 6)  # elbow-reach has 6 muscles
ELBOW = load_scene("elbow-reach").resolved()
CPUS = 2


@pytest.fixture(scope="module", autouse=True)
def local_ray() -> Iterator[None]:
    start_ray(num_cpus=CPUS, logging_level="ERROR")  # never a cluster already running
    yield
    ray.shutdown()


def test_actors_that_die_on_creation_end_the_run_with_their_error() -> None:
    """Actor i resets its envs with seeds (seed + i) * 10000 + k: from seed -100 every
    actor's environment refuses its seed in the constructor (gymnasium), a real failure in
    a real actor process. The second failure is one more than allowed."""
    pool = WorkerPool(ELBOW, POLICY, num_workers=1, seed=-100, max_failures=1)
    start = time.monotonic()
    try:
        with pytest.raises(ActorFailureError) as caught:
            pool.next_fragment(timeout_s=300)
    finally:
        pool.close()
    message = str(caught.value)
    assert time.monotonic() - start < 240
    assert "\n" not in message
    assert message.startswith("rollout actors failed 2 times in 300 s (more than ")
    assert "workers.max_actor_failures 1" in message
    assert "first: actor 0 died: " in message and "; last: actor 1 died: " in message
    assert "Seed must be greater or equal to zero, actual value: -1000000" in message
    assert pool.stats.actor_deaths == 2 and pool.stats.actors_started == 2


def test_failures_outside_the_window_are_forgotten() -> None:
    """With a window shorter than one actor's start, failures never pile up: the pool goes
    on replacing (each failure alone in its window), past ``max_failures`` in all: the
    second failure, which would end the run within a window holding both, does not."""
    pool = WorkerPool(
        ELBOW, POLICY, num_workers=1, seed=-100, max_failures=1, failure_window_s=0.001
    )
    deadline = time.monotonic() + 240
    try:
        while pool.stats.actor_deaths < 2 and time.monotonic() < deadline:
            with pytest.raises(TimeoutError):  # no actor ever returns a fragment
                pool.next_fragment(timeout_s=1)
    finally:
        pool.close()
    assert pool.stats.actor_deaths >= 2


def test_the_default_limit_grows_with_the_pool() -> None:
    assert default_max_failures(1) == 10
    assert default_max_failures(64) == 128


def test_more_actors_than_the_local_ray_has_cpus_are_refused() -> None:
    with pytest.raises(SpecError) as caught:
        WorkerPool(ELBOW, POLICY, num_workers=CPUS + 1)
    assert str(caught.value) == (
        f"workers.num_workers: {CPUS + 1} rollout actors need {CPUS + 1} CPUs (one each); "
        f"this machine's Ray has {CPUS}: at most {CPUS} (or leave it out: the CPUs less one)"
    )
