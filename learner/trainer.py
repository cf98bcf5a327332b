"""A single-stage PPO training loop over rollout fragments, with checkpoints and resume.

Groundwork for the learner issue: one scene (no curriculum or blending yet). Fragments come
from a Ray ``WorkerPool`` (``num_workers >= 1``) or, with ``num_workers = 0``, from one
in-process ``RolloutWorker`` (tests, debugging). Each iteration gathers
``fragments_per_update`` fragments, updates the observation normaliser, runs PPO and
publishes the new weights. A checkpoint is written every ``checkpoint_every`` iterations;
``run`` resumes from the newest checkpoint in ``run_dir``, so a learner killed with SIGKILL
restarts from its last checkpoint with a monotonic env-step count.
"""

from __future__ import annotations

import functools
import logging
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import torch

from learner.checkpoint import latest_checkpoint, load_checkpoint, save_checkpoint
from learner.policy import GaussianPolicy
from learner.ppo import PPOConfig, batch_from_fragments, ppo_update
from workers.env import MuscleEnv
from workers.rollout import RolloutWorker
from workers.scenes import load_scene

if TYPE_CHECKING:
    from workers.pool import WorkerPool

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class TrainConfig:
    """One training run on one scene."""

    scene: str
    """catalogue name or scene YAML path"""
    run_dir: Path
    """checkpoints go to ``run_dir/checkpoints``"""
    backend: str = "mujoco"
    iterations: int = 100
    """PPO updates in the run (a resumed run counts the ones already done)"""
    num_workers: int = 0
    """Ray rollout actors; 0: one in-process worker"""
    envs_per_worker: int = 8
    fragment_length: int = 100
    fragments_per_update: int = 1
    hidden: tuple[int, ...] = (64, 64)
    checkpoint_every: int = 10
    seed: int = 0
    ppo: PPOConfig = field(default_factory=PPOConfig)


class Trainer:
    """Runs :class:`TrainConfig`; ``history`` holds one metrics dict per iteration."""

    def __init__(self, config: TrainConfig) -> None:
        self.config = config
        self.scene = load_scene(config.scene)
        probe = MuscleEnv(self.scene, config.backend)
        dims = (probe.observation_space.shape[0], probe.action_space.shape[0])
        self.policy_factory = functools.partial(GaussianPolicy, *dims, hidden=config.hidden)
        torch.manual_seed(config.seed)
        self.policy = self.policy_factory()
        self.optimizer = torch.optim.Adam(self.policy.parameters(), lr=config.ppo.lr)
        self.iteration = 0
        self.env_steps = 0
        self.history: list[dict] = []
        self._resume()

    @property
    def checkpoint_dir(self) -> Path:
        return self.config.run_dir / "checkpoints"

    def _resume(self) -> None:
        latest = latest_checkpoint(self.checkpoint_dir)
        if latest is None:
            return
        state, meta = load_checkpoint(latest)
        self.policy.load_state_dict(state)
        self.iteration, self.env_steps = int(meta["iteration"]), int(meta["env_steps"])
        logger.info("resumed from %s at iteration %d", latest, self.iteration)

    def _sampler(self) -> tuple[Callable[[], dict], WorkerPool | None]:
        """A function returning the next fragment, and the pool behind it (None in-process)."""
        cfg = self.config
        if cfg.num_workers == 0:
            worker = RolloutWorker(
                self.scene, self.policy_factory, backend=cfg.backend,
                num_envs=cfg.envs_per_worker, fragment_length=cfg.fragment_length,
                seed=cfg.seed + self.iteration,
            )  # fmt: skip
            return lambda: worker.sample(self.policy.state_dict(), self.iteration), None
        from workers.pool import WorkerPool  # lazy: imports Ray

        pool = WorkerPool(
            self.scene, self.policy_factory, backend=cfg.backend, num_workers=cfg.num_workers,
            envs_per_worker=cfg.envs_per_worker, fragment_length=cfg.fragment_length,
            seed=cfg.seed + self.iteration,
        )  # fmt: skip
        pool.set_weights(self.policy.state_dict())

        def sample() -> dict:
            return pool.next_fragment(timeout_s=600)[0]

        return sample, pool

    def run(self) -> list[dict]:
        cfg = self.config
        sample, pool = self._sampler()
        try:
            while self.iteration < cfg.iterations:
                fragments = [sample() for _ in range(cfg.fragments_per_update)]
                obs = np.concatenate([f["obs"].reshape(-1, f["obs"].shape[-1]) for f in fragments])
                self.policy.norm.update(torch.from_numpy(obs))
                stats = ppo_update(
                    self.policy, self.optimizer, batch_from_fragments(fragments, cfg.ppo), cfg.ppo
                )
                if pool is not None:
                    pool.set_weights(self.policy.state_dict())
                self.iteration += 1
                self.env_steps += sum(int(f["steps"]) for f in fragments)
                returns = np.concatenate([f["episode_return"] for f in fragments])
                stats.update(
                    iteration=self.iteration,
                    env_steps=self.env_steps,
                    episode_return=float(returns.mean()) if returns.size else float("nan"),
                )
                self.history.append(stats)
                if self.iteration % cfg.checkpoint_every == 0 or self.iteration == cfg.iterations:
                    self._checkpoint(stats)
        finally:
            if pool is not None:
                pool.close()
        return self.history

    def _checkpoint(self, stats: dict) -> None:
        meta = {
            "iteration": self.iteration,
            "scene": self.scene.model_dump(mode="json"),
            "config": {**asdict(self.config), "run_dir": str(self.config.run_dir)},
            "metrics": stats,
            "network": self.policy.describe(),
        }
        save_checkpoint(self.checkpoint_dir, self.env_steps, self.policy.state_dict(), meta,
                        best_metric="episode_return")  # fmt: skip
