"""What a training run reports: batch statistics, TensorBoard scalars and MCAP recordings
of the current policy (the trainer's outputs besides checkpoints)."""

from __future__ import annotations

import logging
from collections import Counter
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from gaitforge.learner.policy import ActorCritic
from gaitforge.workers.episode import EpisodeRunner
from gaitforge.workers.fragment import Fragment
from gaitforge.workers.scenes import Scene

if TYPE_CHECKING:
    from torch.utils.tensorboard import SummaryWriter

logger = logging.getLogger(__name__)


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


class ScalarLog:
    """TensorBoard scalars in ``log_dir``: every number of an iteration's metrics under
    ``train/``, and each reward term and health cause under their own group; x = env steps.
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
        step = metrics["env_steps"]
        for key, value in metrics.items():
            if isinstance(value, int | float) and np.isfinite(value):
                self._writer.add_scalar(f"train/{key}", value, step)
        for group in ("reward_terms", "health"):
            for key, value in metrics[group].items():
                self._writer.add_scalar(f"{group}/{key}", value, step)

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()


def record_policy(
    policy: ActorCritic, scene: Scene, backend: str, checkpoint: Path, path: Path, seed: int
) -> Path | None:
    """One deterministic episode of ``policy`` on ``scene`` as MCAP at ``path``, with the
    checkpoint it shows named in the metadata (the episode loop of ``workers.episode``, the
    recorder its observer). A failure is logged, never raised: a recording must not stop
    training."""
    from gaitforge.learner.evaluate import policy_act
    from gaitforge.learner.recording import EpisodeRecorder, checkpoint_metadata  # lazy: foxglove

    try:
        with EpisodeRunner(scene, backend) as runner:
            recorder = EpisodeRecorder(path, runner.env, checkpoint_metadata(checkpoint))
            summary = runner.run(policy_act(policy, "deterministic", seed), seed, [recorder])
    except Exception:
        logger.exception("recording %s failed; training goes on", path)
        return None
    logger.info("recorded %s: %.2f m in %.1f s", path, summary.distance_m, summary.sim_time_s)
    return path
