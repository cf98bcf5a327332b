"""The messages of an episode recording (``learner.evaluation.recording`` writes them): Foxglove's
well-known schemas built from one simulator state, and the JSON messages of the scalar
channels, all in the Z-up, X-forward ``world`` frame that Foxglove and Lichtblick expect.

The simulator's world (gait2d and OpenSim bodies are Y-up with X forward; MyoLeg is Z-up with
X forward) is rotated into that frame; rotations are composed with MuJoCo's quaternion
helpers (``mujoco.mju_*``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import mujoco
import numpy as np
from foxglove.messages import (
    Color,
    FrameTransform,
    FrameTransforms,
    JointState,
    JointStates,
    LinePrimitive,
    LinePrimitiveLineType,
    Point3,
    Pose,
    Quaternion,
    SceneEntity,
    SceneUpdate,
    SpherePrimitive,
    Timestamp,
    Vector3,
)
from gaitforge.workers.env import GRAVITY, MuscleEnv
from gaitforge.workers.sim.base import HEALTHY, BodyPose, SimState, Simulator

WORLD = "world"
BODY_RADIUS = 0.03
"""m: the sphere drawn at each body origin."""
BONE_WIDTH = 0.015
"""m: the line from a parent body's origin to its child's."""
MUSCLE_WIDTH = 0.008
"""m: the muscle lines."""
GREY = Color(r=0.8, g=0.8, b=0.8, a=1.0)
OBSTACLE_COLOUR = Color(r=0.6, g=0.4, b=0.3, a=1.0)
REFERENCE_COLOUR = Color(r=0.1, g=0.9, b=0.4, a=0.35)
"""the reference skeleton of imitation scenes: translucent green"""


def z_up_rotation(up_axis: int, forward_axis: int) -> np.ndarray:
    """[3, 3] rotation taking the simulator's world (``up_axis``, ``forward_axis``) to a
    Z-up, X-forward frame (Y = Z x X, to the left): rows are the new axes in the old frame."""
    up, forward = np.eye(3)[up_axis], np.eye(3)[forward_axis]
    return np.stack([forward, np.cross(up, forward), up])


def matrix_to_quat(r: np.ndarray) -> np.ndarray:
    """[4] unit quaternion (w, x, y, z) of the rotation matrix ``r`` [3, 3]."""
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.asarray(r, dtype=np.float64).ravel())
    return q


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of two (w, x, y, z) quaternions: rotation ``b`` then ``a``."""
    q = np.zeros(4)
    mujoco.mju_mulQuat(q, np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64))
    return q


def activation_color(a: float, alpha: float = 1.0) -> Color:
    """Blue (activation 0) to red (1), through purple."""
    a = float(np.clip(a, 0.0, 1.0)) if np.isfinite(a) else 0.0
    return Color(r=a, g=0.1, b=1.0 - a, a=alpha)


def json_schema(title: str, numbers: list[str], strings: tuple[str, ...] = ()) -> dict:
    """A JSON schema of an object of numbers (and strings) named ``title``."""
    props: dict[str, dict[str, str]] = {name: {"type": "number"} for name in numbers}
    props.update({name: {"type": "string"} for name in strings})
    return {"title": title, "type": "object", "properties": props}


def _point(p: np.ndarray) -> Point3:
    return Point3(x=float(p[0]), y=float(p[1]), z=float(p[2]))


def _pose(p: np.ndarray) -> Pose:
    return Pose(
        position=Vector3(x=float(p[0]), y=float(p[1]), z=float(p[2])),
        orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
    )


def _sphere(centre: np.ndarray, radius: float, color: Color) -> SpherePrimitive:
    return SpherePrimitive(
        pose=_pose(centre), size=Vector3(x=2 * radius, y=2 * radius, z=2 * radius), color=color
    )


