"""Fitting a network by regression: the critic to the GAE returns (the warm start of blending
and distillation) and, for behavioural cloning, the actor's mean action to target actions
(an old policy's, or recorded excitations: ``learner.clone_excitations``)."""

from __future__ import annotations

import torch
from gaitforge.learner.policy import GaussianPolicy


def fit_student(
    student: GaussianPolicy,
    obs: torch.Tensor,
    returns: torch.Tensor | None,
    teacher_mean: torch.Tensor | None,
    epochs: int = 50,
    minibatch: int = 256,
    lr: float = 1e-3,
    seed: int = 0,
) -> dict[str, float]:
    """Regress ``student``'s value on ``returns`` [N] and/or its mean action on
    ``teacher_mean`` [N, act_dim] (squared error on excitations in [0, 1]), from ``obs``
    [N, obs_dim] (the normaliser is used as it is, not updated). Only the networks that have
    a target are changed (critic, actor).

    Returns the last epoch's mean losses (``value_mse`` when fitting the value,
    ``action_mse`` when cloning).
    """
    if returns is None and teacher_mean is None:
        raise ValueError("fit_student: nothing to fit (no returns, no target actions)")
    generator = torch.Generator().manual_seed(seed)
    params = [] if returns is None else list(student.critic.parameters())
    if teacher_mean is not None:
        params += list(student.actor.parameters())
        teacher_mean = teacher_mean.float()
    optimizer = torch.optim.Adam(params, lr=lr)
    obs = obs.float()
    returns = None if returns is None else returns.float()
    sums: dict[str, float] = {}
    for _ in range(epochs):
        sums = {}
        order = torch.randperm(len(obs), generator=generator)
        chunks = order.split(minibatch)
        for idx in chunks:
            loss = torch.zeros(())
            if returns is not None:
                value_loss = (student.value(obs[idx]) - returns[idx]).pow(2).mean()
                loss = loss + value_loss
                sums["value_mse"] = sums.get("value_mse", 0.0) + value_loss.item() / len(chunks)
            if teacher_mean is not None:
                mean = torch.sigmoid(student.mean_logits(obs[idx]))
                action_loss = (mean - teacher_mean[idx]).pow(2).mean()
                loss = loss + action_loss
                sums["action_mse"] = sums.get("action_mse", 0.0) + action_loss.item() / len(chunks)
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
    return sums
