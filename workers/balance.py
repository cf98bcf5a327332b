"""The ankle postural reflex of ``action.balance`` (see ``workers.scenes.action``).

Once per control step, from the state the step starts in, it shifts the joint targets of
the balance's dofs (the ankles) by

    offset = -(lean_gain * lean + speed_gain * (v - v*))          rad

    lean   = (x_pelvis - x_feet) / (z_pelvis - z_feet)            rad (small angle)
    v - v* = forward pelvis speed minus the task's target speed   m/s

with ``x`` along the world's forward axis, ``z`` up and ``x_feet``, ``z_feet`` the midpoint
of the feet. A positive offset flexes the ankle (tips the shank forward over the foot), so a
body leaning or drifting backward is tipped forward and one ahead of its feet is pushed back,
the ankle strategy of human quiet standing. Its delay is one control period.
"""

from __future__ import annotations

import numpy as np
from gaitforge.workers.scenes.action import Balance
from gaitforge.workers.sim.base import SimState

MIN_HEIGHT_M = 0.3
"""The pelvis's height over the feet is read as at least this (m), so a body already down
does not divide the lean by almost nothing."""


class AnkleBalance:
    """Target offsets [n_dofs] of ``balance`` for a simulator's kept dofs ``dof_names``.

    Args:
        balance: the scene's ``action.balance``.
        dof_names: the simulator's kept dofs (the balance's dofs among them).
        forward_axis: index of the world's forward axis.
        up_axis: index of the world's up axis.
    """

    def __init__(
        self, balance: Balance, dof_names: list[str], forward_axis: int, up_axis: int
    ) -> None:
        self.balance = balance
        self._mask = np.array([name in balance.dofs for name in dof_names], dtype=np.float64)
        self._forward = forward_axis
        self._up = up_axis

    def lean(self, state: SimState, feet: list[np.ndarray]) -> float:
        """How far the pelvis stands ahead of the feet's midpoint, over its height above
        them (rad); ``feet`` are the feet's positions [3] in m."""
        middle = np.mean(feet, axis=0)
        ahead = state.pelvis_pos[self._forward] - middle[self._forward]
        height = max(state.pelvis_pos[self._up] - middle[self._up], MIN_HEIGHT_M)
        return float(ahead / height)

    def offsets(self, state: SimState, feet: list[np.ndarray], target_speed: float) -> np.ndarray:
        """Target offsets [n_dofs] (rad; 0 off the balance's dofs) for ``state``, the feet's
        positions ``feet`` [3] (m) and the task's target speed now (m/s)."""
        speed_error = state.pelvis_vel[self._forward] - target_speed
        shift = self.balance.lean_gain * self.lean(state, feet)
        shift += self.balance.speed_gain * speed_error
        return -shift * self._mask
