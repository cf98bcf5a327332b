"""The running observation normaliser merges batches exactly and travels in state_dict."""

from __future__ import annotations

import torch
from gaitforge.learner.normalizer import RunningNorm
from gaitforge.learner.policy import GaussianPolicy


def test_merged_batches_equal_the_statistics_of_all_of_them() -> None:
    torch.manual_seed(0)
    data = torch.randn(1000, 4) * torch.tensor([1.0, 10.0, 0.1, 3.0]) + 5.0
    norm = RunningNorm(4, eps=0.0)
    for chunk in data.split([100, 250, 650]):
        norm.update(chunk)
    torch.testing.assert_close(norm.mean, data.double().mean(0))
    torch.testing.assert_close(norm.var, data.double().var(0, unbiased=False))
    z = norm(data)
    torch.testing.assert_close(z.mean(0), torch.zeros(4), atol=1e-5, rtol=0)
    assert z.abs().max() <= norm.clip


def test_statistics_travel_with_the_weights() -> None:
    a, b = GaussianPolicy(3, 2), GaussianPolicy(3, 2)
    a.norm.update(torch.randn(50, 3) + 7.0)
    b.load_state_dict(a.state_dict())
    torch.testing.assert_close(b.norm.mean, a.norm.mean)
    obs = torch.randn(4, 3)
    torch.testing.assert_close(b.value(obs), a.value(obs))
