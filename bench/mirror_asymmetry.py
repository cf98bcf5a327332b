"""How far a policy is from left-right symmetric, which is what ``ppo.mirror``'s mirror
images ask of it: on observations of its own rollout, the gap between its mean action at the
mirrored observation and the mirror of its mean action (per action, in action units and in
its action standard deviations), and how much less likely its mirrored samples are than its
own (mean log-probability, nats).

Usage: python bench/mirror_asymmetry.py CHECKPOINT --scene run-2d+clock [--envs 4] [--steps 250]
"""

from __future__ import annotations

import argparse
import functools
from pathlib import Path

import torch
from gaitforge.learner.checkpoint import load_policy
from gaitforge.learner.curriculum import StageIO
from gaitforge.learner.policy import build_policy
from gaitforge.learner.symmetry import MirrorMap
from gaitforge.workers.rollout import RolloutWorker
from gaitforge.workers.scenes import load_scene
from rich.console import Console
from rich.table import Table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("checkpoint", type=Path)
    parser.add_argument("--scene", required=True)
    parser.add_argument("--backend", default="mujoco")
    parser.add_argument("--envs", type=int, default=4)
    parser.add_argument("--steps", type=int, default=250, help="steps per env")
    parser.add_argument("--seed", type=int, default=3)
    args = parser.parse_args()
    policy, _ = load_policy(args.checkpoint)
    scene = load_scene(args.scene).resolved()
    io = StageIO(scene, args.backend)
    mirror = MirrorMap.from_names(io.obs_names, io.act_names, io.lateral_axis)
    worker = RolloutWorker(scene, functools.partial(build_policy, policy.describe()),
                           backend=args.backend, num_envs=args.envs,
                           fragment_length=args.steps, seed=args.seed)  # fmt: skip
    fragment = worker.sample(policy.state_dict(), 0)
    obs = torch.from_numpy(fragment.flat_obs()).float()
    actions = torch.from_numpy(fragment.action.reshape(-1, fragment.action.shape[-1])).float()
    with torch.no_grad():
        gap = (policy.mean_action(mirror.obs(obs)) - mirror.action(policy.mean_action(obs))).abs()
        std = policy.distribution(obs).stddev[0]
        own, _, _ = policy.evaluate(obs, actions)
        mirrored, _, _ = policy.evaluate(mirror.obs(obs), mirror.action(actions))
    table = Table("action", "std", "mean |mu(M o) - M mu(o)|", "in stds")
    for name, s, g in zip(io.act_names, std.tolist(), gap.mean(0).tolist(), strict=True):
        table.add_row(name, f"{s:.3f}", f"{g:.3f}", f"{g / s:.1f}")
    console = Console()
    console.print(table)
    console.print(
        f"{obs.shape[0]} samples: mean log-probability of its own actions "
        f"{own.mean():.1f} nats, of their mirror images {mirrored.mean():.1f} nats"
    )


if __name__ == "__main__":
    main()
