"""Mirror symmetry: the mirror image of an observation and an action, on real envs."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch
from gaitforge.learner.job import Job
from gaitforge.learner.policy import GaussianPolicy
from gaitforge.learner.ppo import PPOSettings, ppo_update
from gaitforge.learner.symmetry import MirrorMap, add_mirrored
from gaitforge.learner.trainer import Trainer
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.sim.base import Pose


def _map(scene: str) -> tuple[MuscleEnv, MirrorMap]:
    env = MuscleEnv(scene)
    lateral = 3 - env.sim.up_axis - env.sim.forward_axis
    return env, MirrorMap.from_names(env.obs_names, env.sim.muscle_names, lateral)


@pytest.mark.parametrize("scene", ["walk-2d", "walk-3d"])
def test_mirroring_twice_is_the_identity_and_swaps_sides(scene: str) -> None:
    env, mirror = _map(scene)
    obs = torch.randn(5, len(env.obs_names))
    torch.testing.assert_close(mirror.obs(mirror.obs(obs)), obs)
    names = env.obs_names
    once = mirror.obs(obs)
    i, j = names.index("q:knee_angle_r"), names.index("q:knee_angle_l")
    torch.testing.assert_close(once[:, i], obs[:, j])
    k, m = names.index("grf:foot_left"), names.index("grf:foot_right")
    torch.testing.assert_close(once[:, k], obs[:, m])
    lateral = "xyz"[3 - env.sim.up_axis - env.sim.forward_axis]
    v = names.index(f"pelvis_vel_{lateral}")
    torch.testing.assert_close(once[:, v], -obs[:, v])
    h = names.index("pelvis_height")
    torch.testing.assert_close(once[:, h], obs[:, h])
    muscles = env.sim.muscle_names
    action = torch.rand(3, len(muscles))
    flipped = mirror.action(action)
    a = muscles.index(next(n for n in muscles if n.endswith("_r")))
    b = muscles.index(muscles[a][:-2] + "_l")
    torch.testing.assert_close(flipped[:, a], action[:, b])


def test_the_mirror_image_of_a_posed_myoleg_is_the_mirrored_pose() -> None:
    """MyoLeg posed one way (the legs apart, the pelvis turned, listed and spinning), its
    observation mirrored, reads as MyoLeg posed the mirrored way: the two sides' joint axes
    mean the same motion, and the pelvis's up axis and angular velocity flip as they should."""
    env = MuscleEnv(load_scene("walk-3d"))
    lateral = 3 - env.sim.up_axis - env.sim.forward_axis
    mirror = MirrorMap.from_names(env.obs_names, env.sim.muscle_names, lateral)
    pelvis = [i for i, n in enumerate(env.obs_names) if n.startswith("pelvis_up")]
    pelvis += [i for i, n in enumerate(env.obs_names) if n.startswith("pelvis_angvel")]
    dofs = ("hip_flexion", "hip_adduction", "hip_rotation", "knee_angle", "ankle_angle")
    one_leg = dict(zip(dofs, (0.4, 0.1, 0.15, -0.5, 0.1), strict=True))
    other_leg = dict(zip(dofs, (-0.2, -0.05, 0.0, -0.1, -0.15), strict=True))

    def observed(side: float) -> torch.Tensor:
        env.reset(seed=0)
        right, left = (one_leg, other_leg) if side > 0 else (other_leg, one_leg)
        coordinates = {f"{dof}_r": angle for dof, angle in right.items()}
        coordinates |= {f"{dof}_l": angle for dof, angle in left.items()}
        pose = Pose(
            coordinates=coordinates,
            pelvis_pitch=0.1,
            pelvis_list=side * 0.15,
            pelvis_rotation=side * 0.4,
            pelvis_angular_speed=(0.3, side * 0.5, side * 1.0),
        )
        env.sim.set_pose(pose)
        return torch.as_tensor(env._observe(env.sim.state()))

    turned_left, turned_right = observed(1.0), observed(-1.0)
    assert turned_left[pelvis].abs().min() < 1.0  # not all axis-aligned
    torch.testing.assert_close(mirror.obs(turned_left), turned_right, atol=1e-4, rtol=0)
    assert not torch.allclose(turned_left[pelvis], turned_right[pelvis], atol=1e-2)
    assert not torch.allclose(turned_left, mirror.obs(turned_left), atol=1e-2)
    env.close()


