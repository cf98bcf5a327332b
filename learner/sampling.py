"""Where fragments come from: a Ray ``WorkerPool`` or one in-process ``RolloutWorker``.

Both answer the same calls. A *version* is handed out with each weight update; a fragment
carries the version it was made with, so that the trainer can drop fragments made before a
scene or network switch (requests already queued finish on the old ones).
"""

from __future__ import annotations

import threading
from typing import Protocol

import torch
from gaitforge.learner.job import WorkersSpec
from gaitforge.workers.fragment import Fragment, StopRequested
from gaitforge.workers.rollout import PolicyFactory, RolloutWorker
from gaitforge.workers.scenes import Scene


class Sampler(Protocol):
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
        scene, policy_factory, num_workers=workers.num_workers,
        envs_per_worker=workers.envs_per_worker, timeout_s=workers.timeout_s,
        max_failures=workers.max_actor_failures,
        failure_window_s=workers.actor_failure_window_s, **kwargs,
    )  # fmt: skip
