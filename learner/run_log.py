"""What a training run reports: batch statistics, each iteration's metrics and TensorBoard
scalars (the trainer's outputs besides checkpoints and recordings)."""

from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from gaitforge.learner.metrics import tensorboard_layout
from gaitforge.learner.policy import BlendedPolicy
from gaitforge.learner.ppo import PPOSettings
from gaitforge.learner.run_state import RunState
from gaitforge.workers.fragment import Fragment

if TYPE_CHECKING:
    from gaitforge.learner.cmaes import Generation
    from torch.utils.tensorboard import SummaryWriter


def batch_stats(fragments: list[Fragment], version: int) -> dict:
    """A batch's env steps, finished episodes, health causes (count), reward terms
    (weighted mean per env step) and ``policy_lag``: how many weight updates behind
    ``version`` (the newest published when the batch was gathered) its actions were sampled,
    mean per env step (0 for in-process rollouts; with Ray actors, requests queued before an
    update finish on the weights they carry)."""
    steps = sum(f.steps for f in fragments)
    health: Counter[str] = Counter()
    terms: Counter[str] = Counter()
    for f in fragments:
        health.update(f.health)
        terms.update({k: v * f.steps / steps for k, v in f.reward_terms.items()})
    return {
        "batch_steps": steps,
        "episodes": sum(f.episodes for f in fragments),
        "health": dict(health),
        "reward_terms": dict(terms),
        "policy_lag": sum((version - f.policy_version) * f.steps for f in fragments) / steps,
    }


def iteration_metrics(
    run: RunState,
    cfg: PPOSettings,
    losses: dict[str, float],
    stats: dict,
    sampled_s: float,
    elapsed_s: float,
) -> dict:
    """An iteration's metrics: where ``run`` is (iteration, env steps, stage and its env
    steps, names, ``train_s``: s of wall clock the run has trained), the blend's ``alpha``
    (None for one network), throughput (env steps per second of the whole iteration,
    ``elapsed_s``, and of sampling, ``sampled_s``), the stage's recent episodes
    (``CurriculumState.summary``), the learning rate and entropy weight of ``cfg``, PPO's
    ``losses`` and the batch's ``stats`` (:func:`batch_stats`, taken before the update,
    whose new weights would count every fragment one version further behind)."""
    steps = stats.pop("batch_steps")
    curriculum, policy = run.curriculum, run.policy
    return {
        **_where(run),
        "alpha": float(policy.alpha) if isinstance(policy, BlendedPolicy) else None,
        "steps_per_s": steps / max(elapsed_s, 1e-9),
        "sample_steps_per_s": steps / max(sampled_s, 1e-9),
        **curriculum.summary(),
        "lr": cfg.lr,
        "entropy_coef": cfg.entropy_coef,
        **losses,
        **stats,
    }


def _where(run: RunState) -> dict:
    """Where ``run`` is: iteration, env steps, stage (index, name, scene, env steps) and
    ``train_s`` (s of wall clock the run has trained)."""
    return {
        "iteration": run.iteration,
        "env_steps": run.env_steps,
        "stage": run.curriculum.stage,
        "stage_name": run.stage.name or run.scene.name,
        "scene": run.scene.name,
        "stage_env_steps": run.curriculum.stage_env_steps,
        "train_s": run.train_s,
    }


def search_metrics(run: RunState, generation: Generation, elapsed_s: float) -> dict:
    """A CMA-ES generation's metrics (an ``optimize`` stage's iteration): where ``run`` is,
    as :func:`iteration_metrics` says it, and the generation's figures as ``cmaes_*`` (best
    and mean cost, sigma, the best candidate's parts, its generation and the search's
    wall-clock s)."""
    row = generation.row()
    figures = {f"cmaes_{k}": v for k, v in row.items() if k != "env_steps"}
    return {
        **_where(run),
        "steps_per_s": generation.steps / max(elapsed_s, 1e-9),
        **figures,
    }


class ScalarLog:
    """TensorBoard scalars in ``log_dir``: every number of an iteration's metrics under
    ``train/``, and each reward term and health cause under their own group; x = env steps.
    The custom-scalars tab charts each episode metric's training and evaluation curves
    together (``learner.metrics.tensorboard_layout``).
    The writer (and tensorboard's import) waits for the first call."""

    def __init__(self, log_dir: Path, enabled: bool = True) -> None:
        self.log_dir = log_dir
        self.enabled = enabled
        self._writer: SummaryWriter | None = None

    def log(self, metrics: dict) -> None:
        if not self.enabled:
            return
        if self._writer is None:
            from torch.utils.tensorboard import SummaryWriter  # lazy: imports tensorboard

            self._writer = SummaryWriter(str(self.log_dir))
            self._writer.add_custom_scalars(tensorboard_layout())
        step = metrics["env_steps"]
        for key, value in metrics.items():
            if isinstance(value, int | float) and np.isfinite(value):
                self._writer.add_scalar(f"train/{key}", value, step)
        for group in ("reward_terms", "health"):
            for key, value in metrics.get(group, {}).items():
                self._writer.add_scalar(f"{group}/{key}", value, step)

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
