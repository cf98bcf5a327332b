"""Skeletons drawn into a MuJoCo render scene (``learner.evaluation.video``): the body's own
(opaque) and, in imitation scenes, the reference pose's, a translucent green copy of the same
skeleton overlaid in place and moved with the body's pelvis along the ground
(``learner.evaluation.reference_pose``), so a person sees how closely the body follows the
motion."""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

import mujoco
import numpy as np
from gaitforge.learner.evaluation.reference_pose import ReferenceBody, has_clock

if TYPE_CHECKING:
    from gaitforge.workers.env import MuscleEnv

logger = logging.getLogger(__name__)

BONE_RADIUS = 0.015
"""m: skeleton capsules; spheres at body origins are twice as wide."""
SKELETON_RGBA = np.array([0.85, 0.85, 0.8, 1.0], dtype=np.float32)
REFERENCE_RGBA = np.array([0.1, 0.9, 0.4, 0.35], dtype=np.float32)
"""the reference skeleton: translucent green (as in the MCAP recordings)"""


def add_geom(
    scene: mujoco.MjvScene,
    kind: mujoco.mjtGeom,
    size: np.ndarray,
    pos: np.ndarray,
    rgba: np.ndarray,
) -> mujoco.MjvGeom | None:
    """Append a geom (world frame, unrotated) to ``scene``; None when it is full."""
    if scene.ngeom >= scene.maxgeom:
        return None
    geom = scene.geoms[scene.ngeom]
    scene.ngeom += 1
    mujoco.mjv_initGeom(geom, kind, size, pos, np.eye(3).ravel(), rgba)
    return geom


def add_skeleton(
    scene: mujoco.MjvScene, positions: np.ndarray, parents: np.ndarray, rgba: np.ndarray
) -> None:
    """A capsule from each body's parent origin to its origin (``parents[i] >= 0``, an index
    into ``positions`` [B, 3], world m) and a sphere at each origin, in ``rgba``."""
    capsule, sphere = mujoco.mjtGeom.mjGEOM_CAPSULE, mujoco.mjtGeom.mjGEOM_SPHERE
    joint = np.array([2 * BONE_RADIUS, 0, 0])
    for i, here in enumerate(positions):
        parent = parents[i]
        if parent >= 0 and np.linalg.norm(here - positions[parent]) > 1e-6:
            bone = add_geom(scene, capsule, np.zeros(3), np.zeros(3), rgba)
            if bone is None:
                return
            mujoco.mjv_connector(bone, capsule, BONE_RADIUS, positions[parent], here)
        if add_geom(scene, sphere, joint, here, rgba) is None:
            return


def add_model_skeleton(scene: mujoco.MjvScene, m: mujoco.MjModel, d: mujoco.MjData) -> None:
    """The skeleton of a posed model (world body left out), opaque."""
    parents = np.asarray(m.body_parentid[1:], dtype=int) - 1  # the world (-1) draws no bone
    add_skeleton(scene, np.asarray(d.xpos[1:]), parents, SKELETON_RGBA)


class ReferenceSkeleton:
    """The reference pose of an env with the gait clock, drawn as a translucent skeleton while
    :attr:`visible`; does nothing for other scenes (:attr:`active` False)."""

    def __init__(self, env: MuscleEnv) -> None:
        self.visible = True
        self._body: ReferenceBody | None = None
        if has_clock(env):
            try:
                self._body = ReferenceBody(env)
            except ValueError as exc:
                logger.warning("video: no reference skeleton: %s", exc)

    @property
    def active(self) -> bool:
        return self._body is not None

    def draw(self, scene: mujoco.MjvScene, env: MuscleEnv) -> bool:
        """Add the reference skeleton at ``env``'s current phase; False when there is none."""
        frames = None if self._body is None or not self.visible else self._body.frames(env)
        if not frames:
            return False
        names = list(frames)
        index = {name: i for i, name in enumerate(names)}
        positions = np.array([frames[n].position for n in names], dtype=float)
        parents = np.array([index.get(frames[n].parent, -1) for n in names], dtype=int)
        add_skeleton(scene, positions, parents, REFERENCE_RGBA)
        return True
