"""What an OpenSim model shows of its state for drawing, recording and observing: each body's
frame in ground, each muscle's path points (``OpenSimSimulator.body_frames``,
``muscle_paths``) and the vertical ground reaction of a contact force (``foot_forces``)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import opensim
from gaitforge.workers.sim.base import BodyPose


def vec3(v: opensim.Vec3) -> np.ndarray:
    """[3] array of an OpenSim ``Vec3``."""
    return np.array([v.get(0), v.get(1), v.get(2)])


def body_frames(model: opensim.Model, state: opensim.State) -> dict[str, BodyPose]:
    """Every body's position (m) and orientation (quaternion w, x, y, z) in ground, with the
    body its joint hangs from ("" for ground)."""
    model.realizePosition(state)
    parents = {}
    joints = model.getJointSet()
    for i in range(joints.getSize()):
        joint = joints.get(i)
        parent = joint.getParentFrame().findBaseFrame().getName()
        parents[joint.getChildFrame().findBaseFrame().getName()] = (
            "" if parent == "ground" else parent
        )
    frames = {}
    bodies = model.getBodySet()
    for i in range(bodies.getSize()):
        body = bodies.get(i)
        pose = body.getTransformInGround(state)
        q = pose.R().convertRotationToQuaternion()
        frames[body.getName()] = BodyPose(
            vec3(pose.p()), np.array([q.get(k) for k in range(4)]), parents.get(body.getName(), "")
        )
    return frames


def muscle_paths(
    model: opensim.Model,
    state: opensim.State,
    names: Sequence[str],
    muscles: Sequence[opensim.Muscle],
) -> dict[str, np.ndarray]:
    """Each muscle's path points active now, wrap points included, [n_points, 3] m in ground
    (``GeometryPath.getCurrentPath``); a function-based path has none ([0, 3])."""
    model.realizePosition(state)
    paths = {}
    for name, muscle in zip(names, muscles, strict=True):
        geometry = opensim.GeometryPath.safeDownCast(muscle.getPath())
        if geometry is None:
            paths[name] = np.zeros((0, 3))
            continue
        points = geometry.getCurrentPath(state)
        paths[name] = np.array(
            [vec3(points.get(k).getLocationInGround(state)) for k in range(points.getSize())]
        ).reshape(-1, 3)
    return paths


def ground_normal_force(force: opensim.Force, state: opensim.State) -> float:
    """Magnitude of the vertical ground reaction that ``force`` applies (N)."""
    values = force.getRecordValues(state)
    labels = force.getRecordLabels()
    total = 0.0
    for i in range(labels.size()):
        label = labels.get(i)
        if label.endswith(".force.Y") and ".ground." not in f".{label}":
            total += values.get(i)
    return abs(total)
