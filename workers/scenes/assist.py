"""A scene task's ``assist`` field: outside forces on the pelvis that a curriculum takes away
stage by stage (Yu, Turk and Liu 2018, "Learning symmetric and low-energy locomotion": a
virtual assistant that balances the body and pushes it forward, weakened as learning goes).

The hold is a spring and damper on the pelvis's tilt (``upright_kp``, ``upright_kd``: a torque
turning the pelvis's up axis back to the world's, its yaw left free); the push is a force along
the world's forward axis, ``propel_kv`` times how far the pelvis's forward speed falls short of
``task.target_speed`` (none when it is at or over it). Both act on MuJoCo scenes only
(``workers.sim.mujoco.upright``); an assisted scene trains, its unassisted twin is what a policy is
judged on.
"""

from __future__ import annotations

from gaitforge.workers.scenes.clock import NonNegative, StrictSpec
from pydantic import Field


class Assist(StrictSpec):
    """Gains of the pelvis's hold and push; all 0 is no assist."""

    upright_kp: NonNegative = Field(
        default=0.0, description="N m/rad: torque per rad the pelvis's up axis tilts"
    )
    upright_kd: NonNegative = Field(
        default=0.0, description="N m s/rad: torque per rad/s the pelvis tilts (yaw free)"
    )
    propel_kv: NonNegative = Field(
        default=0.0,
        description="N s/m: forward force per m/s the pelvis is slower than task.target_speed",
    )

    @property
    def active(self) -> bool:
        """Whether any gain is above 0."""
        return self.upright_kp > 0 or self.upright_kd > 0 or self.propel_kv > 0
