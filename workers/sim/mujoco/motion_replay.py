"""Kinematic replay of a reference motion on its body's MuJoCo model (no dynamics).

Used by ``bench/data/make_motions.py`` (to place the pelvis and the feet) and by the motion
tests (feet above the floor, stance feet still). Only ``mj_kinematics`` is run: set the pose,
read the frames.

Conventions: the pelvis origin is the pelvis body's frame origin; a foot's *centroid* is the
mean of its contact geoms' centres (``Topology.feet``); a foot's *lowest point* is the lowest
point of any of its contact geoms' surfaces (spheres, capsules, ellipsoids, boxes).
"""

from __future__ import annotations

import mujoco
import numpy as np
from gaitforge.workers.bodies import load_body
from gaitforge.workers.bodies.topology import topology_for
from gaitforge.workers.sim.mujoco.build import build_spec
from gaitforge.workers.sim.mujoco.lock import coupled_qpos
from gaitforge.workers.sim.mujoco.mjcf_models import myoleg_spec

UP = {"myoleg": 2}
"""World up axis index of the MJCF bodies; neutral bodies are Y-up (1). Forward is X (0)."""
_OS_TO_WORLD = {"myoleg": np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])}
"""OpenSim ground axes (X fwd, Y up, Z right) as columns in the body's world axes."""


def _rot(axis: int, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


def _lowest(model: mujoco.MjModel, data: mujoco.MjData, geom: int, up: int) -> float:
    """Height (world ``up`` coordinate) of the lowest surface point of ``geom``."""
    centre = data.geom_xpos[geom]
    rot = data.geom_xmat[geom].reshape(3, 3)
    size = model.geom_size[geom]
    u = rot[up]  # the up direction in the geom's frame
    kind = model.geom_type[geom]
    if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        extent = size[0]
    elif kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
        extent = size[0] + size[1] * abs(u[2])
    elif kind == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
        extent = float(np.sqrt(np.sum((size * u) ** 2)))
    elif kind == mujoco.mjtGeom.mjGEOM_BOX:
        extent = float(np.sum(size * np.abs(u)))
    else:
        raise ValueError(f"contact geom type {kind} not supported")
    return float(centre[up] - extent)


class Replay:
    """One body's model posed from OpenSim-convention coordinates.

    Args:
        body: "myoleg", or a neutral body (``gait2d``, an imported one: Y up, its root
            ``pelvis_tx``, ``pelvis_ty`` and ``pelvis_tilt``, with ``pelvis_tz``,
            ``pelvis_list`` and ``pelvis_rotation`` where it has them).
    """

    def __init__(self, body: str) -> None:
        self.body = body
        self.up = UP.get(body, 1)
        if body == "myoleg":
            self.model = myoleg_spec().compile()
        else:
            self.model = build_spec(load_body(body)).compile()
        self.data = mujoco.MjData(self.model)
        topo = topology_for(body)
        self.feet = {
            foot: [self.model.geom(g).id for g in geoms] for foot, geoms in topo.feet.items()
        }
        self.pelvis = self.model.body("pelvis").id
        self._joints = {self.model.joint(j).name for j in range(self.model.njnt)}
        if self.model.nkey:
            mujoco.mj_resetDataKeyframe(self.model, self.data, 0)
        mujoco.mj_kinematics(self.model, self.data)
        self.qpos0 = self.data.qpos.copy()
        if body in _OS_TO_WORLD:  # pelvis orientation relative to the free root
            root = self.model.body("root").id
            self._pelvis_in_root = self.data.xmat[root].reshape(3, 3).T @ self.data.xmat[
                self.pelvis
            ].reshape(3, 3)
            self._offset_local = self.data.xmat[root].reshape(3, 3).T @ (
                self.data.xpos[self.pelvis] - self.data.xpos[root]
            )

    def pose(
        self,
        joints: dict[str, float],
        pitch: float,
        height: float,
        x: float = 0.0,
        list_: float = 0.0,
        rotation: float = 0.0,
    ) -> None:
        """Pose the body: joints (rad, the model's own signs, as a motion stores them), pelvis
        tilt/list/rotation (rad, OpenSim's convention and order), pelvis
        origin at forward position ``x`` (m) and ``height`` (m) above the floor."""
        m, d = self.model, self.data
        q = self.qpos0.copy()
        for name, value in joints.items():
            q[m.jnt_qposadr[m.joint(name).id]] = value
        if self.body in _OS_TO_WORLD:
            target = _OS_TO_WORLD[self.body] @ _rot(2, pitch) @ _rot(0, list_) @ _rot(1, rotation)
            root_rot = target @ self._pelvis_in_root.T
            quat = np.zeros(4)
            mujoco.mju_mat2Quat(quat, root_rot.flatten())
            pos = np.zeros(3)
            pos[0], pos[self.up] = x, height
            q[0:3] = pos - root_rot @ self._offset_local
            q[3:7] = quat
            q = coupled_qpos(m, q)
        else:
            root = {"pelvis_tilt": pitch, "pelvis_list": list_, "pelvis_rotation": rotation}
            for name, value in {**root, "pelvis_tx": 0.0, "pelvis_ty": 0.0}.items():
                if name in self._joints:
                    q[m.jnt_qposadr[m.joint(name).id]] = value
            q = coupled_qpos(m, q)
            d.qpos[:] = q
            mujoco.mj_kinematics(m, d)
            offset = d.xpos[self.pelvis].copy()
            q[m.jnt_qposadr[m.joint("pelvis_tx").id]] = x - offset[0]
            q[m.jnt_qposadr[m.joint("pelvis_ty").id]] = height - offset[1]
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)

    def pelvis_origin(self) -> np.ndarray:
        """[3] m, world."""
        return self.data.xpos[self.pelvis].copy()

    def centroid(self, foot: str) -> np.ndarray:
        """[3] m, world: mean of the foot's contact geom centres."""
        return self.data.geom_xpos[self.feet[foot]].mean(axis=0)

    def lowest(self, foot: str) -> float:
        """m: height of the foot's lowest contact surface point above the floor."""
        return min(_lowest(self.model, self.data, g, self.up) for g in self.feet[foot])

    def lowest_geom_centre(self, foot: str) -> np.ndarray:
        """[3] m, world: centre of the foot's contact geom that reaches lowest (the one on the
        ground in stance: heel, then toe as the foot rolls over)."""
        g = min(self.feet[foot], key=lambda g: _lowest(self.model, self.data, g, self.up))
        return self.data.geom_xpos[g].copy()
