"""The PPO update: clipped surrogate, value loss, entropy bonus, gradient clipping and an
early stop on KL; a batch is built from rollout fragments with :func:`batch_from_fragments`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from gaitforge.learner.gae import compute_gae
from gaitforge.learner.policy import GaussianPolicy


@dataclass(frozen=True)
class PPOConfig:
    """PPO hyper-parameters (CleanRL's names and defaults where they exist)."""

    gamma: float = 0.99
    """discount per control step"""
    lam: float = 0.95
    """GAE lambda"""
    clip: float = 0.2
    """surrogate clipping range"""
    value_coef: float = 0.5
    """weight of the value loss"""
    entropy_coef: float = 0.0
    """weight of the entropy bonus"""
    lr: float = 3e-4
    """Adam learning rate"""
    epochs: int = 5
    """passes over each batch"""
    minibatches: int = 4
    """minibatches per pass"""
    max_grad_norm: float = 0.5
    """gradient clipping (L2 norm), of the actor's and the critic's parameters apart"""
    target_kl: float | None = 0.03
    """stop the epochs early once the approximate KL exceeds this"""


FROM_ENV = ("obs", "action", "logp", "value", "reward", "bootstrap_value", "last_value")
"""Fragment arrays checked before any arithmetic, so a NaN is named where it entered."""


def batch_from_fragments(fragments: list[dict], cfg: PPOConfig) -> dict[str, torch.Tensor]:
    """Flatten fragments ``[T, K, ...]`` into one batch ``[N, ...]`` with advantages and
    returns (GAE per fragment, bootstrapped on truncation and at the fragment end)."""
    parts: dict[str, list[np.ndarray]] = {k: [] for k in ("obs", "action", "logp", "value")}
    advantages, returns = [], []
    for f in fragments:
        check_finite({k: torch.from_numpy(np.asarray(f[k], dtype=np.float64)) for k in FROM_ENV})
        adv, ret = compute_gae(
            f["reward"], f["value"], f["terminated"], f["truncated"],
            f["bootstrap_value"], f["last_value"], cfg.gamma, cfg.lam,
        )  # fmt: skip
        advantages.append(adv.reshape(-1))
        returns.append(ret.reshape(-1))
        for key in parts:
            parts[key].append(f[key].reshape(-1, *f[key].shape[2:]))
    batch = {key: torch.from_numpy(np.concatenate(v)) for key, v in parts.items()}
    batch["advantage"] = torch.from_numpy(np.concatenate(advantages))
    batch["return"] = torch.from_numpy(np.concatenate(returns))
    check_finite(batch)
    return batch


def check_finite(tensors: dict[str, torch.Tensor]) -> None:
    """Raise ``FloatingPointError`` naming the first tensor with a NaN or Inf."""
    for name, tensor in tensors.items():
        if not torch.isfinite(tensor).all():
            raise FloatingPointError(
                f"{name}: contains NaN or Inf; likely cause: a simulator failure reached the "
                "batch (check the env's health flags) or a diverging value function"
            )


def clipped_surrogate_loss(ratio: torch.Tensor, adv: torch.Tensor, clip: float) -> torch.Tensor:
    """PPO's policy loss: ``-mean(min(r A, clip(r, 1 - eps, 1 + eps) A))`` over ratios
    ``ratio`` [N] and advantages ``adv`` [N]."""
    return -torch.min(ratio * adv, ratio.clamp(1 - clip, 1 + clip) * adv).mean()


def _clip_groups(policy: GaussianPolicy) -> list[list[torch.nn.Parameter]]:
    """Actor and critic parameters, clipped apart: the value loss (returns of order 100)
    would otherwise own the joint gradient norm and clipping would starve the actor."""
    named = [(n, p) for n, p in policy.named_parameters() if p.requires_grad]
    critic = [p for n, p in named if "critic" in n]
    actor = [p for n, p in named if "critic" not in n]
    return [group for group in (actor, critic) if group]


def ppo_update(
    policy: GaussianPolicy,
    optimizer: torch.optim.Optimizer,
    batch: dict[str, torch.Tensor],
    cfg: PPOConfig,
    generator: torch.Generator | None = None,
) -> dict[str, float]:
    """Several epochs of minibatch PPO on ``batch``; returns the last losses and KL."""
    n = batch["obs"].shape[0]
    adv = batch["advantage"]
    adv = (adv - adv.mean()) / (adv.std() + 1e-8)
    stats: dict[str, float] = {}
    for epoch in range(cfg.epochs):
        order = torch.randperm(n, generator=generator)
        kls = []
        for idx in order.chunk(cfg.minibatches):
            logp, entropy, value = policy.evaluate(batch["obs"][idx], batch["action"][idx])
            log_ratio = logp - batch["logp"][idx]
            ratio = log_ratio.exp()
            policy_loss = clipped_surrogate_loss(ratio, adv[idx], cfg.clip)
            value_loss = 0.5 * (value - batch["return"][idx]).pow(2).mean()
            loss = policy_loss + cfg.value_coef * value_loss - cfg.entropy_coef * entropy.mean()
            check_finite({"policy_loss": policy_loss, "value_loss": value_loss})
            optimizer.zero_grad()
            loss.backward()
            for group in _clip_groups(policy):
                torch.nn.utils.clip_grad_norm_(group, cfg.max_grad_norm)
            optimizer.step()
            with torch.no_grad():
                kls.append(((ratio - 1) - log_ratio).mean().item())
        stats = {
            "policy_loss": policy_loss.item(),
            "value_loss": value_loss.item(),
            "entropy": entropy.mean().item(),
            "approx_kl": float(np.mean(kls)),
            "epochs": epoch + 1,
        }
        if cfg.target_kl is not None and stats["approx_kl"] > cfg.target_kl:
            break
    return stats
