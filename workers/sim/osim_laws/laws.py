"""The forces a MuJoCo scene asks to follow OpenSim's laws rather than MuJoCo's own: its
``contact_model: hunt-crossley`` (``hunt_crossley``), ``joint_limits: opensim``
(``limit_springs``) and ``muscle_curves`` / ``muscle_passive: opensim``
(``muscles``). ``mujoco.compile`` has taken MuJoCo's own versions out of the model;
:class:`OpenSimLaws` computes these in Python between each physics step's position-velocity
stage and the rest (``mj_step1`` / ``mj_step2``) and writes them to ``qfrc_applied``.
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np
from gaitforge.workers.bodies import load_body
from gaitforge.workers.scenes import Scene
from gaitforge.workers.sim.mujoco.compile import opensim_limits
from gaitforge.workers.sim.mujoco.contacts import CONTACT_BIT
from gaitforge.workers.sim.osim_laws.hunt_crossley import HuntCrossleyFloor
from gaitforge.workers.sim.osim_laws.limit_springs import LimitSprings
from gaitforge.workers.sim.osim_laws.muscles import OpenSimMuscles

Law = HuntCrossleyFloor | LimitSprings | OpenSimMuscles


class OpenSimLaws:
    """The OpenSim-law forces of one compiled scene (none: MuJoCo's own forces alone).

    Attributes:
        floor: the Hunt-Crossley floor (None without ``contact_model: hunt-crossley``).
        laws: every law in force, the floor included.
    """

    def __init__(
        self, model: mujoco.MjModel, scene: Scene, dof_names: Sequence[str], up_axis: int
    ) -> None:
        self.floor: HuntCrossleyFloor | None = None
        self.laws: list[Law] = []
        if scene.mujoco.contact_model == "hunt-crossley":
            spheres = np.flatnonzero(
                (model.geom_type == mujoco.mjtGeom.mjGEOM_SPHERE)
                & (model.geom_contype & CONTACT_BIT != 0)
                & (model.geom_bodyid != 0)
            )
            self.floor = HuntCrossleyFloor(model, spheres, load_body(scene.body).contact, up_axis)
            self.laws.append(self.floor)
        if scene.mujoco.joint_limits == "opensim":
            self.laws.append(LimitSprings(model, opensim_limits(scene, list(dof_names))))
        active, passive = (
            scene.mujoco.muscle_curves == "opensim",
            scene.mujoco.muscle_passive == "opensim",
        )
        if active or passive:
            muscles = load_body(scene.body).muscles
            self.laws.append(OpenSimMuscles(model, muscles, active=active, passive=passive))

    def advance(self, model: mujoco.MjModel, data: mujoco.MjData, steps: int) -> None:
        """``steps`` MuJoCo steps, the laws' forces set anew within each."""
        if not self.laws:
            mujoco.mj_step(model, data, nstep=steps)
            return
        for _ in range(steps):
            mujoco.mj_step1(model, data)
            self.apply(model, data)
            mujoco.mj_step2(model, data)

    def apply(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """``data.qfrc_applied`` [nv]: the laws' forces at the present positions and speeds
        (after ``mj_step1`` or ``mj_forward``; at a reset it is what the floor's
        :meth:`add_foot_forces` reports before the next step)."""
        applied = data.qfrc_applied
        applied[:] = 0.0
        for law in self.laws:
            law.add(model, data, applied)

    def add_foot_forces(self, forces: np.ndarray, geom_foot: np.ndarray) -> None:
        """Add the floor's normal forces from its last call (N) to ``forces`` [n_feet], each
        sphere's to its foot (``geom_foot`` [ngeom]: the foot index, -1 for none)."""
        if self.floor is None:
            return
        feet = geom_foot[self.floor.spheres]
        on_foot = feet >= 0
        np.add.at(forces, feet[on_foot], self.floor.normal_forces[on_foot])
