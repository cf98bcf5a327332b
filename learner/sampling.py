"""Where fragments come from: a Ray ``WorkerPool`` or one in-process ``RolloutWorker``, and
:class:`Rollouts`, the trainer's side of them.

Both samplers answer the same calls. A *version* is handed out with each weight update; a
fragment carries the version it was made with, so that the trainer can drop fragments made
before a scene or network switch (requests already queued finish on the old ones).
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable
from typing import Protocol

import numpy as np
import torch
from gaitforge.learner.job import WorkersSpec
from gaitforge.learner.policy import ActorCritic, build_policy
from gaitforge.workers.fragment import Fragment, StopRequested
from gaitforge.workers.gait_measure import CandidateScore, CandidateScorer, GaitMeasure
from gaitforge.workers.rollout import PolicyFactory, RolloutWorker
from gaitforge.workers.scenes import Scene


class Sampler(CandidateScorer, Protocol):
    version: int
    """the newest weights' version, handed out by ``set_weights`` and ``set_policy``"""

    def set_weights(self, weights: dict[str, torch.Tensor]) -> int: ...

    def set_scene(self, scene: Scene, backend: str | None = None) -> None: ...

    def set_policy(
        self, policy_factory: PolicyFactory, weights: dict[str, torch.Tensor]
    ) -> int: ...

    def next_fragment(
        self, timeout_s: float | None = None, stop: threading.Event | None = None
    ) -> tuple[Fragment, int]:
        """The next fragment and its policy version; raises ``StopRequested`` once ``stop``
        is set, ``TimeoutError`` when none comes within ``timeout_s``."""
        ...

    def close(self) -> None: ...


class LocalSampler:
    """One in-process ``RolloutWorker`` (tests, debugging, ``num_workers: 0``)."""

    def __init__(self, scene: Scene, policy_factory: PolicyFactory, **worker_kwargs) -> None:
        self.worker = RolloutWorker(scene, policy_factory, **worker_kwargs)
        self.version = -1
        self._weights: dict[str, torch.Tensor] | None = None

    def set_weights(self, weights: dict[str, torch.Tensor]) -> int:
        self.version += 1
        self._weights = {k: v.detach().clone() for k, v in weights.items()}
        return self.version

    def set_scene(self, scene: Scene, backend: str | None = None) -> None:
        self.worker.set_scene(scene, backend)

    def set_policy(self, policy_factory: PolicyFactory, weights: dict[str, torch.Tensor]) -> int:
        self.worker.set_policy(policy_factory)
        return self.set_weights(weights)

    def next_fragment(
        self, timeout_s: float | None = None, stop: threading.Event | None = None
    ) -> tuple[Fragment, int]:
        if stop is not None and stop.is_set():
            raise StopRequested
        return self.worker.sample(self._weights, self.version), self.version

    def score_candidates(
        self,
        candidates: list[np.ndarray],
        seeds: list[int],
        measure: GaitMeasure,
        stop: threading.Event | None = None,
    ) -> list[CandidateScore]:
        """Reflex controller candidates scored by the worker (``RolloutWorker``)."""
        return self.worker.score_candidates(candidates, seeds, measure, stop)

    def close(self) -> None:
        pass


def open_sampler(
    workers: WorkersSpec, scene: Scene, backend: str, policy_factory: PolicyFactory, seed: int
) -> Sampler:
    """A job's sampler for ``scene`` on ``backend``: one in-process worker for
    ``workers.num_workers: 0``, else a Ray ``WorkerPool`` (Ray started first at
    ``workers.ray_address`` if it is set and Ray is not up yet)."""
    kwargs = {"backend": backend, "fragment_length": workers.fragment_length, "seed": seed}
    if workers.num_workers == 0:
        return LocalSampler(scene, policy_factory, num_envs=workers.envs_per_worker, **kwargs)
    import ray  # lazy: the in-process mode needs no Ray
    from gaitforge.workers.pool import WorkerPool
    from gaitforge.workers.ray_start import start_ray

    if not ray.is_initialized() and workers.ray_address is not None:
        start_ray(workers.ray_address)
    return WorkerPool(
        scene,
        policy_factory,
        num_workers=workers.num_workers,
        envs_per_worker=workers.envs_per_worker,
        timeout_s=workers.timeout_s,
        max_failures=workers.max_actor_failures,
        failure_window_s=workers.actor_failure_window_s,
        **kwargs,
    )


def policy_factory(policy: ActorCritic) -> PolicyFactory:
    """What a worker builds ``policy``'s network with (its weights come apart)."""
    return functools.partial(build_policy, policy.describe())


class Rollouts:
    """The trainer's side of the rollout workers over one :meth:`Trainer.run`: the job's
    sampler (:meth:`open`, :meth:`close`), the weights and networks it acts with, and the
    fragments of the current ones (:meth:`gather`; one made before a scene or network switch
    is dropped).

    Args:
        workers: the job's ``workers`` section.
        stop: set to stop waiting for fragments (``StopRequested`` is raised).
    """

    def __init__(self, workers: WorkersSpec, stop: threading.Event) -> None:
        self.workers = workers
        self.stop = stop
        self._sampler: Sampler | None = None
        self._min_version = 0
        """fragments of older weights are dropped"""

    @property
    def sampler(self) -> Sampler:
        if self._sampler is None:
            raise RuntimeError("rollouts: no sampler open (Rollouts.open first)")
        return self._sampler

    @property
    def version(self) -> int:
        """the newest weights' version"""
        return self.sampler.version

    def open(self, scene: Scene, backend: str, policy: ActorCritic, seed: int) -> None:
        """Start the job's workers on ``scene`` with ``backend``, acting with ``policy``; the
        workers' seeds come from ``seed``."""
        self._sampler = open_sampler(self.workers, scene, backend, policy_factory(policy), seed)
        self._min_version = self._sampler.set_weights(policy.state_dict())

    def close(self) -> None:
        if self._sampler is not None:
            self._sampler.close()
            self._sampler = None

    def gather(self, env_steps: int, count: Callable[[Fragment], None]) -> list[Fragment]:
        """Fragments of the current weights or newer, at least ``env_steps`` env steps of
        them; each is passed to ``count`` as it comes (every one counts in the run's env
        steps and the stage's episodes, even if a stop drops the batch).

        Raises:
            StopRequested: ``stop`` was set while fragments were awaited.
        """
        fragments: list[Fragment] = []
        while sum(f.steps for f in fragments) < env_steps:
            fragment, version = self.sampler.next_fragment(self.workers.timeout_s, self.stop)
            if version < self._min_version:
                continue  # made before a scene or network switch
            fragments.append(fragment)
            count(fragment)
        return fragments

    def publish(self, policy: ActorCritic) -> None:
        """The workers act with ``policy``'s new weights from their next fragments on (ones
        already asked for finish on the weights they were asked with)."""
        self.sampler.set_weights(policy.state_dict())

    def set_policy(self, policy: ActorCritic) -> None:
        """The workers act with ``policy``, a new network (or one changed in shape): only
        its fragments are gathered from now on."""
        self._min_version = self.sampler.set_policy(policy_factory(policy), policy.state_dict())

    def set_scene(self, scene: Scene, backend: str, policy: ActorCritic) -> None:
        """The workers go on in ``scene`` with ``backend``, acting with ``policy``: only
        fragments of the new scene are gathered from now on."""
        self.sampler.set_scene(scene, backend)
        self._min_version = self.sampler.set_weights(policy.state_dict())
