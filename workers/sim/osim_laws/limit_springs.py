"""OpenSim's joint-limit springs on MuJoCo: each kept dof with a body-file ``limit`` held by
OpenSim's ``CoordinateLimitForce`` law (the scene's ``joint_limits: opensim``) instead of
MuJoCo's joint-limit constraint.

The law: past the upper limit ``qu`` a stiffness rising smoothly from 0 to ``K`` (N m/rad)
over ``transition`` (rad; Simbody's quintic step ``10x^3 - 15x^4 + 6x^5``) gives a torque
``-K(q) (q - qu)``, the same mirrored below the lower limit, and a damping torque
``-c (K(q) / K) qdot`` (``c`` in N m s/rad) that grows with it. The spring is soft where it
starts: gait2d's knee 4.6 degrees past its 10-degree limit is held with about 40 N m, where
MuJoCo's constraint (time constant 0.02 s) pushes hundreds.
"""

from __future__ import annotations

import mujoco
import numpy as np
from gaitforge.workers.bodies.schema import JointLimit


def step_up(x: float) -> float:
    """Simbody's smooth step: 0 for x <= 0, 1 for x >= 1, ``10x^3 - 15x^4 + 6x^5`` between."""
    x = min(max(x, 0.0), 1.0)
    return x**3 * (10.0 + x * (6.0 * x - 15.0))


def limit_torque(q: float, qdot: float, limit: JointLimit) -> float:
    """The limit spring's generalized force (N m, or N for a slide) at angle ``q`` (rad) and
    speed ``qdot`` (rad/s); 0 within the limit's range. Scalar arithmetic: it runs for each
    dof at every MuJoCo step."""
    lower, upper = limit.range
    if lower <= q <= upper:
        return 0.0
    stiffness = limit.stiffness
    if q > upper:
        k = stiffness * step_up((q - upper) / limit.transition)
        return -k * (q - upper) - limit.damping * k / stiffness * qdot
    k = stiffness * step_up((lower - q) / limit.transition)
    return k * (lower - q) - limit.damping * k / stiffness * qdot


class LimitSprings:
    """The limit springs of a compiled model's dofs, added to a generalized force vector."""

    def __init__(self, model: mujoco.MjModel, limits: dict[str, JointLimit]) -> None:
        joints = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in limits]
        self._each = list(
            zip(
                model.jnt_qposadr[joints].tolist(),
                model.jnt_dofadr[joints].tolist(),
                limits.values(),
                strict=True,
            )
        )

    def add(self, model: mujoco.MjModel, data: mujoco.MjData, qfrc: np.ndarray) -> None:
        """Add the springs' torques at the present state to ``qfrc`` ([nv])."""
        qpos, qvel = data.qpos, data.qvel
        for qadr, vadr, limit in self._each:
            q = qpos[qadr]
            if limit.range[0] <= q <= limit.range[1]:
                continue
            qfrc[vadr] += limit_torque(q, qvel[vadr], limit)
