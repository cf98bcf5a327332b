"""The small protocol every simulator backend implements, and what it returns."""

from __future__ import annotations

from collections.abc import Callable, Collection
from dataclasses import dataclass, field
from typing import NamedTuple, Protocol

import numpy as np
from gaitforge.workers.scenes.profiles import FidelityProfile
from gaitforge.workers.scenes.prune import PrunePlan

HEALTHY = "ok"
MAX_SPEED = 200.0
"""Any joint speed above this (rad/s or m/s) is divergence, not motion: a human joint peaks
near 50 rad/s. MuJoCo only flags accelerations above 1e10, long after a blow-up starts."""


@dataclass(frozen=True)
class Health:
    """Numerical health of one control step. ``cause`` names the first failure seen."""

    cause: str = HEALTHY

    @property
    def ok(self) -> bool:
        return self.cause == HEALTHY


@dataclass
class SimState:
    """Read-out after a step. World frame of the body's source (up and forward axes named).

    Attributes:
        time: simulated time, s.
        dof_pos: [n_dofs] kept non-root dof positions, rad or m.
        dof_vel: [n_dofs] their speeds, rad/s or m/s.
        pelvis_pos: [3] pelvis origin in the world, m.
        pelvis_up: [3] the pelvis's up axis in the world (unit; equals world up when upright).
        pelvis_forward: [3] the pelvis's forward axis in the world (unit; equals world forward
            when it stands facing ahead): its heading.
        pelvis_vel: [3] linear velocity of the pelvis origin, m/s.
        pelvis_angvel: [3] angular velocity of the pelvis, rad/s.
        activations: [n_muscles] in [0, 1].
        foot_forces: [n_feet] normal ground reaction force per foot, N.
    """

    time: float
    dof_pos: np.ndarray
    dof_vel: np.ndarray
    pelvis_pos: np.ndarray
    pelvis_up: np.ndarray
    pelvis_forward: np.ndarray
    pelvis_vel: np.ndarray
    pelvis_angvel: np.ndarray
    activations: np.ndarray
    foot_forces: np.ndarray

    def arrays(self) -> list[np.ndarray]:
        return [
            self.dof_pos,
            self.dof_vel,
            self.pelvis_pos,
            self.pelvis_up,
            self.pelvis_forward,
            self.pelvis_vel,
            self.pelvis_angvel,
            self.activations,
            self.foot_forces,
        ]

    def is_finite(self) -> bool:
        return bool(np.isfinite(self.time)) and all(np.isfinite(a).all() for a in self.arrays())


@dataclass(frozen=True)
class Pose:
    """A whole-body state to start from (reference state initialisation), by name.

    Angles use OpenSim's conventions whatever the backend: pelvis pitch, list and rotation
    are ``pelvis_tilt``, ``pelvis_list`` and ``pelvis_rotation`` (body-fixed Z, X, Y of a
    Y-up, X-forward, Z-right frame; MyoLeg's Z-up world is mapped onto it).

    Attributes:
        coordinates: non-root dof -> value, rad or m. Dofs the scene locked are ignored.
        speeds: non-root dof -> speed, rad/s or m/s (missing ones are 0).
        pelvis_height: m, pelvis origin above the floor.
        pelvis_pitch, pelvis_list, pelvis_rotation: rad.
        pelvis_angular_speed: rad/s, time derivatives of (pitch, list, rotation).
        forward_speed: m/s of the pelvis origin along the world's forward axis.
        vertical_speed: m/s of the pelvis origin along the world's up axis.
    """

    coordinates: dict[str, float]
    speeds: dict[str, float] = field(default_factory=dict)
    pelvis_height: float = 0.9
    pelvis_pitch: float = 0.0
    pelvis_list: float = 0.0
    pelvis_rotation: float = 0.0
    pelvis_angular_speed: tuple[float, float, float] = (0.0, 0.0, 0.0)
    forward_speed: float = 0.0
    vertical_speed: float = 0.0


def check_pose_names(pose: Pose, body: str, kept: Collection[str], locked: Collection[str]) -> None:
    """Raise ``ValueError`` if ``pose`` names a coordinate that is neither kept nor locked."""
    unknown = [n for n in pose.coordinates if n not in kept and n not in locked]
    if unknown:
        raise ValueError(f"set_pose: body {body!r} has no coordinates {unknown}")


class BodyPose(NamedTuple):
    """World pose of one body (for drawing), in the simulator's world frame (its up and
    forward axes: ``Simulator.up_axis``, ``Simulator.forward_axis``).

    Attributes:
        position: [3] body origin in the world, m.
        quaternion: [4] orientation in the world, scalar first (w, x, y, z), unit.
        parent: name of the parent body; "" for a body attached to the world (ground).
    """

    position: np.ndarray
    quaternion: np.ndarray
    parent: str


