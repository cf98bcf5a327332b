"""The pelvis's assist on MuJoCo (``task.assist``, ``workers.scenes.assist``): a torque that
turns the pelvis upright and a force that pushes it toward the task's speed, written to
``data.xfrc_applied`` of the pelvis body before each physics step (at the reflex layer's rate
with joint-target actions)."""

from __future__ import annotations

import mujoco
import numpy as np
from gaitforge.workers.scenes.assist import Assist


class UprightHold:
    """The assist of one compiled scene.

    Args:
        assist: the gains.
        pelvis: the pelvis's body id.
        axes: the world's (up, forward) axis indices.
        pelvis_up_axis: the index of the pelvis frame's axis that points up when it stands.
        target_speed: m/s along the forward axis that the push aims at.
    """

    def __init__(
        self,
        assist: Assist,
        pelvis: int,
        axes: tuple[int, int],
        pelvis_up_axis: int,
        target_speed: float,
    ) -> None:
        self.assist = assist
        self._pelvis = pelvis
        self._world_up = np.eye(3)[axes[0]]
        self._forward = axes[1]
        self._pelvis_up_axis = pelvis_up_axis
        self._target_speed = target_speed
        self._velocity = np.zeros(6)

    def apply(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Set the pelvis's ``xfrc_applied`` [6] (force N, then torque N m, world frame) from
        the state in ``data`` (its positions and velocities as of the last step)."""
        gains = self.assist
        frame = data.xmat[self._pelvis].reshape(3, 3)
        pelvis_up = frame[:, self._pelvis_up_axis]
        mujoco.mj_objectVelocity(
            model, data, mujoco.mjtObj.mjOBJ_BODY, self._pelvis, self._velocity, 0
        )
        angular, linear = self._velocity[:3], self._velocity[3:]  # rotation first, here
        tilt_rate = angular - angular.dot(self._world_up) * self._world_up
        # |up x world_up| = sin(tilt), along the axis that turns up back to world_up
        torque = gains.upright_kp * np.cross(pelvis_up, self._world_up)
        torque -= gains.upright_kd * tilt_rate
        force = np.zeros(3)
        shortfall = self._target_speed - linear[self._forward]
        if gains.propel_kv and shortfall > 0:
            force[self._forward] = gains.propel_kv * shortfall
        data.xfrc_applied[self._pelvis] = np.concatenate([force, torque])