def test_a_body_without_sides_cannot_be_mirrored() -> None:
    with pytest.raises(ValueError, match="no left and right muscles"):
        _map("elbow-reach")


def test_the_mirrored_batch_doubles_and_keeps_advantages() -> None:
    env, mirror = _map("walk-2d")
    policy = GaussianPolicy(len(env.obs_names), len(env.sim.muscle_names))
    n = 6
    batch = {
        "obs": torch.randn(n, len(env.obs_names)),
        "action": torch.rand(n, len(env.sim.muscle_names)),
        "logp": torch.randn(n),
        "value": torch.randn(n),
        "advantage": torch.randn(n),
        "return": torch.randn(n),
    }
    doubled = add_mirrored(batch, mirror, policy)
    assert all(v.shape[0] == 2 * n for v in doubled.values())
    torch.testing.assert_close(doubled["advantage"][n:], batch["advantage"])
    torch.testing.assert_close(doubled["obs"][n:], mirror.obs(batch["obs"]))
    logp, _, _ = policy.evaluate(doubled["obs"][n:], doubled["action"][n:])
    torch.testing.assert_close(doubled["logp"][n:], logp.detach())


def test_the_update_reports_the_kl_of_the_mirror_images_apart() -> None:
    """A policy that acts differently on the two sides (right muscles near 0.9, left near
    0.1, noise 0.05) puts the mirror images of its own samples far in its tails: one update
    moves their probabilities by orders of magnitude more than its samples' (the KL that the
    images of an asymmetric policy bring into an update)."""
    env, mirror = _map("walk-2d")
    muscles = env.sim.muscle_names
    policy = GaussianPolicy(len(env.obs_names), len(muscles), init_std=0.05)
    with torch.no_grad():
        side = torch.tensor([2.0 if m.endswith("_r") else -2.0 for m in muscles])
        policy.actor[-1].bias.copy_(side)
    generator = torch.Generator().manual_seed(0)
    n = 512
    obs = torch.randn(n, len(env.obs_names), generator=generator)
    with torch.no_grad():
        action, logp, value = policy.act(obs)
    batch = {
        "obs": obs,
        "action": action,
        "logp": logp,
        "value": value,
        "advantage": torch.randn(n, generator=generator),
        "return": torch.randn(n, generator=generator),
    }
    doubled = add_mirrored(batch, mirror, policy)
    assert doubled["mirrored"].sum() == n and not doubled["mirrored"][:n].any()
    optimizer = torch.optim.Adam(policy.parameters(), lr=1e-3)
    cfg = PPOSettings(epochs=2, minibatch_size=256, target_kl=None)
    stats = ppo_update(policy, optimizer, doubled, cfg, generator)
    assert stats["approx_kl_mirrored"] > 100 * stats["approx_kl_sampled"], stats
    alone = ppo_update(policy, optimizer, batch, cfg, generator)
    assert "approx_kl_mirrored" not in alone and "approx_kl_sampled" not in alone


def test_a_stage_may_turn_mirroring_off(tmp_path: Path) -> None:
    """``stages[i].ppo.mirror`` in place of the job's: a fine-tune stage without mirror images."""
    job = Job.model_validate(
        {
            "name": "stand-then-fine-tune",
            "ppo": {"mirror": True},
            "workers": {"num_workers": 0},
            "stages": [
                {"scene": "stand-2d", "env_steps": 1000},
                {"scene": "stand-2d", "env_steps": 1000, "ppo": {"mirror": False}},
            ],
        }
    )
    trainer = Trainer(job, tmp_path, tensorboard=False)
    assert trainer.mirrors[0] is not None and trainer.mirrors[1] is None
