"""Named reward terms. Each is computed per control step; the env sums them with the scene's
weights and reports every term, weighted, in ``info["reward_terms"]``.

| term           | per step                                         | unit    |
|----------------|--------------------------------------------------|---------|
| forward        | pelvis forward displacement                      | m       |
| target_speed   | -(forward speed - target)^2                      | (m/s)^2 |
| overspeed      | -max(0, forward speed - target)^2                | (m/s)^2 |
| effort         | -mean(activation^2)                              | 1       |
| smoothness     | -mean((excitation - previous)^2)                 | 1       |
| upright        | pelvis up axis . world up (1 upright)            | 1       |
| alive          | 1 while not terminated                           | 1       |
| reach          | -|dof angle - target|                            | rad     |

A scene whose task imitates a motion (``task.imitate``) also has the tracking terms
``imitate_pose``, ``imitate_joint_speed``, ``imitate_feet``, ``imitate_pelvis_height``,
``imitate_pelvis_pitch`` and ``imitate_pelvis_speed`` (``IMITATION_TERMS``; see
``workers.imitation``), weighted by ``task.imitate.weights``. :func:`term_names` gives a
task's terms; other scenes report exactly ``TERMS``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from gaitforge.workers.scenes.imitate import IMITATION_TERMS
from gaitforge.workers.scenes.spec import RewardWeights, Task
from gaitforge.workers.sim.base import SimState

TERMS: tuple[str, ...] = tuple(RewardWeights.model_fields)
"""The terms of every scene."""
ALL_TERMS: tuple[str, ...] = TERMS + IMITATION_TERMS
"""Every term any scene may report (for schemas)."""


def term_names(task: Task) -> tuple[str, ...]:
    """The reward terms ``task`` reports, in order: ``TERMS``, then with ``task.imitate``
    the ``IMITATION_TERMS``."""
    return ALL_TERMS if task.imitate is not None else TERMS


@dataclass(frozen=True)
class StepContext:
    """What a reward term may look at besides the new state."""

    previous: SimState
    excitation: np.ndarray
    previous_excitation: np.ndarray
    dt: float
    forward_axis: int
    up_axis: int
    target_speed: float | None
    reach_index: int | None
    reach_target: float


def reward_terms(state: SimState, ctx: StepContext) -> dict[str, float]:
    """Unweighted terms for one control step (see the module table)."""
    forward = float(state.pelvis_pos[ctx.forward_axis] - ctx.previous.pelvis_pos[ctx.forward_axis])
    speed = forward / ctx.dt
    target = ctx.target_speed
    reach = 0.0
    if ctx.reach_index is not None:
        reach = -abs(float(state.dof_pos[ctx.reach_index]) - ctx.reach_target)
    return {
        "forward": forward,
        "target_speed": 0.0 if target is None else -((speed - target) ** 2),
        "overspeed": 0.0 if target is None else -(max(0.0, speed - target) ** 2),
        "effort": -float(np.mean(state.activations**2)) if state.activations.size else 0.0,
        "smoothness": -float(np.mean((ctx.excitation - ctx.previous_excitation) ** 2)),
        "upright": float(state.pelvis_up[ctx.up_axis]),
        "alive": 1.0,
        "reach": reach,
    }


def weighted(terms: dict[str, float], weights: RewardWeights) -> dict[str, float]:
    return {name: getattr(weights, name) * value for name, value in terms.items()}
