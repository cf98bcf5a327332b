"""The gait clock of an env (a scene's ``task.clock``): the phase of a recorded gait played
with the episode's time, and the reference state there.

The phase runs with the env's time: ``phase = phase0 + t * tempo / period (mod 1)``, ``t``
the control steps taken times the control period; ``clock.tempo`` plays the motion faster or
slower (its speeds scale with it), times the episode's target speed over the scene's
``task.target_speed`` in a scene that draws one (``task.target_speed_range``). Each reset
draws ``phase0`` (uniform, or 0) and whether the episode is mirrored (left and right legs
swapped, p = 0.5). After a standing start :meth:`GaitClock.ramp` says how far (0..1) the
joint-target base, the clock's speed and the pose imitation compares with have blended from
standing into the motion (over ``clock.ramp_s``). With ``clock.lead_in``, an episode that
starts standing plays the lead-in motion first and cross-fades into the clock's
(``workers.motions.playback``: a run that starts as a walk); the phase, the reference and
(with ``speed_target_from_clock``) the target speed follow it. An imitation scene may start
an episode part way along that way in (:meth:`GaitClock.start_along_lead_in`); its clock
then reads ``start_s`` plus the time since.

What the clock gives the env: the observation's ``PHASE_OBS``, the joint-target base
(:meth:`GaitClock.target_base`), the target-speed term's target
(:meth:`GaitClock.target_speed`) and the reference state (:meth:`GaitClock.reference`) that
imitation (``workers.imitation``) tracks and recordings draw.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from gaitforge.workers.motions import Motion, MotionState, load_motion
from gaitforge.workers.motions.playback import CrossFade, faster
from gaitforge.workers.scenes import Scene

PHASE_OBS = ("phase_sin", "phase_cos", "phase_mirror")
"""The observation's clock entries: sin and cos of 2 pi phase, and +1 in a mirrored episode
(left and right swapped), -1 otherwise (a mirror image flips its sign)."""


class GaitClock:
    """The clock of one env: phase, mirroring, ramp from standing and the reference state."""

    def __init__(self, scene: Scene, dt: float) -> None:
        clock = scene.task.clock
        if clock is None:
            raise ValueError(f"scene {scene.name!r}: task.clock is not set")
        self.spec = clock
        self.motion: Motion = load_motion(scene.body, clock.motion)
        self.tempo = clock.tempo
        """the main motion's tempo this episode (:meth:`follow_target_speed`)"""
        self.nominal_speed = scene.task.target_speed
        """m/s: the target speed the scene's ``tempo`` is set for"""
        lead_in = clock.lead_in
        self.crossfade = (
            None
            if lead_in is None
            else CrossFade(
                lead=load_motion(scene.body, lead_in.motion),
                lead_tempo=lead_in.tempo,
                main=self.motion,
                main_tempo=clock.tempo,
                hold_s=lead_in.hold_s,
                crossfade_s=lead_in.crossfade_s,
            )
        )
        """The lead-in's cross-fade, played after a standing start (None: no lead-in)."""
        self.dt = dt
        self.phase0 = 0.0
        self.mirrored = False
        self.standing_start = True
        self.start_s = 0.0
        """s along the lead-in at which this episode started (0 unless it started inside it)"""
        self._last_reference: tuple[tuple, MotionState] | None = None

    # ---- the episode's start ------------------------------------------------------------

    def follow_target_speed(self, target_speed: float) -> None:
        """Play the main motion at ``clock.tempo`` times ``target_speed`` (m/s) over the
        scene's ``task.target_speed`` (the lead-in keeps its own tempo): the env calls it at
        each reset of a scene that draws its target speed, before :meth:`start`."""
        self.tempo = self.spec.tempo * target_speed / self.nominal_speed
        if self.crossfade is not None:
            self.crossfade = replace(self.crossfade, main_tempo=self.tempo)

    def start(self, rng: np.random.Generator, *, standing: bool = True) -> None:
        """Draw this episode's phase (uniform with ``random_phase``, else 0) and mirroring;
        ``standing``: the episode starts from the reset pose, the ramp and any lead-in
        playing from its start (else in the motion's state at the phase)."""
        self.phase0 = float(rng.uniform()) if self.spec.random_phase else 0.0
        self.mirrored = bool(rng.uniform() < 0.5) if self.spec.mirror else False
        self.standing_start = standing
        self.start_s = 0.0

    def start_at_phase_zero(self) -> None:
        """Start this episode at phase 0 (after :meth:`start`)."""
        self.phase0 = 0.0

    def start_along_lead_in(self, rng: np.random.Generator) -> None:
        """Start this episode (after :meth:`start` with ``standing=False``) at a uniform
        random time (s, > 0) along the lead-in, from the end of the standing ramp to the end
        of the cross-fade, at phase 0 at the standing start."""
        if self.crossfade is None:
            raise ValueError("task.clock.lead_in: not set; there is no lead-in to start along")
        first = max(self.spec.ramp_s, self.dt)
        last = max(first, self.crossfade.hold_s + self.crossfade.crossfade_s)
        self.start_s = float(rng.uniform(first, last))
        self.phase0 = 0.0

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
        ramp_s = self.spec.ramp_s
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
        ``clock.ramp_s`` has not yet passed (a start inside the lead-in is past it)."""
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
