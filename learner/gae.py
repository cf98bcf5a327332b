"""Generalised advantage estimation over rollout fragments ``[T, K]``.

Time-outs are not failures: where an episode was *truncated* the return is bootstrapped
with the value of its final observation (``bootstrap_value``, computed by the rollout
worker before the reset); where it *terminated* (a fall, or a simulator failure) the
future is worth nothing. At the end of a fragment the return is bootstrapped with
``last_value``.
"""

from __future__ import annotations

import numpy as np


def compute_gae(
    reward: np.ndarray,
    value: np.ndarray,
    terminated: np.ndarray,
    truncated: np.ndarray,
    bootstrap_value: np.ndarray,
    last_value: np.ndarray,
    gamma: float = 0.99,
    lam: float = 0.95,
) -> tuple[np.ndarray, np.ndarray]:
    """Advantages and value targets (returns), both ``[T, K]`` float32.

    Args:
        reward, value: ``[T, K]``: reward of step t and V(s_t).
        terminated, truncated: ``[T, K]`` bool: the episode ended after step t.
        bootstrap_value: ``[T, K]``: V(final observation) where ``truncated`` (else ignored).
        last_value: ``[K]``: V(s_T), the observation after the fragment's last step.
        gamma: discount per step; lam: GAE lambda.
    """
    t_len = reward.shape[0]
    advantages = np.zeros_like(reward, dtype=np.float64)
    next_value = last_value.astype(np.float64)
    next_advantage = np.zeros_like(next_value)
    for t in reversed(range(t_len)):
        ended = terminated[t] | truncated[t]
        # value of what follows step t: 0 after a termination, V(final obs) after a
        # truncation, V(s_{t+1}) otherwise
        following = np.where(
            terminated[t], 0.0, np.where(truncated[t], bootstrap_value[t], next_value)
        )
        delta = reward[t] + gamma * following - value[t]
        # the advantage recursion never crosses an episode boundary
        advantages[t] = delta + gamma * lam * np.where(ended, 0.0, next_advantage)
        next_value, next_advantage = value[t].astype(np.float64), advantages[t]
    returns = advantages + value
    return advantages.astype(np.float32), returns.astype(np.float32)
