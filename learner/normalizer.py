"""Running observation normaliser, part of the policy module so that it travels with the
weights to every rollout actor (and into checkpoints)."""

from __future__ import annotations

import torch
from torch import nn


class RunningNorm(nn.Module):
    """Normalises ``[..., dim]`` inputs by a running mean and variance, clipped to +-``clip``.

    The statistics are buffers: they are saved and broadcast with the weights, and changed
    only by :meth:`update` (the learner, from the observations in its batches).
    """

    def __init__(self, dim: int, clip: float = 10.0, eps: float = 1e-4) -> None:
        super().__init__()
        self.clip = clip
        self.register_buffer("mean", torch.zeros(dim, dtype=torch.float64))
        self.register_buffer("var", torch.ones(dim, dtype=torch.float64))
        self.register_buffer("count", torch.tensor(eps, dtype=torch.float64))

    @torch.no_grad()
    def update(self, x: torch.Tensor) -> None:
        """Merge the statistics of ``x`` ``[N, dim]`` (Chan et al.'s parallel algorithm)."""
        x = x.reshape(-1, self.mean.numel()).to(torch.float64)
        n = x.shape[0]
        if n == 0:
            return
        batch_mean, batch_var = x.mean(0), x.var(0, unbiased=False)
        total = self.count + n
        delta = batch_mean - self.mean
        self.mean += delta * n / total
        self.var = (
            self.var * self.count + batch_var * n + delta**2 * self.count * n / total
        ) / total
        self.count = total

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        z = (x - self.mean.to(x.dtype)) / torch.sqrt(self.var.to(x.dtype) + 1e-8)
        return z.clamp(-self.clip, self.clip)
