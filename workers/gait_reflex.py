"""A spinal reflex gait controller after Song and Geyer (2015), on any wired body.

Written from the paper's circuitry as the 2019 Learn-to-Move baseline arranges it (its
nominal values are ``workers.scenes.reflex_parameters``' defaults). Each control step:

**Phases.** A leg is in contact while its foot carries more than ``CONTACT_LOAD`` body
weights. Touching down starts stance; lifting off starts swing, with the knee flexing. In
double support the leg further behind its aim prepares to swing (``swing_init``); the other
is plain stance. Swing moves through: flex the knee (until ``swing.knee_flexion``), hold it
(until the leg reaches its aim), stop the leg (once within ``swing.stop_before`` of its aim)
and hold the leg (once it starts to retract).

**Aims** (the "brain"). A leg's aim, forward of the trunk's long axis, is
``swing.leg_angle + swing.speed_gain * v_forward + swing.position_gain * ahead + lean``:
further forward at speed, and measured from the trunk; ``ahead`` is how far the pelvis is
ahead of the other (stance) foot, as the other leg's angle behind the vertical, rad. The
hip's adduction aim is ``swing.adduction + swing.lateral_gain * v_toward_the_other_side +
swing.lateral_position_gain * under - list``, with ``under`` how far the other foot is
toward this leg's side of its hip, as that leg's frontal angle from the vertical, rad.

**Excitations** (``[x]+`` = max(x, 0); ``load`` in body weights; ``F`` a group's tension over
its peak; ``kf`` knee flexion, ``a`` the leg angle, ``a*`` its aim, ``e = a* - a``):

- trunk in stance: HFL ``load [-kp (lean - lean*) - kd lean']+``, GLU ``load [kp (lean -
  lean*) + kd lean']+``, HAM ``ham_glu_share`` times GLU's; HAB and HAD the same on the
  frontal lean toward the leg;
- compliance in stance (plain stance, or preparing to swing times the other leg's unload):
  RF and VAS positive force feedback, VAS inhibited and BFSH excited as the knee nears
  straight (``[knee_offset - kf]+``); GAS and SOL positive force feedback in all stance;
- swing placement (swing, or preparing to swing times the other leg's load): HFL ``[kp e -
  kd a']+``, GLU ``[-kp e + kd a']+``, HAB and HAD toward the adduction aim;
- the knee in swing: BFSH flexes it early; while it is held RF brakes its flexion, and BFSH
  ``[(extension rate - knee_brake_rate) e]+``: it brakes an extension faster than that rate
  while the leg is short of its aim, and flexes the knee once the leg has passed it; HAM
  retracts a leg past its stop; once held, HFL and GLU hold the hip and VAS and BFSH the
  knee at their aims;
- the ankle: TA ``ta_kp [dorsiflexion* - dorsiflexion]+``, less ``sol_ta`` times SOL's
  feedback in stance.

Each group's excitation but HAB's and HAD's starts at ``PRE_STIM``; all are clipped to
[PRE_STIM, 1]; a muscle's excitation is the weighted sum of its groups'
(``workers.bodies.reflex_wiring``). No neural delays are modelled beyond the control period
(the baseline's 10 ms at 100 Hz). Where the baseline's code reads the hip's abduction speed
for the frontal leg angle, this reads its angle, as the paper's circuitry does; otherwise,
fed the same sensors, the groups' excitations and the phases equal the baseline's at its
nominal parameters (checked along a rollout, off the repository).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from gaitforge.workers.bodies.reflex_wiring import GROUPS, Wiring
from gaitforge.workers.scenes.reflex_parameters import INDEX
from gaitforge.workers.sim.base import Pose, SimState, Simulator
from gaitforge.workers.sim.pose import cross3

GRAVITY = 9.81
CONTACT_LOAD = 0.1
"""body weights on a foot that count as contact"""
START_CONTACT_M = 0.01
"""m between a foot's lowest point and the floor within which it starts in stance"""
PRE_STIM = 0.01
"""every group's excitation floor"""
_G = {g: i for i, g in enumerate(GROUPS)}


@dataclass
class _LegPhase:
    """Where one leg is in its cycle (Song and Geyer's control phases)."""

    contact: bool = False
    stance: bool = False
    swing_init: bool = False
    swing: bool = False
    flex_knee: bool = False
    hold_knee: bool = False
    stop_leg: bool = False
    hold_leg: bool = False

    def touch_down(self) -> None:
        self.stance, self.swing = True, False
        self.flex_knee = self.hold_knee = self.stop_leg = self.hold_leg = False

    def lift_off(self) -> None:
        self.stance = self.swing_init = False
        self.swing = self.flex_knee = True


