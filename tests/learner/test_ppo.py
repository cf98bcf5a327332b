"""PPO: the update is sound, refuses NaN, and learns elbow-reach in-process in seconds."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest
import torch
from gaitforge.learner.job import Job
from gaitforge.learner.policy import GaussianPolicy
from gaitforge.learner.ppo import (
    MAX_BEHAVIOUR_WEIGHT,
    PPOSettings,
    batch_from_fragments,
    clipped_surrogate_loss,
    optimizer_groups,
    ppo_update,
    set_learning_rates,
)
from gaitforge.learner.trainer import Trainer
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.rollout import RolloutWorker
from gaitforge.workers.scenes import load_scene

from tests.learner.test_trainer import elbow_job


def _elbow_factory() -> functools.partial:
    env = MuscleEnv("elbow-reach")
    return functools.partial(
        GaussianPolicy, env.observation_space.shape[0], env.action_space.shape[0]
    )


def test_policy_acts_in_batches_and_evaluates_its_own_samples() -> None:
    torch.manual_seed(0)
    policy = GaussianPolicy(obs_dim=5, act_dim=3)
    obs = torch.randn(7, 5)
    action, logp, value = policy.act(obs)
    assert action.shape == (7, 3) and logp.shape == (7,) and value.shape == (7,)
    again, entropy, _ = policy.evaluate(obs, action)
    torch.testing.assert_close(again, logp)
    assert (entropy > -10).all()
    mean = policy.distribution(obs).mean
    assert ((mean >= 0) & (mean <= 1)).all()


def test_a_nan_in_the_batch_is_refused_naming_the_tensor() -> None:
    worker = RolloutWorker(
        load_scene("elbow-reach").resolved(), _elbow_factory(), num_envs=2, fragment_length=10
    )
    fragment = worker.sample()
    fragment.reward[3, 1] = np.nan
    with pytest.raises(FloatingPointError, match=r"^reward: contains NaN"):
        batch_from_fragments([fragment], PPOSettings())


def test_elbow_reach_learns_in_process() -> None:
    """25 iterations of 800 steps (about 8 s here) at a learning rate of 6e-4: the mean
    episode return rises by more than half of the way from a random policy (about -70)
    towards 0 (to -18 here; with seeds 1 and 2 for torch and the envs in place of 0, to -25
    and -22: the bound is -35)."""
    torch.manual_seed(0)
    factory = _elbow_factory()
    worker = RolloutWorker(
        load_scene("elbow-reach").resolved(), factory, num_envs=8, fragment_length=100
    )
    policy = factory()
    optimizer = torch.optim.Adam(policy.parameters(), lr=6e-4)
    cfg = PPOSettings(epochs=10, gamma=0.95, minibatch_size=200)
    returns = []
    for version in range(25):
        fragment = worker.sample(policy.state_dict(), version)
        returns.append(float(fragment.episode_return.mean()))
        policy.norm.update(torch.from_numpy(fragment.flat_obs()))
        ppo_update(policy, optimizer, batch_from_fragments([fragment], cfg), cfg)
    start, end = np.mean(returns[:3]), np.mean(returns[-3:])
    assert start < -50, f"a random policy should do badly: {start:.1f}"
    assert end > start / 2, f"no learning: {start:.1f} -> {end:.1f}"


def test_clipped_surrogate_against_hand_worked_numbers() -> None:
    # r = 1.5, A = +2: min(3.0, 1.2 * 2) = 2.4;   r = 0.5, A = +1: min(0.5, 0.8) = 0.5;
    # r = 0.5, A = -1: min(-0.5, 0.8 * -1) = -0.8; r = 1.1, A = -3: inside the range, -3.3
    ratio = torch.tensor([1.5, 0.5, 0.5, 1.1])
    adv = torch.tensor([2.0, 1.0, -1.0, -3.0])
    expected = -(2.4 + 0.5 + (-0.8) + (-3.3)) / 4
    assert clipped_surrogate_loss(ratio, adv, 0.2).item() == pytest.approx(expected)


def _update_once(
    policy: GaussianPolicy, batch: dict[str, torch.Tensor], cfg: PPOSettings
) -> dict[str, float]:
    """One PPO update of ``policy`` on ``batch`` (Adam at ``cfg.lr``, a fixed minibatch
    order)."""
    optimizer = torch.optim.Adam(policy.parameters(), lr=cfg.lr)
    return ppo_update(policy, optimizer, batch, cfg, torch.Generator().manual_seed(0))


def test_the_decoupled_objective_clips_around_the_policy_at_the_updates_start() -> None:
    """A batch sampled by older weights (as a Ray actor's queued request is): plain PPO's
    ratios start away from 1 (the KL to the sampling policy), the decoupled objective's at 1,
    its samples weighted by pi_proximal / pi_behaviour. On a batch the current weights
    sampled, the two are the same update."""
    torch.manual_seed(0)
    factory = _elbow_factory()
    worker = RolloutWorker(
        load_scene("elbow-reach").resolved(), factory, num_envs=4, fragment_length=50
    )
    policy, stale = factory(), factory()
    stale.load_state_dict(policy.state_dict())
    with torch.no_grad():
        for parameter in stale.actor.parameters():
            parameter.add_(0.1 * torch.randn_like(parameter))
    still = PPOSettings(lr=1e-12, epochs=1, minibatch_size=200, target_kl=None)
    batch = batch_from_fragments([worker.sample(stale.state_dict(), 0)], still)
    plain = _update_once(policy, batch, still)
    decoupled = _update_once(policy, batch, still.model_copy(update={"decoupled": True}))
    assert plain["approx_kl"] > 1e-3, plain
    assert decoupled["approx_kl"] < 1e-6, decoupled
    assert plain["behaviour_weight"] == 1.0
    assert 0.5 < decoupled["behaviour_weight"] <= MAX_BEHAVIOUR_WEIGHT

    fresh = batch_from_fragments([worker.sample(policy.state_dict(), 1)], still)
    cfg = PPOSettings(lr=1e-3, epochs=3, minibatch_size=50, target_kl=None)
    one, two = factory(), factory()
    one.load_state_dict(policy.state_dict())
    two.load_state_dict(policy.state_dict())
    _update_once(one, fresh, cfg)
    _update_once(two, fresh, cfg.model_copy(update={"decoupled": True}))
    for (name, a), b in zip(one.state_dict().items(), two.state_dict().values(), strict=True):
        torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-5, msg=name)
    assert any(
        not torch.equal(a, b)
        for a, b in zip(one.state_dict().values(), policy.state_dict().values(), strict=True)
    ), "the update moved the weights"


def test_schedules_are_applied_by_the_settings() -> None:
    ppo = PPOSettings(lr=1e-3, lr_end=2e-4, entropy_coef=0.01, entropy_coef_end=0.0)
    half = ppo.at(0.5)
    assert half.lr == pytest.approx(6e-4) and half.entropy_coef == pytest.approx(0.005)
    assert half.lr_end is None and half.at(1.0) == half, "a point of a schedule is constant"
    assert ppo.at(2.0).lr == pytest.approx(2e-4) and ppo.at(0.0).lr == pytest.approx(1e-3)
    assert PPOSettings(lr=1e-3).at(0.7).lr == pytest.approx(1e-3), "no lr_end: constant"
    assert (ppo.minibatches(8192), ppo.minibatches(100), ppo.minibatches(5000)) == (4, 1, 2)
    with pytest.raises(ValueError, match="lr"):
        PPOSettings(lr=-1.0)


def test_the_critic_may_learn_at_a_rate_of_its_own() -> None:
    """With ``critic_lr`` the critic has its own Adam group: at an actor rate of 1e-7 and a
    critic rate of 1e-2, one update moves the critic's weights and barely the actor's."""
    torch.manual_seed(0)
    factory = _elbow_factory()
    worker = RolloutWorker(
        load_scene("elbow-reach").resolved(), factory, num_envs=4, fragment_length=50
    )
    policy = factory()
    cfg = PPOSettings(lr=1e-7, critic_lr=1e-2, epochs=2, minibatch_size=100, target_kl=None)
    single = torch.optim.Adam(optimizer_groups(policy, critic_apart=False))
    set_learning_rates(single, cfg)
    assert [g["lr"] for g in single.param_groups] == [1e-7], "no group of its own: lr"
    optimizer = torch.optim.Adam(optimizer_groups(policy, critic_apart=True))
    set_learning_rates(optimizer, cfg)
    assert [(g["name"], g["lr"]) for g in optimizer.param_groups] == [
        ("actor", 1e-7),
        ("critic", 1e-2),
    ]
    before = {n: p.detach().clone() for n, p in policy.named_parameters()}
    batch = batch_from_fragments([worker.sample(policy.state_dict(), 0)], cfg)
    ppo_update(policy, optimizer, batch, cfg)
    moved = {n: (p - before[n]).abs().max().item() for n, p in policy.named_parameters()}
    assert min(v for n, v in moved.items() if "critic" in n) > 1e-3, moved
    assert max(v for n, v in moved.items() if "critic" not in n) < 1e-5, moved


def test_a_run_resumes_when_a_critic_rate_is_added(tmp_path: Path) -> None:
    """A checkpoint's Adam state (one group) does not fit a job that now gives the critic
    its own rate (two groups): the run resumes with Adam afresh instead of failing."""
    raw = elbow_job().model_dump()
    Trainer(Job.model_validate(raw), tmp_path, tensorboard=False).run(max_iterations=2)
    raw["ppo"]["critic_lr"] = 1e-3
    resumed = Trainer(Job.model_validate(raw), tmp_path, tensorboard=False)
    assert resumed.iteration == 2
    assert [g["name"] for g in resumed.optimizer.param_groups] == ["actor", "critic"]
    resumed.run(max_iterations=1)
    assert resumed.iteration == 3
