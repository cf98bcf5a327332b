"""Imitation of a recorded gait in an env (a scene's ``task.imitate``), DeepMimic-style.

The gait phase runs with the env's time: ``phase = phase0 + t * tempo / period (mod 1)``,
``t`` the control steps taken times the control period; ``imitate.tempo`` plays the motion
faster or slower (its speeds scale with it), times the episode's target speed over the
scene's ``task.target_speed`` in a scene that draws one (``task.target_speed_range``). Each
reset draws ``phase0`` (uniform, or 0) and whether the episode is mirrored (left and right
legs swapped, p = 0.5), and starts the body in the reference state there (joint angles plus
uniform noise, their speeds, pelvis height, pitch, list, rotation and their rates, forward
and vertical speed; ``Simulator.set_pose``); or, with ``init.start: standing`` or in a
fraction ``init.standing_fraction`` of episodes, in the body's standing reset pose, and then
:meth:`Imitation.ramp` says how far (0..1) the joint-target base, and the pose the pose term
and ``max_pose_error_rad`` compare with, have blended from standing into the motion (over
``init.ramp_s``). With ``imitate.lead_in``, an
episode that starts standing plays the lead-in motion first and cross-fades into the scene's
(``workers.motions.playback``: a run that starts as a walk); the phase, the reference and
(with ``speed_target_from_clock``) the target speed of the ``target_speed`` term follow it.
In a fraction ``init.lead_in_fraction`` of episodes the body starts part way along that way
in, in the faded reference state at a random time ``start_s`` past the ramp, and the
episode's clock reads ``start_s`` plus the time since (reference state initialisation along
the fade).

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

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from gaitforge.workers.bodies.topology import topology_for
from gaitforge.workers.motions import Motion, MotionState, load_motion
from gaitforge.workers.motions.playback import CrossFade, faster
from gaitforge.workers.scenes import Scene
from gaitforge.workers.scenes.imitate import IMITATION_TERMS, Imitate, tracked_joints
from gaitforge.workers.sim.base import Pose, SimState, Simulator
from gaitforge.workers.sim.pose import opensim_to_world, pelvis_pitch_list, pelvis_rotation

PHASE_OBS = ("phase_sin", "phase_cos", "phase_mirror")
"""The observation's imitation entries: sin and cos of 2 pi phase, and +1 in a mirrored
episode (left and right swapped), -1 otherwise (a mirror image flips its sign)."""


@dataclass(frozen=True)
class Tracking:
    """One step's tracking: unweighted kernels by term name, RMS pose error (rad)."""

    kernels: dict[str, float]
    pose_error_rad: float