class EpisodeMessages:
    """Builds each step's messages for one env: names, axes and the rotation to ``world``
    are fixed at construction; the distance since reset is tracked across steps."""

    def __init__(self, env: MuscleEnv) -> None:
        sim = env.sim
        self.muscles = list(sim.muscle_names)
        self.feet = list(sim.foot_names)
        self.forward, self.up = sim.forward_axis, sim.up_axis
        self._rot = z_up_rotation(sim.up_axis, sim.forward_axis)
        self._rot_q = matrix_to_quat(self._rot)
        self._target_speed = float(env.scene.task.target_speed or 0.0)
        self.reward_terms = list(env.reward_term_names)
        self._weight = max(GRAVITY * sim.report.mass, 1e-9)
        self._start_forward: float | None = None

    def scalar_schemas(self) -> dict[str, dict]:
        """JSON schema of each scalar channel, by topic."""
        return {
            "/reward": json_schema("gaitforge.Reward", ["total", *self.reward_terms]),
            "/speed": json_schema(
                "gaitforge.Speed", ["forward", "target", "distance", "pelvis_height"]
            ),
            "/activations": json_schema("gaitforge.Activations", self.muscles),
            "/excitations": json_schema("gaitforge.Excitations", self.muscles),
            "/foot_forces": json_schema("gaitforge.FootForces", self.feet),
            "/health": json_schema("gaitforge.Health", ["ok", "fell", "step"], ("cause",)),
        }

    @staticmethod
    def imitation_schema() -> dict:
        """JSON schema of the ``/imitation`` channel (imitation scenes)."""
        return json_schema("gaitforge.Imitation", ["phase", "pose_error_rad", "kept"])

    @staticmethod
    def imitation(info: Mapping[str, Any]) -> dict[str, Any]:
        """The ``/imitation`` message of a step: ``phase`` [0, 1), ``pose_error_rad`` (RMS
        over the tracked kept joints), ``kept`` (1/0: within the bound so far); empty when the
        step's info has none."""
        imitation = info.get("imitation")
        if imitation is None:
            return {}
        phase = float(imitation.get("phase", float("nan")))
        error = float(imitation.get("pose_error_rad", float("nan")))
        return {
            "phase": phase if np.isfinite(phase) else None,
            "pose_error_rad": error if np.isfinite(error) else None,
            "kept": int(bool(imitation.get("kept", False))),
        }

    def to_world(self, p: np.ndarray) -> np.ndarray:
        """[..., 3] simulator-world points to the Z-up ``world`` frame."""
        return np.asarray(p) @ self._rot.T

    def geometry(
        self, sim: Simulator, state: SimState, stamp: Timestamp
    ) -> tuple[FrameTransforms, SceneUpdate, JointStates]:
        """The ``/tf``, ``/scene`` and ``/joints`` messages of ``sim`` in a finite ``state``."""
        frames = sim.body_frames()
        return (
            self._transforms(frames, stamp),
            self._scene(sim, frames, state, stamp),
            self._joints(sim, state, stamp),
        )

    def _transforms(self, frames: dict[str, BodyPose], stamp: Timestamp) -> FrameTransforms:
        """World pose of every body: parent ``world``, child the body's name."""
        transforms = []
        for name, frame in frames.items():
            p = self.to_world(frame.position)
            q = quat_multiply(self._rot_q, frame.quaternion)
            transforms.append(
                FrameTransform(
                    timestamp=stamp,
                    parent_frame_id=WORLD,
                    child_frame_id=name,
                    translation=Vector3(x=float(p[0]), y=float(p[1]), z=float(p[2])),
                    rotation=Quaternion(w=float(q[0]), x=float(q[1]), y=float(q[2]), z=float(q[3])),
                )
            )
        return FrameTransforms(transforms=transforms)

    def skeleton(
        self, frames: dict[str, BodyPose], stamp: Timestamp, entity: str, color: Color
    ) -> SceneEntity:
        """A skeleton entity named ``entity`` in ``world``: a sphere at each body origin of
        ``frames`` (simulator world) and a line from each parent's origin to its child's."""
        positions = {name: self.to_world(f.position) for name, f in frames.items()}
        spheres = [_sphere(p, BODY_RADIUS, color) for p in positions.values()]
        bones = [
            point
            for name, frame in frames.items()
            if frame.parent in positions
            for point in (_point(positions[frame.parent]), _point(positions[name]))
        ]
        line_list = LinePrimitiveLineType.LineList
        lines = (
            [LinePrimitive(type=line_list, thickness=BONE_WIDTH, points=bones, color=color)]
            if bones
            else []
        )
        return SceneEntity(timestamp=stamp, frame_id=WORLD, id=entity, spheres=spheres, lines=lines)

    def reference(self, frames: dict[str, BodyPose], stamp: Timestamp) -> SceneUpdate:
        """The ``/reference`` message: the reference pose's skeleton (entity ``reference``,
        translucent green), from its body frames (``learner.evaluation.reference_pose``)."""
        return SceneUpdate(entities=[self.skeleton(frames, stamp, "reference", REFERENCE_COLOUR)])

    def _scene(
        self, sim: Simulator, frames: dict[str, BodyPose], state: SimState, stamp: Timestamp
    ) -> SceneUpdate:
        """Entities ``skeleton``, ``muscles``, ``obstacles`` and ``contacts``."""
        skeleton = self.skeleton(frames, stamp, "skeleton", GREY)
        paths = sim.muscle_paths()
        lines = []
        for name, a in zip(self.muscles, state.activations, strict=True):
            path = paths.get(name)
            if path is None or len(path) < 2:
                continue
            lines.append(
                LinePrimitive(
                    type=LinePrimitiveLineType.LineStrip,
                    thickness=MUSCLE_WIDTH,
                    points=[_point(p) for p in self.to_world(path)],
                    color=activation_color(a),
                )
            )
        muscles = SceneEntity(timestamp=stamp, frame_id=WORLD, id="muscles", lines=lines)
        obstacle_spheres = []
        for ahead, height, radius in sim.obstacles():
            centre = np.zeros(3)
            centre[self.forward], centre[self.up] = ahead, height
            obstacle_spheres.append(_sphere(self.to_world(centre), radius, OBSTACLE_COLOUR))
        obstacles = SceneEntity(
            timestamp=stamp, frame_id=WORLD, id="obstacles", spheres=obstacle_spheres
        )
        contact_spheres = []
        forces = dict(zip(self.feet, state.foot_forces, strict=True))
        for foot, foot_spheres in sim.contact_spheres().items():
            load = float(np.clip(forces.get(foot, 0.0) / self._weight, 0.0, 1.0))
            colour = Color(r=0.5 * (1 - load), g=0.5 + 0.5 * load, b=0.5 * (1 - load), a=0.8)
            for *centre, radius in foot_spheres:
                contact_spheres.append(_sphere(self.to_world(np.array(centre)), radius, colour))
        contacts = SceneEntity(
            timestamp=stamp, frame_id=WORLD, id="contacts", spheres=contact_spheres
        )
        return SceneUpdate(entities=[skeleton, muscles, obstacles, contacts])

    def _joints(self, sim: Simulator, state: SimState, stamp: Timestamp) -> JointStates:
        """Every scalar joint coordinate; velocities of the kept dofs."""
        speeds = dict(zip(sim.dof_names, state.dof_vel, strict=True))
        return JointStates(
            timestamp=stamp,
            joints=[
                JointState(
                    name=name,
                    position=float(q),
                    velocity=None if (v := speeds.get(name)) is None else float(v),
                )
                for name, q in sim.coordinates().items()
            ],
        )

    def scalars(
        self,
        state: SimState | None,
        action: np.ndarray,
        terms: Mapping[str, float],
        info: Mapping[str, Any],
        step: int,
    ) -> dict[str, dict[str, Any]]:
        """Each scalar channel's message, by topic (``state`` None after a failed step: the
        channels keep their counts with what is still known)."""
        reward = {"total": float(sum(terms.values())), **{k: float(v) for k, v in terms.items()}}
        action = np.asarray(action, dtype=float).ravel()
        excitations = {m: float(e) for m, e in zip(self.muscles, action, strict=False)}
        if state is not None:
            here = float(state.pelvis_pos[self.forward])
            if self._start_forward is None:
                self._start_forward = here - float(info.get("distance", 0.0))
            speed = {
                "forward": float(state.pelvis_vel[self.forward]),
                "target": self._target_speed,
                "distance": float(info.get("distance", here - self._start_forward)),
                "pelvis_height": float(state.pelvis_pos[self.up]),
            }
            activations = dict(zip(self.muscles, map(float, state.activations), strict=True))
            forces = dict(zip(self.feet, map(float, state.foot_forces), strict=True))
        else:
            speed = {"target": self._target_speed, "distance": float(info.get("distance", 0.0))}
            activations, forces = {}, {}
        cause = str(info.get("health", HEALTHY))
        health = {
            "ok": int(cause == HEALTHY),
            "cause": cause,
            "fell": int(bool(info.get("fell", False))),
            "step": int(info.get("step", step)),
        }
        return {
            "/reward": reward,
            "/excitations": excitations,
            "/speed": speed,
            "/activations": activations,
            "/foot_forces": forces,
            "/health": health,
        }
