"""Anchor 1: stable-baselines3 PPO on MyoSuite's ``myoLegWalk-v0`` for a fixed training time.

    python bench/myoleg_anchors/sb3_walk.py --minutes M --seed S --out DIR [--resume]
        [--n-envs N] [--eval-episodes 10]

The env is MyoSuite's registered ``myoLegWalk-v0`` with its default reward and settings
(``reset_type="init"``, 1000-step episodes of 0.01 s). The only wrapper is an affine
``RescaleAction`` to [-1, 1] (SB3's advice for Box actions; activation = (a + 1) / 2), so
the policy's initial mean is activation 0.5 rather than half the muscles clipped at 0.

PPO: ``MlpPolicy`` with SB3's PPO defaults (n_steps 2048 per env, batch 64, 10 epochs,
lr 3e-4, gamma 0.99, GAE lambda 0.95, clip 0.2, no entropy bonus) except 256x256 policy
and value networks; ``VecNormalize`` on observations and rewards (as rl-zoo does for MuJoCo);
N envs in ``SubprocVecEnv`` (default: one per core).

Training stops when the run's training seconds reach ``--minutes`` (summed over
``--resume`` restarts; checkpoint writes and start-up are left out). Checkpoints every
10 min and at the end in ``DIR/checkpoints``; ``DIR/progress.csv`` every 30 s; at the end
``evaluate.py``'s JSON in ``DIR/eval.json`` and its table on stdout.
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium
import torch
from common import (
    ENV_ID,
    PROGRESS_FILE,
    STATE_FILE,
    ProgressLog,
    TrainClock,
    machine_cores,
    package_versions,
    prepare_run_dir,
    run_arguments,
    setup_logging,
    write_json,
)
from evaluate import evaluate_run, format_table
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import configure
from stable_baselines3.common.vec_env import (
    DummyVecEnv,
    SubprocVecEnv,
    VecEnv,
    VecMonitor,
    VecNormalize,
)

log = logging.getLogger("sb3_walk")

PPO_KWARGS: dict[str, Any] = {
    "n_steps": 2048,
    "batch_size": 64,
    "n_epochs": 10,
    "learning_rate": 3e-4,
    "gamma": 0.99,
    "gae_lambda": 0.95,
    "clip_range": 0.2,
    "ent_coef": 0.0,
    "vf_coef": 0.5,
    "max_grad_norm": 0.5,
    "policy_kwargs": {"net_arch": {"pi": [256, 256], "vf": [256, 256]}},
}
VECNORMALIZE_KWARGS: dict[str, Any] = {
    "norm_obs": True,
    "norm_reward": True,
    "clip_obs": 10.0,
    "gamma": 0.99,
}


def make_env() -> gymnasium.Env:
    """``myoLegWalk-v0`` as registered, its [0, 1] activations shown as [-1, 1] actions."""
    from myosuite.utils import gym

    env = gym.make(ENV_ID)
    return gymnasium.wrappers.RescaleAction(env, -1.0, 1.0)


def build_venv(n_envs: int) -> VecEnv:
    """``n_envs`` envs (in subprocesses when more than one), episode stats recorded."""
    fns: list[Callable[[], gymnasium.Env]] = [make_env] * n_envs
    venv = SubprocVecEnv(fns) if n_envs > 1 else DummyVecEnv(fns)
    return VecMonitor(venv)


class Checkpointer:
    """Saves the model and the normaliser statistics and records them in ``state.json``."""

    def __init__(self, out: Path, clock: TrainClock, interval_s: float) -> None:
        self.out = out
        self.clock = clock
        self.interval_s = interval_s
        (out / "checkpoints").mkdir(exist_ok=True)
        self.last_s = clock.elapsed()

    def save(self, model: PPO) -> None:
        """Write a checkpoint now (its time is left out of the training time)."""
        with self.clock.paused():
            steps = int(model.num_timesteps)
            rel = Path("checkpoints") / f"ppo_{steps}.zip"
            rel_norm = Path("checkpoints") / f"vecnormalize_{steps}.pkl"
            model.save(self.out / rel)
            env = model.get_env()
            assert isinstance(env, VecNormalize)
            env.save(str(self.out / rel_norm))
            state = {
                "checkpoint": str(rel),
                "vecnormalize": str(rel_norm),
                "env_steps": steps,
                "train_seconds": self.clock.elapsed(),
            }
            write_json(self.out / STATE_FILE, state)
        self.last_s = self.clock.elapsed()
        log.info("checkpoint %s at %.0f s of training", rel, state["train_seconds"])


class BudgetCallback(BaseCallback):
    """Records finished episodes, writes progress rows and checkpoints, stops at the budget."""

    def __init__(self, clock: TrainClock, progress: ProgressLog, ckpt: Checkpointer) -> None:
        super().__init__()
        self.clock = clock
        self.progress = progress
        self.ckpt = ckpt

    def _on_step(self) -> bool:
        for info in self.locals["infos"]:
            episode = info.get("episode")
            if episode is not None:
                self.progress.episode(episode["r"], episode["l"])
        now = self.clock.elapsed()
        self.progress.maybe_write(now, int(self.model.num_timesteps))
        if now - self.ckpt.last_s >= self.ckpt.interval_s:
            self.ckpt.save(self.model)
        return not self.clock.expired()


def train(args: argparse.Namespace) -> None:
    """Train (or resume) for the budget, checkpoint, then evaluate."""
    out: Path = args.out
    run_info = {
        "runner": "sb3",
        "env_id": ENV_ID,
        "seed": args.seed,
        "n_envs": args.n_envs,
        "checkpoint_minutes": args.checkpoint_minutes,
        "algorithm": "PPO",
        "ppo": PPO_KWARGS,
        "vecnormalize": VECNORMALIZE_KWARGS,
        "action_map": "RescaleAction: activation = (a + 1) / 2, a in [-1, 1]",
        "versions": package_versions("myosuite", "stable-baselines3", "torch", "gymnasium"),
        "argv": sys.argv,
    }
    state = prepare_run_dir(out, args.resume, run_info)
    clock = TrainClock(args.minutes * 60.0, state.get("train_seconds", 0.0))
    if clock.expired():
        log.info("budget already spent (%.0f s); evaluating", clock.elapsed())
    else:
        venv = build_venv(args.n_envs)
        if state:
            venv = VecNormalize.load(str(out / state["vecnormalize"]), venv)
            model = PPO.load(out / state["checkpoint"], env=venv, device="cpu")
            log.info("resumed %s at %d steps", state["checkpoint"], model.num_timesteps)
        else:
            venv = VecNormalize(venv, **VECNORMALIZE_KWARGS)
            model = PPO("MlpPolicy", venv, seed=args.seed, device="cpu", verbose=0, **PPO_KWARGS)
        model.set_logger(configure(str(out / "sb3_log" / f"from_{model.num_timesteps}"), ["csv"]))
        progress = ProgressLog(out / PROGRESS_FILE)
        ckpt = Checkpointer(out, clock, args.checkpoint_minutes * 60.0)
        clock.start()
        log.info("training for %.0f s more with %d envs", clock.remaining(), args.n_envs)
        model.learn(
            total_timesteps=10**12,
            callback=BudgetCallback(clock, progress, ckpt),
            reset_num_timesteps=not state,
        )
        progress.maybe_write(clock.elapsed(), int(model.num_timesteps), force=True)
        ckpt.save(model)
        venv.close()
    report = evaluate_run(out, episodes=args.eval_episodes, seed=args.eval_seed)
    print(format_table(report))


def main(argv: list[str] | None = None) -> None:
    """Command line: see the module docstring."""
    p = run_arguments(__doc__)
    p.add_argument("--n-envs", type=int, default=machine_cores(), help="default: cores")
    setup_logging()
    args = p.parse_args(argv)
    torch.set_num_threads(args.torch_threads)
    train(args)


if __name__ == "__main__":
    main()