@dataclass
class CompileReport:
    """What compiling a scene kept and dropped, and the model's size before and after.

    ``size_full`` is the body with nothing removed; ``size`` the scene's model. Keys: dofs,
    joints, bodies, muscles, tendons, wrap_objects, geoms, sites, contact_pairs.
    """

    scene: str
    backend: str
    body: str
    profile: FidelityProfile
    plan: PrunePlan
    size_full: dict[str, int]
    size: dict[str, int]
    mass: float = 0.0
    """kg, of the compiled model"""
    dropped_joints: list[str] = field(default_factory=list)

    def saved(self) -> dict[str, int]:
        return {k: self.size_full.get(k, 0) - v for k, v in self.size.items()}


Reflex = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""Joint angles and speeds of the kept dofs ([n_dofs] each) -> excitations [n_muscles] in
[0, 1] (``workers.reflex.ReflexLayer``)."""


class Simulator(Protocol):
    """One simulated scene. Implementations never raise for a numerical failure: they
    report it in :class:`Health` and leave the state for ``reset`` to repair."""

    report: CompileReport
    dof_names: list[str]
    muscle_names: list[str]
    foot_names: list[str]
    up_axis: int
    forward_axis: int

    def reset(self, seed: int) -> None:
        """Default pose plus seeded noise; re-place obstacles; zero activations."""

    def step(self, excitations: np.ndarray, duration: float) -> Health:
        """Hold ``excitations`` ([n_muscles] in [0, 1]) for ``duration`` seconds."""

    def step_reflex(
        self, reflex: Reflex, duration: float, updates: int
    ) -> tuple[np.ndarray, Health]:
        """Step ``duration`` seconds, setting the excitations ``updates`` times, evenly, to
        ``reflex(q, qd)`` of the kept dofs' angles and speeds then ([n_dofs] each ->
        [n_muscles] in [0, 1]; ``workers.reflex``). Returns the mean excitations [n_muscles] and the
        health. MuJoCo only (scenes with joint targets are refused on OpenSim)."""

    def state(self) -> SimState: ...

    def moment_arms(self) -> np.ndarray:
        """[n_muscles, n_dofs]: each muscle's moment arm about each kept dof now (m; the
        joint torque per newton of tension, signed as the dof's axis)."""

    def muscle_sensors(self) -> tuple[np.ndarray, np.ndarray]:
        """What a muscle's spindles and tendon organs sense now: each muscle's fibre length
        as a fraction of its optimal length, and its tension as a fraction of its maximum
        isometric force ([n_muscles] each, dimensionless; ``workers.gait_reflex``)."""

    def set_pose(self, pose: Pose) -> None:
        """Put the body in ``pose`` (kept dofs, pelvis height and orientation, speeds) where
        it stands now along the ground (forward position kept, lateral 0); lifted if a
        foot would start inside the floor. Call after ``reset``; activations unchanged.

        Raises:
            ValueError: ``pose`` names a coordinate the body lacks.
        """

    def push(self, force: np.ndarray) -> None:
        """Hold ``force`` [3] (N, world frame) on the pelvis's centre of mass from now on,
        until the next call (zeros to stop; a reset stops it).

        Raises:
            ValueError: the scene has no ``pushes`` (OpenSim builds the force only then).
        """

    def foot_positions(self) -> dict[str, np.ndarray]:
        """Each foot's (``foot_names``) point: the mean of its contact geoms' centres in
        the world, [3] m."""

    def obstacles(self) -> np.ndarray:
        """[n_obstacles, 3]: forward position, height (m) and radius (m) of each obstacle."""

    def get_state(self) -> dict[str, np.ndarray]:
        """Everything needed to continue the integration exactly (for pickling)."""

    def set_state(self, state: dict[str, np.ndarray]) -> None: ...

    def poison(self) -> None:
        """Write NaN into the simulator's state (fault injection in tests)."""

    # ---- read-outs for drawing (recordings, video) -------------------------------------

    def body_frames(self) -> dict[str, BodyPose]:
        """World pose of every body (the world/ground itself excluded), parents first."""

    def muscle_paths(self) -> dict[str, np.ndarray]:
        """Each muscle's path, by muscle name (``muscle_names``): [P, 3] points in the world
        from origin to insertion (via points and wrap points included), m."""

    def contact_spheres(self) -> dict[str, np.ndarray]:
        """Each foot's (``foot_names``) contact spheres: [S, 4] centre in the world (m) and
        radius (m); spheres only (MuJoCo foot geoms of other shapes are left out)."""

    def coordinates(self) -> dict[str, float]:
        """Every scalar joint coordinate by name (root dofs and locked dofs included), rad
        or m; ball and free joints are left out."""
