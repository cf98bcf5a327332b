"""How far a checkpoint's policy acts from its own mirror image, and where that leaves the
mirror images that ``ppo.mirror`` adds to every batch (``learner.symmetry``).

Each checkpoint plays a few episodes of its scene with sampled actions. For each visited
observation ``o`` the policy's mean at the mirrored observation is compared with the mirror
image of its mean at ``o`` (0 for a symmetric policy), and each sampled action and its
mirror image are measured in the policy's own noise: ``|a - mean| / std``, the largest over
the action's entries. A sampled action sits within about 3 of its mean; an image far beyond
that sits in the policy's tail, where a small change of the mean changes its probability by
orders of magnitude, and an update's KL (``approx_kl_mirrored`` in TensorBoard) follows.
With ``--update-to`` the KL of one update (the last checkpoint listed to the one given) is
measured on that checkpoint's samples and on their images.

Usage: python bench/mirror_asymmetry.py CKPT [CKPT ...] [--scene SCENE] [--episodes 8]
           [--seed 0] [--update-to NEXT_CKPT]
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from gaitforge.learner.checkpoint import load_policy
from gaitforge.learner.checkpoint_meta import META_FILE, CheckpointError, CheckpointMeta
from gaitforge.learner.curriculum import StageIO
from gaitforge.learner.evaluation.episodes import make_runner
from gaitforge.learner.evaluation.evaluate import EvaluationError, resolve_checkpoint
from gaitforge.learner.policy import ActorCritic
from gaitforge.learner.symmetry import MirrorMap
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.spec_io import SpecError
from rich.console import Console
from rich.table import Table

console = Console(width=140)


@dataclass
class Samples:
    """What a policy did on its scene: observations [N, obs_dim], sampled actions
    [N, act_dim], and the mirror map of the scene."""

    obs: torch.Tensor
    action: torch.Tensor
    mirror: MirrorMap


def play(
    policy: ActorCritic, obs_names: list[str] | None, scene: Scene, episodes: int, seed: int
) -> Samples:
    """``episodes`` episodes of ``policy`` (trained on inputs ``obs_names``; None: unnamed,
    only their number is known) on ``scene`` (MuJoCo) from seeds ``seed``.., actions sampled
    with a generator seeded with ``seed``.

    Raises:
        EvaluationError: the scene's sizes are not the policy's (``make_runner``).
        ValueError: the scene's body has no sides.
    """
    io = StageIO(scene, "mujoco")
    mirror = MirrorMap.from_names(io.obs_names, io.act_names, io.lateral_axis)
    generator = torch.Generator().manual_seed(seed)
    observations, actions = [], []
    runner = make_runner(policy, scene, "mujoco", obs_names)
    env = runner.env
    try:
        for episode in range(episodes):
            obs, _ = env.reset(seed=seed + episode)
            done = False
            while not done:
                x = torch.as_tensor(obs, dtype=torch.float32)
                with torch.no_grad():
                    dist = policy.distribution(x[None])
                    noise = torch.randn(dist.mean.shape, generator=generator)
                    action = (dist.mean + dist.stddev * noise)[0]
                observations.append(x)
                actions.append(action)
                obs, _, terminated, truncated, _ = env.step(action.numpy().astype(np.float64))
                done = terminated or truncated
    finally:
        runner.close()
    return Samples(torch.stack(observations), torch.stack(actions), mirror)


@torch.no_grad()
def asymmetry(policy: ActorCritic, samples: Samples) -> dict[str, float]:
    """The policy against its mirror image on ``samples``: the mean over samples of
    ``|mirror(mean(o)) - mean(mirror(o))|`` (its mean and largest over the action's entries;
    actions lie in [0, 1]), and the median over samples of the largest ``|a - mean| / std``
    of the sampled actions and of their mirror images."""
    mirror = samples.mirror
    own = policy.distribution(samples.obs)
    mirrored_obs = mirror.obs(samples.obs)
    seen = policy.distribution(mirrored_obs)
    gap = (mirror.action(own.mean) - seen.mean).abs().mean(0)
    sampled_z = ((samples.action - own.mean) / own.stddev).abs().amax(-1)
    image_z = ((mirror.action(samples.action) - seen.mean) / seen.stddev).abs().amax(-1)
    return {
        "noise": own.stddev.mean().item(),
        "gap_mean": gap.mean().item(),
        "gap_max": gap.max().item(),
        "sampled_z": sampled_z.median().item(),
        "image_z": image_z.median().item(),
    }


@torch.no_grad()
def one_update_kl(before: ActorCritic, after: ActorCritic, samples: Samples) -> dict[str, float]:
    """PPO's approximate KL ``mean((r - 1) - log r)`` with ``r = pi_after / pi_before`` on the
    sampled actions and on their mirror images, and the median ``|log r|`` of each."""
    mirror = samples.mirror
    result = {}
    for name, obs, action in (
        ("sampled", samples.obs, samples.action),
        ("images", mirror.obs(samples.obs), mirror.action(samples.action)),
    ):
        log_ratio = after.evaluate(obs, action)[0] - before.evaluate(obs, action)[0]
        result[f"{name}_kl"] = ((log_ratio.exp() - 1) - log_ratio).mean().item()
        result[f"{name}_log_ratio"] = log_ratio.abs().median().item()
    return result


def checkpoint_scene(path: Path, scene: str | None) -> tuple[ActorCritic, CheckpointMeta, Scene]:
    """The policy at checkpoint (or run directory) ``path``, its metadata and the scene it is
    played on (``scene``, else its own).

    Raises:
        EvaluationError, CheckpointError, SpecError: no such checkpoint or scene.
    """
    ckpt = resolve_checkpoint(path)
    policy, meta = load_policy(ckpt)
    chosen = load_scene(scene) if scene else meta.scene_spec(ckpt / META_FILE)
    return policy, meta, chosen.resolved()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoints", nargs="+", type=Path)
    parser.add_argument("--scene", help="a catalogue scene or YAML; default each checkpoint's")
    parser.add_argument("--episodes", type=int, default=8)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--update-to", type=Path, help="a later checkpoint: the KL of the update from the last"
    )
    args = parser.parse_args()
    if args.episodes < 1:
        parser.error(f"--episodes must be >= 1, got {args.episodes}")

    table = Table(
        title="The policy against its mirror image: the mirror gap |mirror(mean(o)) - "
        "mean(mirror(o))| (actions in [0, 1]); the median of max |a - mean| / std"
    )
    for column in (
        "checkpoint",
        "env steps",
        "samples",
        "noise (std)",
        "mirror gap: mean, largest entry",
        "|a - mean| / std: sampled",
        "images",
    ):
        table.add_column(column, justify="right")
    last: tuple[ActorCritic, Samples] | None = None
    try:
        for path in args.checkpoints:
            policy, meta, scene = checkpoint_scene(path, args.scene)
            samples = play(policy, meta.obs_names, scene, args.episodes, args.seed)
            last = (policy, samples)
            a = asymmetry(policy, samples)
            table.add_row(
                path.name,
                f"{meta.env_steps:,}",
                str(len(samples.obs)),
                f"{a['noise']:.3f}",
                f"{a['gap_mean']:.3f}, {a['gap_max']:.3f}",
                f"{a['sampled_z']:.1f}",
                f"{a['image_z']:.1f}",
            )
        after = None if args.update_to is None else checkpoint_scene(args.update_to, args.scene)[0]
    except (EvaluationError, CheckpointError, SpecError, ValueError) as exc:
        parser.error(str(exc))
    console.print(table)
    if after is not None and last is not None:
        kl = one_update_kl(last[0], after, last[1])
        update = Table(title=f"One update: {args.checkpoints[-1].name} -> {args.update_to.name}")
        for column in ("actions", "approx KL", "median |log ratio|"):
            update.add_column(column, justify="right")
        for name in ("sampled", "images"):
            update.add_row(name, f"{kl[f'{name}_kl']:.3g}", f"{kl[f'{name}_log_ratio']:.3g}")
        console.print(update)


if __name__ == "__main__":
    main()
