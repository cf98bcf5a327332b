"""``set_pose`` on MuJoCo: a :class:`~gaitforge.workers.sim.base.Pose` written into ``qpos``
and ``qvel`` of a planar root (gait2d: ``pelvis_tx``/``pelvis_ty`` slides and a
``pelvis_tilt`` hinge) or a free root (MyoLeg: a free joint on the pelvis's parent body).

Speeds are the central difference of the poses at ``-/+ POSE_DT`` seconds
(``mj_differentiatePos``), so joint couplings (MyoLeg's knee and patella joints driven by
``knee_angle_*``) and the free root's angular velocity (in its local frame, as MuJoCo wants
it) come out consistent. The pelvis origin is placed at the pose's height by kinematics; if
a contact geom then still lies inside the floor, the body is lifted onto it.
"""

from __future__ import annotations

import mujoco
import numpy as np
from gaitforge.workers.sim.base import Pose
from gaitforge.workers.sim.mujoco.build import FLOOR
from gaitforge.workers.sim.mujoco.lock import coupled_qpos
from gaitforge.workers.sim.pose import pelvis_rotation

POSE_DT = 1e-4
"""s between the poses whose difference gives the speeds."""
ROOT_ANGLES = ("pelvis_tilt", "pelvis_list", "pelvis_rotation")
"""Planar/hinge root coordinates, in the order of ``Pose``'s pitch, list, rotation."""


class PoseSetter:
    """Writes poses into one model's data (addresses looked up once).

    Args:
        model: the compiled scene.
        dofs: kept non-root dofs, with ``(qpos addresses, lower, upper limits)`` [n_dofs].
        pelvis: body id of the pelvis.
        axes: the world's (up, forward) axes.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        dofs: list[str],
        limits: tuple[np.ndarray, np.ndarray, np.ndarray],
        pelvis: int,
        axes: tuple[int, int],
    ) -> None:
        m = self.model = model
        self.dofs = dofs
        self.qadr, self.qlo, self.qhi = limits
        self.pelvis = pelvis
        self.up, self.forward = axes
        self.floor = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, FLOOR)
        self.scratch = mujoco.MjData(m)
        parent = int(m.body_parentid[pelvis])
        self.free = next(
            (
                int(m.jnt_qposadr[j])
                for j in range(m.njnt)
                if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE
                and int(m.jnt_bodyid[j]) in {pelvis, parent}
            ),
            -1,
        )
        self.pelvis_in_root = np.eye(3)
        if self.free >= 0 and m.body_jntnum[pelvis] == 0:  # free joint on the parent
            mujoco.mju_quat2Mat(self.pelvis_in_root.ravel(), m.body_quat[pelvis])
        slides = {
            axis: int(m.jnt_qposadr[j])
            for j in range(m.njnt)
            for axis in range(3)
            if int(m.jnt_bodyid[j]) == pelvis
            and m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE
            and abs(m.jnt_axis[j][axis]) > 0.999
        }
        if self.free >= 0:
            slides = {axis: self.free + axis for axis in range(3)}
        self.up_adr = slides.get(self.up, -1)
        self.forward_adr = slides.get(self.forward, -1)
        self.lateral_adr = slides.get(3 - self.up - self.forward, -1)
        self.hinges = [
            int(m.jnt_qposadr[j])
            if (j := mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n)) >= 0
            else -1
            for n in ROOT_ANGLES
        ]

    def apply(self, data: mujoco.MjData, pose: Pose) -> None:
        """Set ``data`` to ``pose`` (forward position kept, lateral 0) and run ``mj_forward``."""
        m = self.model
        base = data.qpos.copy()
        before, qpos, after = (self.qpos(base, pose, t) for t in (-POSE_DT, 0.0, POSE_DT))
        qvel = np.zeros(m.nv)
        mujoco.mj_differentiatePos(m, qvel, 2 * POSE_DT, before, after)
        data.qpos[:] = qpos
        data.qvel[:] = qvel
        mujoco.mj_forward(m, data)
        lowest = min(
            (data.contact[i].dist for i in range(data.ncon) if self.floor in data.contact[i].geom),
            default=0.0,
        )
        if lowest < 0.0 and self.up_adr >= 0:
            data.qpos[self.up_adr] -= lowest
            mujoco.mj_forward(m, data)

    def qpos(self, base: np.ndarray, pose: Pose, t: float) -> np.ndarray:
        """``qpos`` of ``pose`` advanced ``t`` seconds at its speeds, from ``base`` (whose
        forward position is kept)."""
        m = self.model
        q = base.copy()
        for k, name in enumerate(self.dofs):
            if name in pose.coordinates:
                value = pose.coordinates[name] + t * pose.speeds.get(name, 0.0)
                q[self.qadr[k]] = np.clip(value, self.qlo[k], self.qhi[k])
        rates = pose.pelvis_angular_speed
        angles = (
            pose.pelvis_pitch + t * rates[0],
            pose.pelvis_list + t * rates[1],
            pose.pelvis_rotation + t * rates[2],
        )
        if self.free >= 0:
            rot = pelvis_rotation(*angles, self.up, self.forward) @ self.pelvis_in_root.T
            mujoco.mju_mat2Quat(q[self.free + 3 : self.free + 7], rot.ravel())
        else:
            for adr, angle in zip(self.hinges, angles, strict=True):
                if adr >= 0:
                    q[adr] = angle
        if self.forward_adr >= 0:
            q[self.forward_adr] += t * pose.forward_speed
        if self.lateral_adr >= 0:
            q[self.lateral_adr] = 0.0
        q = coupled_qpos(m, q)
        self.scratch.qpos[:] = q
        mujoco.mj_kinematics(m, self.scratch)
        if self.up_adr >= 0:
            height = pose.pelvis_height + t * pose.vertical_speed
            q[self.up_adr] += height - self.scratch.xpos[self.pelvis, self.up]
        return q
