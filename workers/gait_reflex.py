"""A spinal reflex gait controller after Song and Geyer (2015), on any wired body.

Each leg is in stance while its foot carries more than ``contact_load`` body weights, else in
swing; in double support the leg further behind (smaller leg angle) prepares to swing. Each
control step every group of the leg (``workers.bodies.reflex_wiring.GROUPS``) gets an
excitation from delayed sensory feedback, then each muscle the weighted sum of its groups'.
With ``F`` a group's force over its maximum isometric force, ``L`` its fibre length over
the optimal one, ``[x]+`` = max(x, 0), ``load`` the foot's load in body weights and
``p.*`` the parameters (``workers.scenes.reflex_parameters``):

Stance (leg compliance, knee protection, trunk balance):
    SOL = S0 + p.stance.sol_force F_SOL
    GAS = S0 + p.stance.gas_force F_GAS
    TA  = S0 + p.stance.ta_length [L_TA - p.stance.ta_length_offset]+ - p.stance.sol_ta F_SOL
    VAS = S0 + p.stance.vas_force F_VAS - p.stance.knee_stop [knee_offset - knee]+ (extending)
    GLU = S0 + p.stance.glu_force F_GLU + load [p.trunk.kp (lean - p.trunk.lean)
                                                + p.trunk.kd lean_rate]+
    HFL = S0 + load [-(p.trunk.kp (lean - p.trunk.lean) + p.trunk.kd lean_rate)]+
    HAM = S0 + p.trunk.ham_share (GLU's trunk part)
    HAB = S0 + load [-(p.trunk.list_kp list + p.trunk.list_kd list_rate)]+
    HAD = S0 + load [+(p.trunk.list_kp list + p.trunk.list_kd list_rate)]+
    BFSH = S0 + p.stance.bfsh_knee_stop [knee_offset - knee]+
    ``list`` is the trunk's lean toward the leg's own side. The trailing leg in double
    support adds ``p.swing_init.*`` to HFL, RF and BFSH, takes it from GLU, and inhibits VAS
    by ``p.swing_init.vas_load`` times the other leg's load.

Swing (leg placement):
    aim  = p.swing.leg_angle + p.swing.speed_gain v_forward
    hip  = p.swing.hip_kp (aim - leg_angle) - p.swing.hip_kd leg_angle_rate
    HFL = S0 + [hip]+ + p.swing.hfl_length [L_HFL - p.swing.hfl_length_offset]+
    GLU = S0 + [-hip]+
    HAM = S0 + p.swing.ham_length [L_HAM - p.swing.ham_length_offset]+
    knee aim: p.swing.knee_flexion until the leg is within p.swing.extend_before of its
    aim, then straight; BFSH flexes toward it, RF extends, each by p.swing.knee_kp/kd
    TA  = S0 + p.swing.ta_length [L_TA - p.stance.ta_length_offset]+;  SOL = GAS = VAS = S0
    adduction aim = p.swing.adduction - p.swing.lateral_gain v_toward_own_side;
    HAD and HAB drive the hip toward it (p.swing.adduction_kp/kd)

The leg angle is the hip-to-ankle line's angle forward of the vertical, taken as hip
flexion minus the trunk's forward lean minus half the knee flexion (thigh and shank of
about equal length). Delays, as a nerve's length sets them: hip and trunk feedback
``SHORT_DELAY_S``, knee ``MEDIUM_DELAY_S``, ankle ``LONG_DELAY_S``, each rounded to whole
control steps.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np
from gaitforge.workers.bodies.reflex_wiring import GROUPS, Leg, Wiring
from gaitforge.workers.scenes.reflex_parameters import INDEX
from gaitforge.workers.sim.base import Pose, SimState, Simulator

SHORT_DELAY_S = 0.005
MEDIUM_DELAY_S = 0.010
LONG_DELAY_S = 0.020
GRAVITY = 9.81
_G = {g: i for i, g in enumerate(GROUPS)}


@dataclass
class _Sensed:
    """One control step's sensory picture (before delays)."""

    force: np.ndarray
    """[2, n_groups]: each leg's groups' force over maximum isometric force"""
    length: np.ndarray
    """[2, n_groups]: each leg's groups' fibre length over optimal length"""
    load: np.ndarray
    """[2]: each foot's load, body weights"""
    joints: np.ndarray
    """[2, 4]: each leg's hip flexion, hip adduction, knee flexion, dorsiflexion (rad)"""
    joint_rates: np.ndarray
    """[2, 4]: their rates, rad/s"""
    lean: float
    """rad the trunk leans forward of vertical"""
    list_right: float
    """rad the trunk leans toward the right"""
    lean_rate: float
    """rad/s (the change since the previous picture)"""
    list_rate: float
    """rad/s"""
    forward_speed: float
    """m/s of the pelvis forward"""
    right_speed: float
    """m/s of the pelvis toward the right"""


