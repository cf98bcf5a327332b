"""Policy blending: alpha 0 is pi_old, alpha 1 is pi_new; widening keeps the actions; a
blended policy survives a checkpoint round trip; the trainer's transitions run for real."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch
from gaitforge.learner.checkpoint import latest_checkpoint, load_policy, save_checkpoint
from gaitforge.learner.job import Job
from gaitforge.learner.policy import BlendedPolicy, GaussianPolicy, build_policy, widen_inputs
from gaitforge.learner.trainer import Trainer


def _trained_like(policy: GaussianPolicy, seed: int) -> GaussianPolicy:
    """Non-trivial weights and normaliser statistics."""
    torch.manual_seed(seed)
    with torch.no_grad():
        for p in policy.parameters():
            p.add_(torch.randn_like(p) * 0.3)
    policy.norm.update(torch.randn(128, policy.obs_dim) * 2 + 0.5)
    return policy


def _blend(
    obs_dim_old: int = 6, obs_dim_new: int = 6
) -> tuple[BlendedPolicy, GaussianPolicy, GaussianPolicy]:
    old = _trained_like(GaussianPolicy(obs_dim_old, 4, (16,)), 1)
    new = _trained_like(GaussianPolicy(obs_dim_new, 4, (32, 32)), 2)
    blended = BlendedPolicy(old.describe(), new.describe(), list(range(obs_dim_old)))
    blended.old.load_state_dict(old.state_dict())
    blended.new.load_state_dict(new.state_dict())
    return blended, old, new


@pytest.mark.parametrize("alpha", [0.0, 1.0])
def test_alpha_zero_is_pi_old_and_one_is_pi_new(alpha: float) -> None:
    blended, old, new = _blend(obs_dim_old=5, obs_dim_new=6)
    blended.set_alpha(alpha)
    obs = torch.randn(32, 6)
    reference = old.distribution(obs[:, :5]) if alpha == 0 else new.distribution(obs)
    got = blended.distribution(obs)
    torch.testing.assert_close(got.mean, reference.mean)
    torch.testing.assert_close(got.stddev, reference.stddev)
    action = torch.rand(32, 4)
    logp, _, _ = blended.evaluate(obs, action)
    torch.testing.assert_close(logp, reference.log_prob(action).sum(-1))


def test_halfway_the_mean_is_the_average_and_only_pi_new_learns() -> None:
    blended, old, new = _blend()
    blended.set_alpha(0.5)
    obs = torch.randn(16, 6)
    expected = 0.5 * (old.distribution(obs).mean + new.distribution(obs).mean)
    torch.testing.assert_close(blended.distribution(obs).mean, expected)
    blended.distribution(obs).mean.sum().backward()
    assert all(p.grad is None for p in blended.old.parameters())
    assert all(p.grad is not None for p in blended.new.actor.parameters())
    assert {id(p) for p in blended.trainable_parameters()} == {
        id(p) for p in blended.new.parameters()
    }


def test_widened_inputs_keep_the_actions() -> None:
    policy = _trained_like(GaussianPolicy(3, 2, (8,)), 3)
    wider = widen_inputs(policy, ["a", "b", "c"], ["a", "x", "b", "c", "y"])
    obs = torch.randn(10, 5)
    torch.testing.assert_close(
        wider.distribution(obs).mean, policy.distribution(obs[:, [0, 2, 3]]).mean
    )
    torch.testing.assert_close(wider.value(obs), policy.value(obs[:, [0, 2, 3]]))
    with pytest.raises(ValueError, match="observation lost"):
        widen_inputs(policy, ["a", "b", "c"], ["a", "b"])


def test_a_blended_checkpoint_round_trips_with_its_structure(tmp_path: Path) -> None:
    blended, _, _ = _blend()
    blended.set_alpha(0.3)
    path = save_checkpoint(tmp_path, 7, blended.state_dict(), {"network": blended.describe()})
    loaded, _ = load_policy(path)
    assert isinstance(loaded, BlendedPolicy) and float(loaded.alpha) == pytest.approx(0.3)
    obs = torch.randn(8, 6)
    torch.testing.assert_close(loaded.mean_action(obs), blended.mean_action(obs))
    assert isinstance(build_policy(blended.describe()), BlendedPolicy)


def _two_stage_job(transition: str) -> Job:
    return Job.model_validate(
        {
            "name": f"elbow-{transition}",
            "workers": {"num_workers": 0, "envs_per_worker": 4, "fragment_length": 32},
            "ppo": {"batch_env_steps": 256, "minibatch_size": 128, "epochs": 2},
            "network": {"hidden": [16]},
            "stages": [
                {"scene": "elbow-reach", "env_steps": 256},
                {
                    "scene": "elbow-reach",
                    "env_steps": 1024,
                    "transition": transition,
                    "network": {"hidden": [32, 32]},
                    "blend": {
                        "ramp_env_steps": 512,
                        "critic_warmup_env_steps": 128,
                        "fit_epochs": 3,
                    },
                },
            ],
        }
    )


def test_a_blend_builds_the_new_network(tmp_path: Path) -> None:
    transition = "blend"
    trainer = Trainer(_two_stage_job(transition), tmp_path, tensorboard=False)
    history = trainer.run()
    assert trainer.done and history[0]["stage"] == 0
    stage1 = [h for h in history if h["stage"] == 1]
    assert stage1[-1]["stage_env_steps"] >= 1024
    alphas = [h["alpha"] for h in stage1 if h["alpha"] is not None]
    assert alphas == sorted(alphas) and 0 < alphas[0] < 1, "alpha ramps up from 0"
    # the run ends on pi_new alone, saved with its lineage
    policy, meta = load_policy(latest_checkpoint(tmp_path / "checkpoints"))
    assert isinstance(policy, GaussianPolicy) and policy.hidden == (32, 32)
    assert [entry.transition for entry in meta.lineage] == ["initial", transition]
    assert meta.stage.index == 1
