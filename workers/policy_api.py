"""What a rollout worker needs of a policy, and a trivial one for benchmarks and tests.

``workers`` never imports ``learner``: the trainer hands the pool a zero-argument policy
constructor (picklable, e.g. a ``functools.partial`` of a module class) and the weights.
"""

from __future__ import annotations

from typing import Protocol

import torch
from torch import nn


class RolloutPolicy(Protocol):
    """A torch module that acts for a batch of envs (excitations in [0, 1])."""

    def act(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """obs [K, obs_dim] -> action [K, act_dim] (excitations; the env clips them to [0, 1]),
        log-probability [K] of that action, value [K]."""

    def value(self, obs: torch.Tensor) -> torch.Tensor:
        """obs [K, obs_dim] -> value [K] (to bootstrap truncated episodes)."""

    def load_state_dict(self, state: dict, strict: bool = True) -> object: ...


class UniformExcitationPolicy(nn.Module):
    """Independent uniform excitations around a learnable-looking ``centre`` (weights exist so
    that weight broadcasting is exercised); log-probability and value are 0.

    It costs almost nothing, so a pool running it measures the simulators and the plumbing.
    """

    def __init__(self, act_dim: int, spread: float = 0.5) -> None:
        super().__init__()
        self.centre = nn.Parameter(torch.full((act_dim,), 0.5))
        self.spread = spread

    def act(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        k = obs.shape[0]
        noise = (torch.rand(k, self.centre.numel()) * 2.0 - 1.0) * self.spread
        action = (self.centre + noise).clamp(0.0, 1.0)
        zeros = torch.zeros(k)
        return action, zeros, zeros

    def value(self, obs: torch.Tensor) -> torch.Tensor:
        return torch.zeros(obs.shape[0])
