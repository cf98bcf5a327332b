"""``release_constant_inputs``: an input that was constant through a stage (a target speed)
changes value at the next stage without changing the policy's actions or values."""

from __future__ import annotations

import torch
from gaitforge.learner.policy import GaussianPolicy, release_constant_inputs


def test_a_constant_input_taking_a_new_value_changes_nothing() -> None:
    torch.manual_seed(0)
    policy = GaussianPolicy(4, 3, (16, 16))
    obs = torch.randn(512, 4)
    obs[:, 2] = 1.014  # a target speed, constant through the stage
    policy.norm.update(obs)
    before_actions = policy.mean_action(obs)
    shifted = obs.clone()
    shifted[:, 2] = 1.25
    # unreleased, the new value is 0.236 / sqrt(var ~ 0): clipped to 10 and it moves the actions
    assert (policy.mean_action(shifted) - before_actions).abs().max() > 1e-2
    assert release_constant_inputs(policy) == [2]
    for batch in (obs, shifted):
        assert torch.allclose(policy.mean_action(batch), before_actions, atol=1e-3)
        assert torch.allclose(policy.value(batch), policy.value(obs), atol=1e-3)
    assert release_constant_inputs(policy) == []  # its variance is 1 now
    assert policy.norm(shifted)[:, 2].abs().max() < 1.0