@dataclass
class _Sensed:
    """One control step's sensory picture, per leg ``[2]`` (right, left) where indexed."""

    force: np.ndarray
    """[2, n_groups]: tension over peak force"""
    load: np.ndarray
    """[2]: body weights on each foot"""
    hip: np.ndarray
    """[2]: hip flexion, rad"""
    adduction: np.ndarray
    """[2]: hip adduction, rad (0 on a planar body)"""
    knee: np.ndarray
    """[2]: knee flexion, rad"""
    ankle: np.ndarray
    """[2]: dorsiflexion, rad"""
    knee_rate: np.ndarray
    """[2]: rad/s of knee flexion"""
    leg: np.ndarray
    """[2]: leg angle forward of the trunk's long axis, hip flexion - knee flexion / 2, rad"""
    leg_rate: np.ndarray
    """[2]: its rate, rad/s"""
    lean: float
    """rad the trunk leans forward (along its heading)"""
    lean_rate: float
    list_right: float
    """rad the trunk leans toward the right"""
    list_rate: float
    forward_speed: float
    """m/s of the pelvis along its heading"""
    right_speed: float
    """m/s of the pelvis toward its right"""


class GaitReflex:
    """Song and Geyer's circuitry on one simulator, with ``wiring`` for its body.

    Args:
        wiring: the body's wiring (its muscles, dofs and feet must be the simulator's).
        sim: the simulator it drives.
        control_hz: how often ``__call__`` is called, Hz.
        parameters: the parameter vector [n_parameters] (``reflex_parameters``).

    Raises:
        ValueError: the wiring names a muscle, dof or foot the simulator lacks.
    """

    def __init__(
        self, wiring: Wiring, sim: Simulator, control_hz: float, parameters: np.ndarray
    ) -> None:
        self.wiring = wiring
        self.sim = sim
        self.dt = 1.0 / control_hz
        self._values: dict[str, float] = {}
        self.parameters = parameters
        muscles = {name: i for i, name in enumerate(sim.muscle_names)}
        dofs = {name: i for i, name in enumerate(sim.dof_names)}
        n_mus = len(sim.muscle_names)
        self._sense = np.zeros((2, len(GROUPS), n_mus))
        """[leg, group, muscle]: a group's sensed tension is its muscles' weighted mean"""
        self._drive = np.zeros((2, len(GROUPS), n_mus))
        """[leg, group, muscle]: a muscle's excitation is its groups' weighted sum"""
        self._dofs = np.zeros((2, 4), dtype=int)
        self._signs = np.zeros((2, 4))
        """[leg, (hip flexion, adduction, knee, ankle)]: index and sign; sign 0 if absent"""
        missing: list[str] = []
        for k, leg in enumerate(wiring.legs()):
            for g, members in leg.groups.items():
                kept = {m: w for m, w in members.items() if m in muscles}
                missing += [f"muscle {m}" for m in members if m not in muscles]
                for muscle, weight in kept.items():
                    self._drive[k, _G[g], muscles[muscle]] = weight
                    self._sense[k, _G[g], muscles[muscle]] = weight / sum(kept.values())
            for j, dof in enumerate(leg.dofs.values()):
                if dof is None:
                    continue
                if dof.name not in dofs:
                    missing.append(f"dof {dof.name}")
                    continue
                self._dofs[k, j], self._signs[k, j] = dofs[dof.name], dof.sign
            if leg.foot not in sim.foot_names:
                missing.append(f"foot {leg.foot}")
        if missing:
            raise ValueError(
                f"reflex wiring of {wiring.body!r}: the scene's simulator has no {missing} "
                "(kept muscles, dofs and feet are the scene's keep)"
            )
        self._frontal = np.array([leg.frontal for leg in wiring.legs()])
        self._feet = [sim.foot_names.index(leg.foot) for leg in wiring.legs()]
        self._weight = GRAVITY * sim.report.mass
        up, forward = np.eye(3)[sim.up_axis], np.eye(3)[sim.forward_axis]
        self._axes = (up, forward, np.cross(forward, up))
        self._phases = (_LegPhase(), _LegPhase())
        self._previous: _Sensed | None = None

    @property
    def parameters(self) -> np.ndarray:
        """The parameter vector [n_parameters] (``reflex_parameters``)."""
        return self._parameters

    @parameters.setter
    def parameters(self, vector: np.ndarray) -> None:
        self._parameters = vector
        # by name, as Python floats: read several dozen times a control step
        self._values = {name: float(vector[i]) for name, i in INDEX.items()}

    # ---- episode ------------------------------------------------------------------------

    def start_pose(self, rng: np.random.Generator, noise: float, forward_speed: float) -> Pose:
        """The start pose the parameters choose (``pose.*``), lowered onto the floor, the
        right leg leading, moving forward at ``forward_speed`` m/s (0: from rest).
        ``noise`` (rad) is the most each chosen angle is moved, uniformly from ``rng`` (the
        scene's ``init_noise``)."""
        par = self._values
        jitter = rng.uniform(-noise, noise, 7)
        lean = par["pose.lean"] + jitter[0]
        coordinates: dict[str, float] = {}
        chosen = (("pose.lead_hip", "pose.lead_knee"), ("pose.trail_hip", "pose.trail_knee"))
        for k, (leg, (hip, knee)) in enumerate(zip(self.wiring.legs(), chosen, strict=True)):
            hip_flexion = par[hip] + lean + jitter[1 + 2 * k]
            coordinates[leg.hip_flexion.name] = leg.hip_flexion.sign * hip_flexion
            knee_flexion = max(0.0, par[knee] + jitter[2 + 2 * k])
            coordinates[leg.knee.name] = leg.knee.sign * knee_flexion
            ankle = par["pose.ankle"] + jitter[5 + k]
            coordinates[leg.ankle.name] = leg.ankle.sign * ankle
        # OpenSim's pelvis_tilt turns the pelvis backward: a forward lean is negative
        return Pose(
            coordinates=coordinates,
            pelvis_height=0.0,
            pelvis_pitch=-float(lean),
            forward_speed=forward_speed,
        )

    def reset(self, state: SimState) -> None:
        """Start the phases from ``state`` (after the simulator's reset and start pose): a
        leg whose foot's contact spheres come within ``START_CONTACT_M`` of the floor (at the
        start it may carry no load yet; a foot without spheres, MyoLeg's: one that carries
        any) is in stance, one in the air in swing with its knee flexing."""
        self._previous = None
        sensed = self._read(state)
        spheres = self.sim.contact_spheres()
        up = self.sim.up_axis
        for k, (leg, phase) in enumerate(zip(self.wiring.legs(), self._phases, strict=True)):
            phase.__init__()
            foot = spheres.get(leg.foot, np.zeros((0, 4)))
            if len(foot):
                phase.contact = bool((foot[:, up] - foot[:, 3]).min() < START_CONTACT_M)
            else:
                phase.contact = bool(sensed.load[k] > 0.0)
            if phase.contact:
                phase.touch_down()
            else:
                phase.lift_off()

    # ---- control ------------------------------------------------------------------------

    def __call__(self, state: SimState) -> np.ndarray:
        """Excitations [n_muscles] in [0, 1] for the coming control step, from ``state`` and
        the simulator's muscle sensors now."""
        s = self._read(state)
        self._previous = s
        aim, adduction_aim = self.aims(s)
        contact = s.load > CONTACT_LOAD
        behind = aim - s.leg
        starter = int(np.argmax(behind)) if contact.all() else -1
        groups = np.zeros((2, len(GROUPS)))
        for k, phase in enumerate(self._phases):
            self._advance(
                phase, bool(contact[k]), bool(contact[1 - k]), k == starter, s, k, float(aim[k])
            )
            groups[k] = self._leg(phase, s, k, float(aim[k]), float(adduction_aim[k]))
        excitation = np.einsum("lg,lgm->m", np.clip(groups, PRE_STIM, 1.0), self._drive)
        return np.clip(excitation, 0.0, 1.0)

    def aims(self, s: _Sensed) -> tuple[np.ndarray, np.ndarray]:
        """Each leg's placement aims from the sensed picture ``s``: its angle forward of the
        trunk's long axis [2] and its hip's adduction [2], rad (the module docstring's
        "brain"; each from the other leg's foot)."""
        par = self._values
        ahead = s.lean - s.leg  # [2] rad the pelvis is ahead of each foot
        aim = (
            par["swing.leg_angle"]
            + par["swing.speed_gain"] * s.forward_speed
            + par["swing.position_gain"] * ahead[::-1]
            + s.lean
        )
        side = np.array([1.0, -1.0])  # right, left
        lean = side * s.list_right  # [2] toward each leg
        toward_other = -side * s.right_speed
        under = s.adduction[::-1] - lean  # the other foot's frontal angle toward this side
        adduction = (
            par["swing.adduction"]
            + par["swing.lateral_gain"] * toward_other
            + par["swing.lateral_position_gain"] * under
            - lean
        )
        return aim, adduction

    def _advance(
        self,
        phase: _LegPhase,
        contact: bool,
        other_contact: bool,
        starts_swing: bool,
        s: _Sensed,
        k: int,
        aim: float,
    ) -> None:
        """Move ``phase`` on by this step's contacts and the leg's angles."""
        par = self._values
        if contact and not phase.contact:
            phase.touch_down()
        if phase.stance:
            phase.swing_init = starts_swing and other_contact
        if phase.contact and not contact:
            phase.lift_off()
        if phase.swing:
            if phase.flex_knee:
                if s.knee[k] > par["swing.knee_flexion"]:
                    phase.flex_knee, phase.hold_knee = False, True
            else:
                if phase.hold_knee and s.leg[k] > aim:
                    phase.hold_knee = False
                if s.leg[k] > aim - par["swing.stop_before"]:
                    phase.stop_leg = True
                if phase.stop_leg and s.leg_rate[k] < 0.0:
                    phase.hold_leg = True
        phase.contact = contact

    def _leg(
        self, phase: _LegPhase, s: _Sensed, k: int, aim: float, adduction_aim: float
    ) -> np.ndarray:
        """The eleven groups' excitations [n_groups] of leg ``k`` (before the floor and
        clip), with its aims (rad)."""
        par = self._values
        u = np.full(len(GROUPS), PRE_STIM)
        u[[_G["HAB"], _G["HAD"]]] = 0.0  # no floor added: only the clip's
        load, other_load = float(s.load[k]), float(s.load[1 - k])
        stance, init, swing = float(phase.stance), float(phase.swing_init), float(phase.swing)
        plain_stance = stance * (1.0 - init)
        compliant = plain_stance + init * (1.0 - other_load)
        placing = init * other_load + swing
        hold_leg, hold_knee = float(phase.hold_leg), float(phase.hold_knee)
        error = aim - s.leg[k]
        # trunk balance in stance
        trunk = par["trunk.lean"]
        hfl_trunk = (
            stance
            * load
            * max(
                -par["stance.hfl_trunk_kp"] * (s.lean - trunk)
                - par["stance.hfl_trunk_kd"] * s.lean_rate,
                0.0,
            )
        )
        glu_trunk = (
            stance
            * load
            * max(
                par["stance.glu_trunk_kp"] * (s.lean - trunk)
                + par["stance.glu_trunk_kd"] * s.lean_rate,
                0.0,
            )
        )
        # swing placement and the leg's hold
        hfl_leg = placing * max(
            par["swing.hfl_leg_kp"] * error - par["swing.hfl_leg_kd"] * s.leg_rate[k], 0.0
        )
        glu_leg = placing * max(
            -par["swing.glu_leg_kp"] * error + par["swing.glu_leg_kd"] * s.leg_rate[k], 0.0
        )
        knee_held = par["swing.knee_held"]
        hip_aim = aim + 0.5 * knee_held
        hip_error = hip_aim - s.hip[k]
        u[_G["HFL"]] += (
            hfl_trunk + hfl_leg + hold_leg * par["swing.hfl_hold_kp"] * max(hip_error, 0.0)
        )
        u[_G["GLU"]] += (
            glu_trunk + glu_leg + hold_leg * par["swing.glu_hold_kp"] * max(-hip_error, 0.0)
        )
        stop = aim - par["swing.stop_before"]
        ham_stop = float(phase.stop_leg) * par["swing.ham_stop_kp"] * max(s.leg[k] - stop, 0.0)
        u[_G["HAM"]] += par["stance.ham_glu_share"] * glu_trunk + ham_stop
        # knee
        knee, knee_rate = s.knee[k], s.knee_rate[k]
        near_straight = max(par["stance.knee_offset"] - knee, 0.0)
        u[_G["RF"]] += compliant * par["stance.rf_force"] * s.force[k, _G["RF"]] + hold_knee * (
            par["swing.rf_knee_kd"] * max(knee_rate, 0.0)
        )
        u[_G["VAS"]] += compliant * (
            par["stance.vas_force"] * s.force[k, _G["VAS"]]
            - par["stance.vas_knee_kp"] * near_straight
        ) + hold_leg * par["swing.vas_hold_kp"] * max(knee - knee_held, 0.0)
        flexing = init * other_load + float(phase.flex_knee)
        u[_G["BFSH"]] += (
            compliant * par["stance.bfsh_knee_kp"] * near_straight
            + flexing
            * max(
                par["swing.bfsh_flex_kd"] * s.leg_rate[k]
                + par["swing.bfsh_flex_kp"] * (par["swing.knee_flexion"] - knee),
                0.0,
            )
            + hold_knee
            * par["swing.bfsh_hold_kd"]
            * max((-knee_rate - par["swing.knee_brake_rate"]) * error, 0.0)
            + par["swing.bfsh_ham_gain"] * max(ham_stop - par["swing.bfsh_ham_offset"], 0.0)
            + hold_leg * par["swing.bfsh_knee_hold_kp"] * max(knee_held - knee, 0.0)
        )
        # ankle
        sol = stance * par["stance.sol_force"] * s.force[k, _G["SOL"]]
        u[_G["SOL"]] += sol
        u[_G["GAS"]] += stance * par["stance.gas_force"] * s.force[k, _G["GAS"]]
        u[_G["TA"]] += (
            par["ankle.ta_kp"] * max(par["ankle.dorsiflexion"] - s.ankle[k], 0.0)
            - stance * par["stance.sol_ta"] * sol
        )
        if self._frontal[k]:
            self._frontal_groups(u, s, k, stance * load, placing, adduction_aim)
        return u

    def _frontal_groups(
        self, u: np.ndarray, s: _Sensed, k: int, loaded: float, placing: float, aim: float
    ) -> None:
        """HAB and HAD of leg ``k`` into ``u``: trunk balance in stance (``loaded``: stance
        times load) and the adduction ``aim`` (rad) while placing the leg."""
        par = self._values
        side = 1.0 if k == 0 else -1.0
        lean, rate = side * s.list_right, side * s.list_rate
        error = lean - par["trunk.list"]
        past = s.adduction[k] - aim
        u[_G["HAB"]] += loaded * max(
            -par["stance.hab_trunk_kp"] * error - par["stance.hab_trunk_kd"] * rate, 0.0
        ) + placing * par["swing.hab_leg_kp"] * max(past, 0.0)
        u[_G["HAD"]] += loaded * max(
            par["stance.had_trunk_kp"] * error + par["stance.had_trunk_kd"] * rate, 0.0
        ) + placing * par["swing.had_leg_kp"] * max(-past, 0.0)

    # ---- sensing ------------------------------------------------------------------------

    def _read(self, state: SimState) -> _Sensed:
        _, force = self.sim.muscle_sensors()
        up, forward, right = self._heading(state)
        angles = state.dof_pos[self._dofs] * self._signs
        rates = state.dof_vel[self._dofs] * self._signs
        trunk_up = state.pelvis_up
        lean = float(np.arctan2(trunk_up @ forward, trunk_up @ up))
        list_right = float(np.arctan2(trunk_up @ right, trunk_up @ up))
        before = self._previous
        hip, knee = angles[:, 0], angles[:, 2]
        return _Sensed(
            force=self._sense @ force,
            load=state.foot_forces[self._feet] / self._weight,
            hip=hip,
            adduction=angles[:, 1],
            knee=knee,
            ankle=angles[:, 3],
            knee_rate=rates[:, 2],
            leg=hip - 0.5 * knee,
            leg_rate=rates[:, 0] - 0.5 * rates[:, 2],
            lean=lean,
            lean_rate=0.0 if before is None else (lean - before.lean) / self.dt,
            list_right=list_right,
            list_rate=0.0 if before is None else (list_right - before.list_right) / self.dt,
            forward_speed=float(state.pelvis_vel @ forward),
            right_speed=float(state.pelvis_vel @ right),
        )

    def _heading(self, state: SimState) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """World up, the pelvis's heading (its forward axis on the ground) and its right
        [3] each: the frame the trunk's lean and the pelvis's speeds are read in, as the
        vestibular sense reads them, so that a turn about the vertical does not mix the
        sagittal and frontal senses. World forward while the pelvis faces straight up or
        down."""
        up, forward, _ = self._axes
        heading = state.pelvis_forward - (state.pelvis_forward @ up) * up
        norm = float(np.linalg.norm(heading))
        if norm > 1e-6:
            forward = heading / norm
        return up, forward, cross3(forward, up)