class Imitation:
    """The imitation side of one env: phase, reference, reset pose and tracking terms."""

    def __init__(self, scene: Scene, sim: Simulator, dt: float) -> None:
        imitate = scene.task.imitate
        if imitate is None:
            raise ValueError(f"scene {scene.name!r}: task.imitate is not set")
        self.spec: Imitate = imitate
        self.motion: Motion = load_motion(scene.body, imitate.motion)
        self.tempo = imitate.tempo
        """the main motion's tempo this episode (:meth:`follow_target_speed`)"""
        self.nominal_speed = scene.task.target_speed
        """m/s: the target speed the scene's ``tempo`` is set for"""
        lead_in = imitate.lead_in
        self.crossfade = (
            None
            if lead_in is None
            else CrossFade(
                lead=load_motion(scene.body, lead_in.motion),
                lead_tempo=lead_in.tempo,
                main=self.motion,
                main_tempo=imitate.tempo,
                hold_s=lead_in.hold_s,
                crossfade_s=lead_in.crossfade_s,
            )
        )
        """The lead-in's cross-fade, played after a standing start (None: no lead-in)."""
        topology = topology_for(scene.body)
        self.joints = tracked_joints(imitate, scene.body, scene.keep.joints, topology)
        self._index = np.array([sim.dof_names.index(j) for j in self.joints], dtype=int)
        self._standing = np.array([topology.dof_defaults[j] for j in self.joints])
        self._feet = [f for f in sim.foot_names if f in self.motion.feet]
        self.dt = dt
        self.up, self.forward = sim.up_axis, sim.forward_axis
        self._to_os = opensim_to_world(self.up, self.forward).T
        self._turns = self.motion.body != "gait2d"  # 3-D: heading may differ
        self.phase0 = 0.0
        self.mirrored = False
        self.standing_start = False
        self.start_s = 0.0
        """s along the lead-in at which this episode started (0 unless it started inside it)"""
        self._last_reference: tuple[tuple, MotionState] | None = None

    # ---- phase and reference ----------------------------------------------------------

    def _fading(self) -> CrossFade | None:
        """The lead-in's cross-fade if this episode plays it (it started standing, or
        inside the lead-in)."""
        return self.crossfade if self.standing_start or self.start_s > 0.0 else None

    def _clock_s(self, steps: int) -> float:
        """s on the episode's clock after ``steps`` control steps (from ``start_s``)."""
        return self.start_s + steps * self.dt

    def _phase_at(self, clock_s: float) -> float:
        """Phase in [0, 1) at ``clock_s`` s on the episode's clock."""
        if fade := self._fading():
            return (self.phase0 + fade.cycles(clock_s)) % 1.0
        # start_s is 0 unless the lead-in fades: the clock reads the time played
        return (self.phase0 + clock_s * self.tempo / self.motion.period_s) % 1.0

    def _motion_at(self, clock_s: float) -> MotionState:
        """The motion (faded from the lead-in, at ``tempo``, not mirrored) at ``clock_s``."""
        if fade := self._fading():
            return fade.at(clock_s, self.phase0)
        return faster(self.motion.at(self._phase_at(clock_s)), self.tempo)

    def _ramp_at(self, clock_s: float) -> float:
        """:meth:`ramp` at ``clock_s`` s on the episode's clock."""
        ramp_s = self.spec.init.ramp_s
        if not self.standing_start or ramp_s <= 0.0:
            return 1.0
        return min(1.0, clock_s / ramp_s)

    def phase(self, steps: int) -> float:
        """Phase in [0, 1) after ``steps`` control steps of this episode."""
        return self._phase_at(self._clock_s(steps))

    def reference(self, steps: int) -> MotionState:
        """The reference after ``steps`` control steps (mirrored if the episode is; speeds
        times ``tempo``; cross-faded from the lead-in after a standing start or a start
        inside the lead-in). A step asks for it twice (the targets' base, then tracking): the
        last one is kept."""
        key = (steps, self.phase0, self.mirrored, self.standing_start, self.start_s, self.tempo)
        if self._last_reference is not None and self._last_reference[0] == key:
            return self._last_reference[1]
        state = self._motion_at(self._clock_s(steps))
        if self.mirrored:
            state = self.motion.mirrored_state(state)
        self._last_reference = (key, state)
        return state

    def ramp(self, steps: int) -> float:
        """How far (0..1) the joint targets' base has blended from the standing pose into the
        motion's after ``steps`` control steps: 1 unless this episode started standing and
        ``init.ramp_s`` has not yet passed (a start inside the lead-in is past it)."""
        return self._ramp_at(self._clock_s(steps))

    def target_speed(self, steps: int, task_target: float | None) -> float | None:
        """The ``target_speed`` term's target (m/s) after ``steps`` steps: ``task_target``, or
        with ``speed_target_from_clock`` the smaller of it and the reference's forward speed
        times :meth:`ramp` (from standing into the motion, faded from the lead-in)."""
        if task_target is None or not self.spec.speed_target_from_clock:
            return task_target
        clock_s = self._clock_s(steps)
        speed = self._motion_at(clock_s).forward_speed * self._ramp_at(clock_s)
        return min(task_target, speed)

    def target_base(
        self, steps: int, dofs: Sequence[str], standing: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Joint-target actions' base after ``steps`` control steps, for ``dofs`` [n_dofs]:
        the reference's angles (rad) and speeds (rad/s) where it has them, else ``standing``
        [n_dofs] and 0, blended from ``standing`` (speeds from 0) by :meth:`ramp`."""
        ref = self.reference(steps)
        angles = np.array([ref.joints.get(d, q) for d, q in zip(dofs, standing, strict=True)])
        speeds = np.array([ref.joint_speeds.get(d, 0.0) for d in dofs])
        blend = self.ramp(steps)
        return standing + blend * (angles - standing), blend * speeds

    def observe(self, steps: int) -> list[float]:
        """``PHASE_OBS`` after ``steps`` steps."""
        angle = 2.0 * np.pi * self.phase(steps)
        return [float(np.sin(angle)), float(np.cos(angle)), 1.0 if self.mirrored else -1.0]

    # ---- reference state initialisation ----------------------------------------------

    def follow_target_speed(self, target_speed: float) -> None:
        """Play the scene's main motion at ``imitate.tempo`` times ``target_speed`` (m/s)
        over the scene's ``task.target_speed`` (the lead-in keeps its own tempo): the env
        calls it at each reset of a scene that draws its target speed, before
        :meth:`start`."""
        self.tempo = self.spec.tempo * target_speed / self.nominal_speed
        if self.crossfade is not None:
            self.crossfade = replace(self.crossfade, main_tempo=self.tempo)

    def start(self, rng: np.random.Generator) -> Pose | None:
        """Draw this episode's phase, mirroring and start; the pose to start it from (None
        for a standing start: the simulator's reset pose)."""
        init = self.spec.init
        self.phase0 = float(rng.uniform()) if init.random_phase else 0.0
        self.mirrored = bool(rng.uniform() < 0.5) if init.mirror else False
        fraction = init.standing_fraction
        mixed_standing = fraction > 0.0 and bool(rng.uniform() < fraction)
        self.standing_start = init.start == "standing" or mixed_standing
        self.start_s = 0.0
        # of the episodes not standing, a share lead_in_fraction / (1 - fraction) starts
        # inside the lead-in: lead_in_fraction of all
        inside_lead_in = not self.standing_start and init.lead_in_fraction > 0.0
        if inside_lead_in and rng.uniform() * (1.0 - fraction) < init.lead_in_fraction:
            self.start_s = self._lead_in_start_s(rng)
        if mixed_standing or self.start_s > 0.0:
            self.phase0 = 0.0
        if self.standing_start:
            return None
        noise = rng.uniform(-init.noise, init.noise, len(self.joints))
        return self.pose_of(self.reference(0), noise)

    def _lead_in_start_s(self, rng: np.random.Generator) -> float:
        """A uniform random time (s, > 0) along the lead-in from the end of the standing ramp
        to the end of the cross-fade."""
        assert self.crossfade is not None  # the scene's validation ties the fraction to it
        first = max(self.spec.init.ramp_s, self.dt)
        last = max(first, self.crossfade.hold_s + self.crossfade.crossfade_s)
        return float(rng.uniform(first, last))

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
        pose by ``ramp`` (0..1, :meth:`ramp`)."""
        angles = np.array([ref.joints[j] for j in self.joints])
        return state.dof_pos[self._index] - (self._standing + ramp * (angles - self._standing))

    def track(self, state: SimState, previous: SimState, sim: Simulator, steps: int) -> Tracking:
        """The tracking kernels of the state after step ``steps`` (see the module table)."""
        ref = self.reference(steps)
        scales = self.spec.scales
        pose = self.pose_error(state, ref, self.ramp(steps))
        speed = state.dof_vel[self._index] - np.array([ref.joint_speeds[j] for j in self.joints])
        pitch, list_ = pelvis_pitch_list(state.pelvis_up, self.up, self.forward)
        height = float(state.pelvis_pos[self.up]) - ref.pelvis_height
        forward = float(state.pelvis_pos[self.forward] - previous.pelvis_pos[self.forward])
        errors = {
            "pose": float(pose @ pose),
            "joint_speed": float(speed @ speed),
            "feet": self._feet_error(state, ref, sim),
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

    def _feet_error(self, state: SimState, ref: MotionState, sim: Simulator) -> float:
        if not self._feet:
            return 0.0
        feet = sim.foot_positions()
        turn = np.eye(3)
        if self._turns:  # compare in the reference's heading: turn the body's by the difference
            turn = self._heading(ref) @ self._heading_of(sim).T
        total = 0.0
        for foot in self._feet:
            rel = turn @ (feet[foot] - state.pelvis_pos) - np.asarray(ref.feet_rel_pelvis[foot])
            total += float(rel @ rel)
        return total

    def _heading(self, ref: MotionState) -> np.ndarray:
        """[3, 3] world rotation about up by the reference pelvis's heading."""
        rot = pelvis_rotation(
            ref.pelvis_pitch, ref.pelvis_list, ref.pelvis_rotation, self.up, self.forward
        )
        return self._yaw(rot)

    def _heading_of(self, sim: Simulator) -> np.ndarray:
        q = sim.body_frames()["pelvis"].quaternion
        w, x, y, z = q
        rot = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
            ]
        )
        return self._yaw(rot)

    def _yaw(self, world_from_pelvis: np.ndarray) -> np.ndarray:
        """The rotation about the world's up axis that turns forward to the pelvis's forward
        axis projected on the ground."""
        x_os = self._to_os @ world_from_pelvis[:, 0]  # pelvis forward, OpenSim frame
        yaw = np.arctan2(-x_os[2], x_os[0])  # about OpenSim's Y (up)
        c, s = np.cos(yaw), np.sin(yaw)
        about_y = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
        to_world = self._to_os.T
        return to_world @ about_y @ self._to_os
