"""Fitting a new network to an old one's rollouts: the critic to the GAE returns (the warm
start of blending and distillation) and, for behavioural cloning, the actor's mean action to
the old policy's."""

from __future__ import annotations

import torch
from gaitforge.learner.policy import GaussianPolicy


def fit_student(
    student: GaussianPolicy,
    obs: torch.Tensor,
    returns: torch.Tensor,
    teacher_mean: torch.Tensor | None,
    epochs: int = 50,
    minibatch: int = 256,
    lr: float = 1e-3,
    seed: int = 0,
) -> dict[str, float]:
    """Regress ``student``'s value on ``returns`` [N] and, if given, its mean action on
    ``teacher_mean`` [N, act_dim] (squared error on excitations), from ``obs`` [N, obs_dim].

    Returns the last epoch's mean losses (``value_mse``, and ``action_mse`` when cloning).
    """
    generator = torch.Generator().manual_seed(seed)
    params = list(student.critic.parameters())
    if teacher_mean is not None:
        params += list(student.actor.parameters())
    optimizer = torch.optim.Adam(params, lr=lr)
    obs, returns = obs.float(), returns.float()
    losses: dict[str, float] = {}
    for _ in range(epochs):
        sums = {"value_mse": 0.0, "action_mse": 0.0}
        order = torch.randperm(len(obs), generator=generator)
        chunks = order.split(minibatch)
        for idx in chunks:
            value_loss = (student.value(obs[idx]) - returns[idx]).pow(2).mean()
            loss = value_loss
            sums["value_mse"] += value_loss.item() / len(chunks)
            if teacher_mean is not None:
                mean = torch.sigmoid(student.mean_logits(obs[idx]))
                action_loss = (mean - teacher_mean[idx]).pow(2).mean()
                loss = loss + action_loss
                sums["action_mse"] += action_loss.item() / len(chunks)
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
        losses = sums if teacher_mean is not None else {"value_mse": sums["value_mse"]}
    return losses
