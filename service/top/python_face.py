"""The Python face's operations, at the package top: train a job, evaluate a checkpoint, load
a trained policy. Each does what the CLI does (``gaitforge train``, ``gaitforge evaluate``),
with typed arguments and results; torch is imported at the first call.

Bad arguments raise ``gaitforge.service.ops.InputError`` (a ``SpecError``) naming the
argument; a bad job raises ``SpecError`` naming the file and field.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

if TYPE_CHECKING:
    from gaitforge.learner.checkpoint_meta import CheckpointMeta
    from gaitforge.learner.evaluation.results import EvaluationReport
    from gaitforge.learner.policy import ActorCritic
    from gaitforge.service.ops.train import TrainResult
    from gaitforge.workers.scenes import Scene


def train(
    job: str | Path | Mapping[str, Any],
    run_dir: str | Path | None = None,
    *,
    seed: int | None = None,
    overrides: Mapping[str, Any] | None = None,
    workers: int | None = None,
    address: str | None = None,
    budget_scale: float = 1.0,
    max_minutes: float | None = None,
    max_iterations: int | None = None,
    tensorboard: bool = True,
) -> TrainResult:
    """Train ``job`` (a job file, or a job as a mapping whose scene paths start at the
    working directory) into ``run_dir`` (default ``runs/<job name>``), resuming from its
    newest checkpoint there, until every stage is over, ``max_minutes`` of wall clock or
    ``max_iterations`` more updates.

    Args:
        seed: the job's seed, in place of its own.
        overrides: job fields set by dotted path (``{"ppo.lr": 1e-4}``), as ``--set``.
        workers: Ray rollout actors (0: in-process); default the job's.
        address: a Ray cluster to join; default a local Ray, started and stopped here.
        budget_scale: every stage's env steps times this (a smoke run: 0.01).

    Returns:
        Where the run stands: its directory, newest checkpoint, env steps, stage, finished.
    """
    from gaitforge.service.ops import validate_request
    from gaitforge.service.ops.train import TrainRequest, prepare_training

    source: dict[str, Any] = (
        {"job": dict(job)} if isinstance(job, Mapping) else {"job_file": Path(job)}
    )
    request = validate_request(
        TrainRequest,
        **source,
        run_dir=None if run_dir is None else Path(run_dir),
        workers=workers,
        address=address,
        budget_scale=budget_scale,
        seed=seed,
        overrides=dict(overrides or {}),
        tensorboard=tensorboard,
    )
    training = prepare_training(request)
    try:
        training.start_ray()
        max_seconds = None if max_minutes is None else 60.0 * max_minutes
        return training.run(max_iterations=max_iterations, max_seconds=max_seconds)
    finally:
        training.close()


def evaluate(
    checkpoint: str | Path,
    *,
    scene: str | Path | None = None,
    overrides: Mapping[str, Any] | None = None,
    backend: Literal["mujoco", "opensim"] | None = None,
    episodes: int = 10,
    modes: Sequence[Literal["deterministic", "stochastic"]] = ("deterministic",),
    seed: int = 0,
    sweep: Sequence[float] | None = None,
    record: str | Path | None = None,
    video: str | Path | None = None,
    gait: str | Path | None = None,
) -> EvaluationReport:
    """Evaluate ``checkpoint`` (a checkpoint or a run directory, its newest checkpoint) on
    ``episodes`` seeded episodes (seeds ``seed + i``), as ``gaitforge evaluate`` does.

    Args:
        scene: another scene to evaluate on (sizes must fit the policy); default its own.
        overrides: scene fields set by dotted path (``{"task.target_speed": 1.0}``).
        sweep: target-speed reductions in [0, 1) for the speed-against-safety sweep.
        record, video, gait: an MCAP recording, an MP4 and a gait-cycle PNG of the first
            episode.

    Returns:
        The report: per mode the figures with 95 % intervals and every episode
        (``report.results["deterministic"].fall_rate``); ``report.to_dict()`` is JSON-able.
    """
    from gaitforge.learner.evaluation.evaluate import evaluate_checkpoint

    def path(value: str | Path | None) -> Path | None:
        return None if value is None else Path(value)

    return evaluate_checkpoint(
        Path(checkpoint),
        scene=scene,
        scene_set=dict(overrides or {}),
        backend=backend,
        episodes=episodes,
        modes=modes,
        seed=seed,
        sweep=sweep,
        record=path(record),
        video=path(video),
        gait=path(gait),
    )


class TrainedPolicy:
    """A trained policy, to act in its scene's env: ``action = policy(obs)``.

    Attributes:
        network: the actor-critic (``learner.policy``), in eval mode.
        meta: the checkpoint's metadata (job, stage, metrics, provenance).
        scene: the scene it was trained on (``gaitforge.workers.env.MuscleEnv(policy.scene)``
            makes its env).
        obs_names: the observation entries it reads, in order.
    """

    def __init__(self, network: ActorCritic, meta: CheckpointMeta, scene: Scene) -> None:
        self.network = network
        self.meta = meta
        self.scene = scene
        self.obs_names: list[str] = list(meta.obs_names)

    def __call__(self, obs: np.ndarray, deterministic: bool = True) -> np.ndarray:
        """obs [n_obs] (the env's observation, float32) -> action [n_act] (float64, in the
        env's action space): the mean action, or with ``deterministic=False`` a sample."""
        import torch

        with torch.inference_mode():
            x = torch.as_tensor(np.asarray(obs), dtype=torch.float32).unsqueeze(0)
            if deterministic:
                action = self.network.mean_action(x)
            else:
                action = self.network.distribution(x).sample()
        return action[0].numpy().astype(np.float64)


def load_policy(checkpoint: str | Path) -> TrainedPolicy:
    """The policy of ``checkpoint`` (a checkpoint directory, e.g. ``examples/policies/
    walk-2d``, or a run directory: its newest checkpoint).

    Raises:
        EvaluationError: nothing there, or no checkpoint in it.
        CheckpointError: a damaged checkpoint, naming the file.
    """
    from gaitforge.learner.checkpoint import load_policy as load_network
    from gaitforge.learner.checkpoint_meta import META_FILE
    from gaitforge.learner.evaluation.evaluate import resolve_checkpoint

    path = resolve_checkpoint(Path(checkpoint))
    network, meta = load_network(path)
    return TrainedPolicy(network, meta, meta.scene_spec(path / META_FILE).resolved())
