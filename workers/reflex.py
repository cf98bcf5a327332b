"""The reflex layer of ``action.kind: joint_targets`` (see ``workers.scenes.action``).

A policy's action ``a`` [n_dofs] in [0, 1] sets target angles ``base + (2 a - 1) *
range_rad`` for the control period; ``reflex_hz`` times a second the layer reads the joint
angles ``q`` and speeds ``qd`` and excites each muscle in proportion to the torque it can
add toward the target:

    tau*  = kp (q* - q) + kd (qd* - qd)                      [n_dofs], excitation units
    e_i   = clip(sum_j R_ij / max_j |R_ij| * tau*_j, 0, 1)   [n_muscles]

``R`` [n_muscles, n_dofs] is the moment arm (joint torque per newton of tension, m), read
from the simulator once per control step; normalising each muscle's row by its largest
moment arm makes ``kp`` and ``kd`` excitation per rad and per rad/s whatever the muscle's
size. A muscle whose pull would move a joint away from its target gets nothing from it (the
clip), so agonists fire and antagonists relax; a biarticular muscle sums both joints.
"""

from __future__ import annotations

import numpy as np
from gaitforge.workers.scenes.action import ActionSpec
from gaitforge.workers.sim.base import Simulator


class ReflexLayer:
    """Joint targets -> excitations for one simulator.

    Args:
        spec: the scene's action spec (kind joint_targets).
        sim: the simulator it drives; its kept dofs are the targets' dofs.
    """

    def __init__(self, spec: ActionSpec, sim: Simulator) -> None:
        self.spec = spec
        self.sim = sim
        n_dofs = len(sim.dof_names)
        self._targets = np.zeros(n_dofs)
        self._target_speeds = np.zeros(n_dofs)
        self._gain = np.zeros((len(sim.muscle_names), n_dofs))

    def set_targets(self, action: np.ndarray, base: np.ndarray, base_speeds: np.ndarray) -> None:
        """Targets for the coming control period from ``action`` [n_dofs] in [0, 1], around
        ``base`` [n_dofs] (rad) with speed targets ``base_speeds`` [n_dofs] (rad/s); reads
        the moment arms once."""
        a = np.clip(np.nan_to_num(np.asarray(action, dtype=np.float64), nan=0.5), 0.0, 1.0)
        self._targets = base + (2.0 * a - 1.0) * self.spec.range_rad
        self._target_speeds = base_speeds
        arms = self.sim.moment_arms()
        scale = np.abs(arms).max(axis=1, keepdims=True)
        self._gain = np.divide(arms, scale, out=np.zeros_like(arms), where=scale > 0)

    def __call__(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Excitations [n_muscles] in [0, 1] for joint angles ``q`` and speeds ``qd``
        [n_dofs] (the simulator's kept dofs)."""
        torque = self.spec.kp * (self._targets - q) + self.spec.kd * (self._target_speeds - qd)
        excitation = self._gain @ torque
        return np.minimum(np.maximum(excitation, 0.0, out=excitation), 1.0, out=excitation)
