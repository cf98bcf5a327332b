"""OpenSim's ground contact on MuJoCo: Simbody's ``HuntCrossleyForce`` law between each kept
contact sphere and the floor, applied to MuJoCo's bodies as forces every physics step.

The law (Simbody's ``HuntCrossleyForceImpl::calcForce``, both surfaces with the body's
``ContactMaterial``, as ``opensim.build`` gives them): a sphere of radius R (m) overlapping
the floor by a depth d (m) at a point moving with velocity v (m/s) feels

- a Hertz force ``fH = 4/3 k^1.5 sqrt(R) d^1.5`` (N), where ``k = stiffness^(2/3) / 2`` is the
  two equal surfaces' combined stiffness (``stiffness`` in N/m^1.5),
- a normal force ``f = fH (1 + 1.5 c v_in)`` along the floor's normal, none where ``f < 0``
  (``c`` the dissipation, s/m; ``v_in`` the speed into the floor, m/s),
- a friction force against the slip, ``f min(s, 1) (ud + 2 (us - ud) / (1 + s^2))`` with
  ``s`` the slip speed over :data:`TRANSITION_VELOCITY` (Simbody's, including its use of the
  unclipped ``f``),

at the overlap's middle, depth / 2 below the floor. Unlike MuJoCo's soft contact (a
constraint whose force depends on the whole body's inertia), the force depends on the
sphere's depth and speed alone, as OpenSim's does.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
from gaitforge.workers.bodies.schema import ContactMaterial

TRANSITION_VELOCITY = 0.1
"""m/s: slip speed of peak static friction (the reference's HuntCrossleyForce value; also
OpenSim's, ``opensim.build``)."""


def hertz_coefficient(stiffness: float, radius: float) -> float:
    """N/m^1.5: ``fH / d^1.5`` for a sphere of ``radius`` (m) on a half-space, both surfaces
    of ``stiffness`` (N/m^1.5)."""
    combined = 0.5 * stiffness ** (2.0 / 3.0)
    return 4.0 / 3.0 * combined**1.5 * np.sqrt(radius)


def sphere_force(
    depth: float, velocity: np.ndarray, up: int, coefficient: float, material: ContactMaterial
) -> np.ndarray:
    """[3] world force (N) from the floor, whose normal is world axis ``up``, on a sphere
    ``depth`` (m, > 0) into it whose contact point moves at ``velocity`` ([3], m/s), with
    :func:`hertz_coefficient` ``coefficient`` (N/m^1.5). Scalar arithmetic: it runs for each
    touching sphere at every MuJoCo step."""
    normal = coefficient * depth**1.5 * (1.0 - 1.5 * material.dissipation * velocity[up])
    force = velocity.copy()
    force[up] = 0.0  # the slip, for now
    speed = math.sqrt(force[0] ** 2 + force[1] ** 2 + force[2] ** 2)
    if speed > 0.0:
        ratio = speed / TRANSITION_VELOCITY
        us, ud = material.static_friction, material.dynamic_friction
        friction = normal * min(ratio, 1.0) * (ud + 2.0 * (us - ud) / (1.0 + ratio * ratio))
        force *= -friction / speed
    force[up] = max(normal, 0.0)
    return force


class HuntCrossleyFloor:
    """The floor's Hunt-Crossley forces on a compiled model's contact spheres.

    ``add`` is called between ``mj_step1`` and ``mj_step2``: it reads the spheres' positions
    and velocities there and adds their generalized forces to a vector the caller applies.
    ``forces`` ([n spheres, 3], N, world frame) holds the last call's forces on the spheres,
    ``normal_forces`` ([n spheres], N) their normal parts.
    """

    def __init__(
        self, model: mujoco.MjModel, spheres: np.ndarray, material: ContactMaterial, up: int
    ) -> None:
        self.spheres = np.asarray(spheres, dtype=int)
        self.bodies = model.geom_bodyid[self.spheres]
        self.radii = model.geom_size[self.spheres, 0].copy()
        self.coefficient = np.array([hertz_coefficient(material.stiffness, r) for r in self.radii])
        self.material = material
        self.up = up
        self.forces = np.zeros((len(self.spheres), 3))
        self._each = list(
            zip(
                self.spheres.tolist(),
                self.bodies.tolist(),
                self.radii.tolist(),
                self.coefficient.tolist(),
                strict=True,
            )
        )
        self._jac = np.zeros((3, model.nv))
        self._torque = np.zeros(3)

    @property
    def normal_forces(self) -> np.ndarray:
        return self.forces[:, self.up]

    def add(self, model: mujoco.MjModel, data: mujoco.MjData, qfrc: np.ndarray) -> None:
        """Add the floor's forces at the present positions and speeds to ``qfrc`` ([nv];
        the floor is the plane through the origin normal to axis ``up``)."""
        self.forces[:] = 0.0
        for i, (geom, body, radius, coefficient) in enumerate(self._each):
            point = data.geom_xpos[geom].copy()
            depth = radius - point[self.up]
            if depth <= 0.0:
                continue
            point[self.up] = -0.5 * depth  # the overlap's middle
            mujoco.mj_jac(model, data, self._jac, None, point, body)
            force = sphere_force(depth, self._jac @ data.qvel, self.up, coefficient, self.material)
            self.forces[i] = force
            mujoco.mj_applyFT(model, data, force, self._torque, point, body, qfrc)
