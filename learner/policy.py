"""Policy networks. ``GaussianPolicy``: an actor-critic over excitations in [0, 1].

Implements ``workers.policy_api.RolloutPolicy``: ``act`` samples from a diagonal Gaussian
whose mean is squashed into [0, 1] by a sigmoid; the sample itself is returned (the env
clips it to [0, 1]), so that its log-probability is exact for the PPO ratio.
"""

from __future__ import annotations

import itertools

import torch
from torch import nn
from torch.distributions import Normal

from learner.normalizer import RunningNorm


def _mlp(sizes: list[int], out: int) -> nn.Sequential:
    layers: list[nn.Module] = []
    for a, b in itertools.pairwise(sizes):
        layers += [nn.Linear(a, b), nn.Tanh()]
    layers.append(nn.Linear(sizes[-1], out))
    return nn.Sequential(*layers)


class GaussianPolicy(nn.Module):
    """Actor and critic MLPs over a normalised observation.

    Args:
        obs_dim, act_dim: sizes of observation and action (muscles).
        hidden: hidden layer widths of both networks.
        init_std: initial standard deviation of the excitations.
    """

    def __init__(
        self, obs_dim: int, act_dim: int, hidden: tuple[int, ...] = (64, 64), init_std: float = 0.3
    ) -> None:
        super().__init__()
        self.norm = RunningNorm(obs_dim)
        self.actor = _mlp([obs_dim, *hidden], act_dim)
        self.critic = _mlp([obs_dim, *hidden], 1)
        self.log_std = nn.Parameter(
            torch.full((act_dim,), float(torch.log(torch.tensor(init_std))))
        )

    def distribution(self, obs: torch.Tensor) -> Normal:
        """obs [N, obs_dim] -> Normal over actions [N, act_dim] (mean in [0, 1])."""
        mean = torch.sigmoid(self.actor(self.norm(obs)))
        return Normal(mean, self.log_std.exp().expand_as(mean))

    def value(self, obs: torch.Tensor) -> torch.Tensor:
        """obs [N, obs_dim] -> V(s) [N]."""
        return self.critic(self.norm(obs)).squeeze(-1)

    def act(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """obs [K, obs_dim] -> sampled action [K, act_dim], its log-probability [K], V [K]."""
        dist = self.distribution(obs)
        action = dist.sample()
        return action, dist.log_prob(action).sum(-1), self.value(obs)

    def evaluate(
        self, obs: torch.Tensor, action: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Log-probability [N], entropy [N] and value [N] of ``action`` [N, act_dim]."""
        dist = self.distribution(obs)
        return dist.log_prob(action).sum(-1), dist.entropy().sum(-1), self.value(obs)
