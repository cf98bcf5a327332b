"""Imitation of a recorded gait in an env (a scene's ``task.imitate``), DeepMimic-style.

The gait clock (``workers.gait_clock``) says where in the motion the episode is; imitation
tracks it. Each reset starts the body in the reference state at the clock's phase (joint
angles plus uniform noise, their speeds, pelvis height, pitch, list, rotation and their
rates, forward and vertical speed; ``Simulator.set_pose``); or, in a fraction
``starts.standing`` of episodes, in the body's standing reset pose at phase 0 (at the
clock's phase when every episode starts standing); or, in a fraction ``starts.lead_in``,
part way along the clock's lead-in, in the faded reference state there.

Tracking terms, each ``exp(-scale * error)`` in (0, 1], weighted by ``task.imitate.weights``:

| term                    | error                                                    | unit      |
|-------------------------|----------------------------------------------------------|-----------|
| imitate_pose            | sum over tracked joints of (angle - reference)^2         | rad^2     |
| imitate_joint_speed     | sum over tracked joints of (speed - reference)^2         | (rad/s)^2 |
| imitate_feet            | sum over feet of |foot - pelvis - ref.|^2, in heading    | m^2       |
| imitate_pelvis_height   | (pelvis height - reference)^2                            | m^2       |
| imitate_pelvis_pitch    | (pitch - reference)^2 + (list - reference)^2 (OpenSim's) | rad^2     |
| imitate_pelvis_speed    | (forward speed over the step - reference at its end)^2   | (m/s)^2   |

The tracked joints are the motion's joints that the scene keeps. The episode ends early
(``terminated``, ``info["imitation"]["kept"]`` False) when the RMS pose error over them passes
``max_pose_error_rad``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from gaitforge.workers.bodies.topology import topology_for
from gaitforge.workers.gait_clock import GaitClock
from gaitforge.workers.motions import MotionState
from gaitforge.workers.scenes import Scene
from gaitforge.workers.scenes.clock import clock_joints
from gaitforge.workers.scenes.imitate import IMITATION_TERMS, Imitate
from gaitforge.workers.sim.base import Pose, SimState, Simulator
from gaitforge.workers.sim.pose import opensim_to_world, pelvis_pitch_list, pelvis_rotation


def wrapped(angle: float) -> float:
    """``angle`` (rad) brought into [-pi, pi)."""
    return (angle + np.pi) % (2.0 * np.pi) - np.pi


@dataclass(frozen=True)
class Tracking:
    """One step's tracking: unweighted kernels by term name, RMS pose error (rad)."""

    kernels: dict[str, float]
    pose_error_rad: float


