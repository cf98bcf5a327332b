"""Tuning a scene's reflex gait controller with CMA-ES (``learner.cmaes``), in-process or on
a Ray pool of rollout actors."""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

from gaitforge.learner.cmaes import CmaesTuning, Generation
from gaitforge.learner.stage_spec import StageOptimize
from gaitforge.service.ops.errors import InputError
from gaitforge.workers.policy_api import UniformExcitationPolicy
from gaitforge.workers.scenes import BackendMismatch, load_scene


def tune(
    scene_ref: str,
    out_dir: Path,
    settings: StageOptimize,
    backend: str = "mujoco",
    workers: int = 0,
    tensorboard: bool = True,
    seed: int = 0,
    overrides: dict[str, Any] | None = None,
) -> tuple[CmaesTuning, list[Generation]]:
    """Tune ``scene_ref``'s controller (with ``overrides``, dotted scene fields) into
    ``out_dir`` (resuming a state there) on ``backend``, with ``workers`` Ray actors (0: in
    this process).

    Raises:
        SpecError: the scene cannot be loaded (an ``InputError`` where it does not run on
            ``backend`` or has no reflex gait controller).
    """
    try:
        scene = load_scene(scene_ref, overrides, backend=backend).resolved()
    except BackendMismatch as exc:
        raise InputError("backend", str(exc)) from None
    # tuned.yaml runs on every backend the scene does: a search on MuJoCo goes on on OpenSim
    portable = load_scene(scene_ref, overrides)
    if not scene.action.gait:
        raise InputError(
            "scene",
            f"{scene.name!r}: action.kind is {scene.action.kind!r}, not reflex_gait "
            "(the controller CMA-ES tunes)",
        )
    from gaitforge.workers.rollout import RolloutWorker
    from gaitforge.workers.scenes.io_names import action_names

    # the policy is never asked: candidates run the controller alone
    act_dim = len(action_names(scene, backend))
    policy = functools.partial(UniformExcitationPolicy, act_dim)
    pool = None
    if workers > 0:
        from gaitforge.workers.pool import WorkerPool

        pool = WorkerPool(
            scene,
            policy,
            backend=backend,
            num_workers=workers,
            envs_per_worker=1,
            queue_depth=0,
            seed=seed,
        )
    scorer = pool or RolloutWorker(scene, policy, backend=backend, num_envs=1, seed=seed)
    try:
        tuning = CmaesTuning(scene, settings, out_dir, scorer, tensorboard, seed, written=portable)
        return tuning, tuning.run()
    finally:
        if pool is not None:
            pool.close()