class GaitReflex:
    """Song and Geyer's circuitry on one simulator, with ``wiring`` for its body.

    Args:
        wiring: the body's wiring (its muscles and dofs must be kept by the scene).
        sim: the simulator it drives.
        control_hz: how often ``__call__`` is called, Hz.
        parameters: the parameter vector [n_parameters] (``parameters.parameter_vector``).

    Raises:
        ValueError: the wiring names a muscle, dof or foot the simulator lacks.
    """

    def __init__(
        self, wiring: Wiring, sim: Simulator, control_hz: float, parameters: np.ndarray
    ) -> None:
        self.wiring = wiring
        self.sim = sim
        self.dt = 1.0 / control_hz
        self.parameters = parameters
        muscles = {name: i for i, name in enumerate(sim.muscle_names)}
        dofs = {name: i for i, name in enumerate(sim.dof_names)}
        n_mus = len(sim.muscle_names)
        self._sense = np.zeros((2, len(GROUPS), n_mus))
        """[leg, group, muscle]: a group's sensed value is its muscles' weighted mean"""
        self._drive = np.zeros((2, len(GROUPS), n_mus))
        """[leg, group, muscle]: a muscle's excitation is its groups' weighted sum"""
        self._dof_index = np.zeros((2, 4), dtype=int)
        self._dof_sign = np.zeros((2, 4))
        self._frontal = np.zeros(2, dtype=bool)
        missing: list[str] = []
        for k, leg in enumerate(wiring.legs()):
            for g, members in leg.groups.items():
                for muscle, weight in members.items():
                    if muscle not in muscles:
                        missing.append(f"muscle {muscle}")
                        continue
                    self._drive[k, _G[g], muscles[muscle]] = weight
                total = sum(w for m, w in members.items() if m in muscles)
                for muscle, weight in members.items():
                    if muscle in muscles:
                        self._sense[k, _G[g], muscles[muscle]] = weight / total
            self._frontal[k] = leg.frontal
            for j, dof in enumerate(_leg_dofs(leg)):
                if dof is None:
                    continue
                if dof.name not in dofs:
                    missing.append(f"dof {dof.name}")
                    continue
                self._dof_index[k, j], self._dof_sign[k, j] = dofs[dof.name], dof.sign
            if leg.foot not in sim.foot_names:
                missing.append(f"foot {leg.foot}")
        if missing:
            raise ValueError(
                f"reflex wiring of {wiring.body!r}: the scene's simulator has no {missing} "
                "(kept muscles, dofs and feet are the scene's keep)"
            )
        self._feet = [sim.foot_names.index(leg.foot) for leg in wiring.legs()]
        self._weight = GRAVITY * sim.report.mass
        up, forward = np.eye(3)[sim.up_axis], np.eye(3)[sim.forward_axis]
        self._axes = (up, forward, np.cross(forward, up))
        steps = [max(0, round(d * control_hz) - 1) for d in (SHORT_DELAY_S, MEDIUM_DELAY_S)]
        self._short, self._medium = steps
        self._long = max(0, round(LONG_DELAY_S * control_hz) - 1)
        self._history: deque[_Sensed] = deque(maxlen=self._long + 1)

    # ---- episode ------------------------------------------------------------------------

    def reset(self) -> None:
        """Forget the sensory history (call after the simulator's reset and start pose)."""
        self._history.clear()

    def start_pose(self, rng: np.random.Generator, noise: float) -> Pose:
        """The start pose the parameters choose (``pose.*``), at rest, lowered onto the
        floor; the right leg leads. ``noise`` (rad) is the most each chosen angle is moved,
        uniformly at random from ``rng`` (the scene's ``init_noise``)."""
        p = self.parameters
        jitter = rng.uniform(-noise, noise, 7)
        lean = p[INDEX["pose.lean"]] + jitter[0]
        coordinates: dict[str, float] = {}
        chosen = (("pose.lead_hip", "pose.lead_knee"), ("pose.trail_hip", "pose.trail_knee"))
        for k, (leg, (hip, knee)) in enumerate(zip(self.wiring.legs(), chosen, strict=True)):
            hip_flexion = p[INDEX[hip]] + lean + jitter[1 + 2 * k]
            coordinates[leg.hip_flexion.name] = leg.hip_flexion.sign * hip_flexion
            knee_flexion = max(0.0, p[INDEX[knee]] + jitter[2 + 2 * k])
            coordinates[leg.knee.name] = leg.knee.sign * knee_flexion
            ankle = p[INDEX["pose.ankle"]] + jitter[5 + k]
            coordinates[leg.ankle.name] = leg.ankle.sign * ankle
        # OpenSim's pelvis_tilt turns the pelvis backward: a forward lean is negative
        return Pose(coordinates=coordinates, pelvis_height=0.0, pelvis_pitch=-float(lean))

    # ---- control ------------------------------------------------------------------------

    def __call__(self, state: SimState) -> np.ndarray:
        """Excitations [n_muscles] in [0, 1] for the coming control step, from ``state`` and
        the simulator's muscle sensors now."""
        self._history.append(self._read(state))
        short = self._delayed(self._short)
        medium = self._delayed(self._medium)
        long = self._delayed(self._long)
        stance = short.load > self.parameters[INDEX["contact_load"]]
        groups = np.zeros((2, len(GROUPS)))
        for k in range(2):
            other = 1 - k
            trailing = bool(stance[other]) and self._leg_angle(short, k) < self._leg_angle(
                short, other
            )
            if stance[k]:
                groups[k] = self._stance(k, short, medium, long, trailing)
            else:
                groups[k] = self._swing(k, short, medium, long)
        excitation = np.einsum("lg,lgm->m", groups, self._drive)
        return np.clip(excitation, 0.0, 1.0)

    def _stance(
        self,
        k: int,
        short: _Sensed,
        medium: _Sensed,
        long: _Sensed,
        trailing: bool,
    ) -> np.ndarray:
        p, P = self.parameters, INDEX
        s0 = p[P["pre_stim"]]
        u = np.full(len(GROUPS), s0)
        f_long, f_med, f_short = long.force[k], medium.force[k], short.force[k]
        u[_G["SOL"]] += p[P["stance.sol_force"]] * f_long[_G["SOL"]]
        u[_G["GAS"]] += p[P["stance.gas_force"]] * f_long[_G["GAS"]]
        u[_G["TA"]] += (
            p[P["stance.ta_length"]]
            * max(long.length[k, _G["TA"]] - p[P["stance.ta_length_offset"]], 0.0)
            - p[P["stance.sol_ta"]] * f_long[_G["SOL"]]
        )
        knee = medium.joints[k, 2]
        overextended = max(p[P["stance.knee_offset"]] - knee, 0.0)
        extending = medium.joint_rates[k, 2] < 0.0
        u[_G["VAS"]] += p[P["stance.vas_force"]] * f_med[_G["VAS"]]
        if extending:
            u[_G["VAS"]] -= p[P["stance.knee_stop"]] * overextended
        u[_G["BFSH"]] += p[P["stance.bfsh_knee_stop"]] * overextended
        load = min(float(short.load[k]), 1.5)
        trunk = p[P["trunk.kp"]] * (short.lean - p[P["trunk.lean"]]) + p[P["trunk.kd"]] * (
            short.lean_rate
        )
        u[_G["GLU"]] += p[P["stance.glu_force"]] * f_short[_G["GLU"]] + load * max(trunk, 0.0)
        u[_G["HFL"]] += load * max(-trunk, 0.0)
        u[_G["HAM"]] += p[P["trunk.ham_share"]] * load * max(trunk, 0.0)
        if self._frontal[k]:
            side = 1.0 if k == 0 else -1.0
            frontal = (
                p[P["trunk.list_kp"]] * side * short.list_right
                + p[P["trunk.list_kd"]] * side * short.list_rate
            )
            u[_G["HAB"]] += load * max(-frontal, 0.0)
            u[_G["HAD"]] += load * max(frontal, 0.0)
        if trailing:
            u[_G["HFL"]] += p[P["swing_init.hfl"]]
            u[_G["GLU"]] -= p[P["swing_init.glu"]]
            u[_G["RF"]] += p[P["swing_init.rf"]]
            u[_G["BFSH"]] += p[P["swing_init.bfsh"]]
            u[_G["VAS"]] -= p[P["swing_init.vas_load"]] * float(short.load[1 - k])
        return u

    def _swing(self, k: int, short: _Sensed, medium: _Sensed, long: _Sensed) -> np.ndarray:
        p, P = self.parameters, INDEX
        s0 = p[P["pre_stim"]]
        u = np.full(len(GROUPS), s0)
        aim = p[P["swing.leg_angle"]] + p[P["swing.speed_gain"]] * short.forward_speed
        angle = self._leg_angle(short, k)
        hip = p[P["swing.hip_kp"]] * (aim - angle) - p[P["swing.hip_kd"]] * self._leg_angle(
            short, k, rates=True
        )
        u[_G["HFL"]] += max(hip, 0.0) + p[P["swing.hfl_length"]] * max(
            short.length[k, _G["HFL"]] - p[P["swing.hfl_length_offset"]], 0.0
        )
        u[_G["GLU"]] += max(-hip, 0.0)
        u[_G["HAM"]] += p[P["swing.ham_length"]] * max(
            short.length[k, _G["HAM"]] - p[P["swing.ham_length_offset"]], 0.0
        )
        extend = angle > aim - p[P["swing.extend_before"]]
        knee_aim = 0.0 if extend else p[P["swing.knee_flexion"]]
        knee = (
            p[P["swing.knee_kp"]] * (knee_aim - medium.joints[k, 2])
            - p[P["swing.knee_kd"]] * medium.joint_rates[k, 2]
        )
        u[_G["BFSH"]] += max(knee, 0.0)
        u[_G["RF"]] += max(-knee, 0.0)
        u[_G["TA"]] += p[P["swing.ta_length"]] * max(
            long.length[k, _G["TA"]] - p[P["stance.ta_length_offset"]], 0.0
        )
        if self._frontal[k]:
            side = 1.0 if k == 0 else -1.0
            aim_add = p[P["swing.adduction"]] - p[P["swing.lateral_gain"]] * side * (
                short.right_speed
            )
            adduction = (
                p[P["swing.adduction_kp"]] * (aim_add - short.joints[k, 1])
                - p[P["swing.adduction_kd"]] * short.joint_rates[k, 1]
            )
            u[_G["HAD"]] += max(adduction, 0.0)
            u[_G["HAB"]] += max(-adduction, 0.0)
        return u

    # ---- sensing ------------------------------------------------------------------------

    def _read(self, state: SimState) -> _Sensed:
        length, force = self.sim.muscle_sensors()
        up, forward, right = self._axes
        trunk_up = state.pelvis_up
        joints = state.dof_pos[self._dof_index] * self._dof_sign
        joint_rates = state.dof_vel[self._dof_index] * self._dof_sign
        joints[~self._frontal, 1] = joint_rates[~self._frontal, 1] = 0.0
        lean = float(np.arctan2(trunk_up @ forward, trunk_up @ up))
        list_right = float(np.arctan2(trunk_up @ right, trunk_up @ up))
        before = self._history[-1] if self._history else None
        return _Sensed(
            force=self._sense @ force,
            length=self._sense @ length,
            load=state.foot_forces[self._feet] / self._weight,
            joints=joints,
            joint_rates=joint_rates,
            lean=lean,
            list_right=list_right,
            lean_rate=0.0 if before is None else (lean - before.lean) / self.dt,
            list_rate=0.0 if before is None else (list_right - before.list_right) / self.dt,
            forward_speed=float(state.pelvis_vel @ forward),
            right_speed=float(state.pelvis_vel @ right),
        )

    def _delayed(self, steps: int) -> _Sensed:
        """The picture ``steps`` control steps ago (the oldest kept at the episode's start)."""
        return self._history[max(0, len(self._history) - 1 - steps)]

    @staticmethod
    def _leg_angle(sensed: _Sensed, k: int, rates: bool = False) -> float:
        """rad the leg points forward of vertical (its rate, rad/s, with ``rates``)."""
        if rates:
            hip, _, knee, _ = sensed.joint_rates[k]
            return float(hip - sensed.lean_rate - 0.5 * knee)
        hip, _, knee, _ = sensed.joints[k]
        return float(hip - sensed.lean - 0.5 * knee)


def _leg_dofs(leg: Leg) -> tuple:
    return (leg.hip_flexion, leg.hip_adduction, leg.knee, leg.ankle)