class Imitation:
    """The tracking side of one env: its starts, the tracking terms and the early end."""

    def __init__(self, scene: Scene, sim: Simulator, clock: GaitClock) -> None:
        imitate = scene.task.imitate
        if imitate is None:
            raise ValueError(f"scene {scene.name!r}: task.imitate is not set")
        assert scene.task.clock is not None  # the scene's validation ties imitation to it
        self.spec: Imitate = imitate
        self.clock = clock
        topology = topology_for(scene.body)
        self.joints = clock_joints(scene.task.clock, scene.body, scene.keep.joints, topology)
        self._index = np.array([sim.dof_names.index(j) for j in self.joints], dtype=int)
        self._standing = np.array([topology.dof_defaults[j] for j in self.joints])
        self._feet = [f for f in sim.foot_names if f in clock.motion.feet]
        self.dt = clock.dt
        self.up, self.forward = sim.up_axis, sim.forward_axis
        self._to_os = opensim_to_world(self.up, self.forward).T

    # ---- reference state initialisation ----------------------------------------------

    def start(self, rng: np.random.Generator) -> Pose | None:
        """Start the clock and draw where this episode starts; the pose to start it from
        (None for a standing start: the simulator's reset pose)."""
        starts, clock = self.spec.starts, self.clock
        fraction = starts.standing
        clock.start(rng, standing=starts.all_standing)
        mixed_standing = 0.0 < fraction < 1.0 and bool(rng.uniform() < fraction)
        if mixed_standing:
            clock.standing_start = True
            clock.start_at_phase_zero()
        # of the episodes not standing, a share lead_in / (1 - standing) starts inside the
        # lead-in: lead_in of all
        inside_lead_in = not clock.standing_start and starts.lead_in > 0.0
        if inside_lead_in and rng.uniform() * (1.0 - fraction) < starts.lead_in:
            clock.start_along_lead_in(rng)
        if clock.standing_start:
            return None
        noise = rng.uniform(-starts.noise, starts.noise, len(self.joints))
        return self.pose_of(clock.reference(0), noise)

    def pose_of(self, ref: MotionState, noise: np.ndarray | None = None) -> Pose:
        """The simulator pose of reference state ``ref``: its tracked joints (plus ``noise``,
        [n_tracked] rad, if given) and speeds, and its pelvis."""
        noise = np.zeros(len(self.joints)) if noise is None else noise
        return Pose(
            coordinates={
                j: ref.joints[j] + float(e) for j, e in zip(self.joints, noise, strict=True)
            },
            speeds={n: ref.joint_speeds[n] for n in self.joints},
            pelvis_height=ref.pelvis_height,
            pelvis_pitch=ref.pelvis_pitch,
            pelvis_list=ref.pelvis_list,
            pelvis_rotation=ref.pelvis_rotation,
            pelvis_angular_speed=ref.pelvis_angular_speed,
            forward_speed=ref.forward_speed,
            vertical_speed=ref.pelvis_vertical_speed,
        )

    # ---- tracking -----------------------------------------------------------------------

    def pose_error(self, state: SimState, ref: MotionState, ramp: float = 1.0) -> np.ndarray:
        """[n_tracked] angle minus reference, rad; the reference blended from the standing
        pose by ``ramp`` (0..1, ``GaitClock.ramp``)."""
        angles = np.array([ref.joints[j] for j in self.joints])
        return state.dof_pos[self._index] - (self._standing + ramp * (angles - self._standing))

    def track(self, state: SimState, previous: SimState, sim: Simulator, steps: int) -> Tracking:
        """The tracking kernels of the state after step ``steps`` (see the module table)."""
        ref = self.clock.reference(steps)
        scales = self.spec.scales
        pose = self.pose_error(state, ref, self.clock.ramp(steps))
        speed = state.dof_vel[self._index] - np.array([ref.joint_speeds[j] for j in self.joints])
        pitch, list_ = pelvis_pitch_list(state.pelvis_up, self.up, self.forward)
        height = float(state.pelvis_pos[self.up]) - ref.pelvis_height
        forward = float(state.pelvis_pos[self.forward] - previous.pelvis_pos[self.forward])
        turned = wrapped(self._heading_of(state) - self._heading(ref))
        errors = {
            "pose": float(pose @ pose),
            "joint_speed": float(speed @ speed),
            "feet": self._feet_error(state, ref, sim, turned),
            "pelvis_height": height**2,
            "pelvis_pitch": (pitch - ref.pelvis_pitch) ** 2 + (list_ - ref.pelvis_list) ** 2,
            "pelvis_speed": (forward / self.dt - ref.forward_speed) ** 2,
        }
        kernels = {
            f"imitate_{name}": float(np.exp(-getattr(scales, name) * err))
            for name, err in errors.items()
        }
        rms = float(np.sqrt(np.mean(pose**2)))
        return Tracking(kernels=kernels, pose_error_rad=rms)

    def kept(self, pose_error_rad: float) -> bool:
        """Whether the error is within ``max_pose_error_rad`` (always, if none is set)."""
        bound = self.spec.max_pose_error_rad
        return bound is None or pose_error_rad <= bound

    def weighted(self, kernels: dict[str, float]) -> dict[str, float]:
        weights = self.spec.weights
        return {
            t: getattr(weights, t.removeprefix("imitate_")) * kernels[t] for t in IMITATION_TERMS
        }

    def _feet_error(
        self, state: SimState, ref: MotionState, sim: Simulator, turned: float
    ) -> float:
        """Sum over feet of the squared distance (m^2) between the foot's offset from the
        pelvis and the reference's, compared in the reference's heading: the body's offsets
        turned back about the vertical by ``turned`` (rad, the body's heading minus the
        reference's)."""
        if not self._feet:
            return 0.0
        feet = sim.foot_positions()
        turn = self._about_up(-turned)
        total = 0.0
        for foot in self._feet:
            rel = turn @ (feet[foot] - state.pelvis_pos) - np.asarray(ref.feet_rel_pelvis[foot])
            total += float(rel @ rel)
        return total

    def _heading(self, ref: MotionState) -> float:
        """The reference pelvis's heading, rad (see :meth:`_yaw`)."""
        rot = pelvis_rotation(
            ref.pelvis_pitch, ref.pelvis_list, ref.pelvis_rotation, self.up, self.forward
        )
        return self._yaw(rot[:, 0])

    def _heading_of(self, state: SimState) -> float:
        """The body's pelvis's heading, rad (see :meth:`_yaw`)."""
        return self._yaw(state.pelvis_forward)

    def _yaw(self, pelvis_forward: np.ndarray) -> float:
        """The angle (rad, about OpenSim's up axis) from the world's forward axis to
        ``pelvis_forward`` ([3], world) projected on the ground."""
        x_os = self._to_os @ pelvis_forward
        return float(np.arctan2(-x_os[2], x_os[0]))

    def _about_up(self, yaw: float) -> np.ndarray:
        """[3, 3] world rotation by ``yaw`` rad about the up axis (OpenSim's sense)."""
        c, s = np.cos(yaw), np.sin(yaw)
        about_y = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
        return self._to_os.T @ about_y @ self._to_os
