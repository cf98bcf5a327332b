"""The reflex gait controller's parameters: a named vector with defaults and bounds.

The defaults are Song and Geyer's nominal values as the 2019 Learn-to-Move baseline scales
them (its parameter multipliers at 1), the bounds that baseline's search space; angles in
rad, speeds in m/s. The two position gains of swing-leg placement (``swing.position_gain``,
``swing.lateral_position_gain``) are the paper's, which the baseline leaves out: they
default to 0, the baseline's controller, and the search may give them either sign. Knee
angles are flexion (0 straight), ankle angles dorsiflexion, hip angles flexion, leg angles
forward of the trunk's long axis (hip flexion less half the knee flexion). Gains: excitation
per rad (``_kp``), per rad/s (``_kd``), per unit of force over the maximum isometric force
(``_force``). ``pose.*`` is the start pose the optimiser may choose (the right leg leads).
CMA-ES (``learner.cmaes``) tunes within the bounds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

DEG = math.pi / 180.0


@dataclass(frozen=True)
class Parameter:
    """One parameter: its name, default, bounds (inclusive) and what it is."""

    name: str
    default: float
    low: float
    high: float
    meaning: str


def _gain(name: str, nominal: float, meaning: str) -> Parameter:
    """A gain searched from 0 to three times its nominal value."""
    return Parameter(name, nominal, 0.0, 3.0 * nominal, meaning)


PARAMETERS: tuple[Parameter, ...] = (
    # what the "brain" sets: targets
    Parameter("trunk.lean", 10 * DEG, 0.0, 60 * DEG, "sagittal trunk lean held in stance"),
    Parameter("trunk.list", 5 * DEG, 0.0, 10 * DEG, "frontal lean toward the stance leg held"),
    Parameter("swing.leg_angle", 15 * DEG, -25 * DEG, 55 * DEG, "leg aimed forward of vertical"),
    Parameter("swing.speed_gain", 2 * DEG, 0.0, 10 * DEG, "more leg angle per m/s of speed"),
    Parameter(
        "swing.position_gain",
        0.0,
        -1.0,
        1.0,
        "more leg angle per rad the pelvis is ahead of the stance foot (Song and Geyer's C_d)",
    ),
    Parameter("swing.stop_before", 5 * DEG, 0.0, 15 * DEG, "how far short of its aim it stops"),
    Parameter("swing.knee_flexion", 40 * DEG, 0.0, 100 * DEG, "knee flexion of early swing"),
    Parameter("swing.knee_held", 5 * DEG, 0.0, 110 * DEG, "knee flexion held in late swing"),
    Parameter("stance.knee_offset", 5 * DEG, 0.0, 25 * DEG, "knee flexion below which VAS stops"),
    Parameter("ankle.dorsiflexion", 10 * DEG, -30 * DEG, 30 * DEG, "dorsiflexion TA holds"),
    Parameter("swing.adduction", -10 * DEG, -30 * DEG, 30 * DEG, "hip adduction aimed at"),
    Parameter("swing.lateral_gain", 10 * DEG, 0.0, 30 * DEG, "more adduction per m/s sideways"),
    Parameter(
        "swing.lateral_position_gain",
        0.0,
        -1.0,
        1.0,
        "more adduction per rad the stance foot is under the body (its frontal C_d)",
    ),
    # stance: trunk balance (HFL, GLU, HAM; HAB, HAD)
    _gain("stance.hfl_trunk_kp", 2.0, "HFL against trunk lean behind its target"),
    _gain("stance.hfl_trunk_kd", 1.0, "HFL against trunk lean rate"),
    _gain("stance.glu_trunk_kp", 2.0, "GLU against trunk lean ahead of its target"),
    _gain("stance.glu_trunk_kd", 0.5, "GLU against trunk lean rate"),
    _gain("stance.ham_glu_share", 1.0, "HAM's share of GLU's trunk excitation"),
    _gain("stance.hab_trunk_kp", 10.0, "HAB against frontal lean away from the leg"),
    _gain("stance.hab_trunk_kd", 1.0, "HAB against frontal lean rate"),
    _gain("stance.had_trunk_kp", 2.0, "HAD against frontal lean toward the leg"),
    _gain("stance.had_trunk_kd", 0.3, "HAD against frontal lean rate"),
    # stance: leg compliance and knee protection
    _gain("stance.rf_force", 0.3, "RF positive force feedback"),
    _gain("stance.vas_force", 1.0, "VAS positive force feedback"),
    _gain("stance.vas_knee_kp", 2.0, "VAS inhibition as the knee nears straight"),
    _gain("stance.bfsh_knee_kp", 2.0, "BFSH as the knee nears straight"),
    _gain("stance.gas_force", 1.2, "GAS positive force feedback"),
    _gain("stance.sol_force", 1.2, "SOL positive force feedback"),
    _gain("stance.sol_ta", 0.5, "SOL's excitation inhibiting TA"),
    _gain("ankle.ta_kp", 2.0, "TA per rad of plantarflexion past its target"),
    # swing: leg placement, knee, retraction
    _gain("swing.hfl_leg_kp", 1.0, "HFL per rad the leg is behind its aim"),
    _gain("swing.hfl_leg_kd", 0.1, "HFL per rad/s the leg retracts"),
    _gain("swing.glu_leg_kp", 1.0, "GLU per rad the leg is ahead of its aim"),
    _gain("swing.glu_leg_kd", 0.1, "GLU per rad/s the leg swings forward"),
    _gain("swing.hfl_hold_kp", 1.0, "HFL holding the hip at the end of swing"),
    _gain("swing.glu_hold_kp", 0.5, "GLU holding the hip at the end of swing"),
    _gain("swing.ham_stop_kp", 2.0, "HAM per rad the leg is past its stop"),
    _gain("swing.rf_knee_kd", 0.1, "RF braking knee flexion while the knee is held"),
    _gain("swing.vas_hold_kp", 0.3, "VAS extending the knee to its held flexion"),
    _gain("swing.bfsh_flex_kp", 2.0, "BFSH flexing the knee in early swing"),
    _gain("swing.bfsh_flex_kd", 0.2, "BFSH per rad/s the leg swings forward, early swing"),
    _gain("swing.bfsh_hold_kd", 1.0, "BFSH braking knee extension before the leg's aim"),
    Parameter(
        "swing.knee_brake_rate",
        175 * DEG,
        155 * DEG,
        180 * DEG,
        "knee extension rate (rad/s) above which BFSH brakes it while the knee is held",
    ),
    _gain("swing.bfsh_ham_gain", 2.0, "BFSH with HAM's retraction excitation"),
    _gain("swing.bfsh_ham_offset", 0.3, "HAM retraction excitation below which BFSH is quiet"),
    _gain("swing.bfsh_knee_hold_kp", 2.0, "BFSH flexing the knee to its held flexion"),
    _gain("swing.hab_leg_kp", 2.0, "HAB per rad the hip is adducted past its aim"),
    _gain("swing.had_leg_kp", 2.0, "HAD per rad the hip is abducted short of its aim"),
    # the start pose
    Parameter("pose.lean", 0.0, -0.1, 0.3, "trunk lean at the start (forward +)"),
    Parameter("pose.lead_hip", 0.0, -0.2, 0.6, "leading (right) hip flexion at the start"),
    Parameter("pose.trail_hip", 0.0, -0.5, 0.3, "trailing (left) hip flexion at the start"),
    Parameter("pose.lead_knee", 0.05, 0.0, 0.8, "leading knee flexion at the start"),
    Parameter("pose.trail_knee", 0.05, 0.0, 0.8, "trailing knee flexion at the start"),
    Parameter("pose.ankle", 0.0, -0.2, 0.3, "both ankles' dorsiflexion at the start"),
)
NAMES = tuple(p.name for p in PARAMETERS)
DEFAULTS = np.array([p.default for p in PARAMETERS])
LOWER = np.array([p.low for p in PARAMETERS])
UPPER = np.array([p.high for p in PARAMETERS])
INDEX = {name: i for i, name in enumerate(NAMES)}


def parameter_vector(values: dict[str, float] | None = None) -> np.ndarray:
    """The defaults [n_parameters] with ``values`` by name in their place.

    Raises:
        ValueError: an unknown name, or a value outside its bounds.
    """
    vector = DEFAULTS.copy()
    for name, value in (values or {}).items():
        if name not in INDEX:
            raise ValueError(f"reflex parameter {name!r}: unknown; the parameters are {NAMES}")
        spec = PARAMETERS[INDEX[name]]
        if not spec.low - 1e-12 <= value <= spec.high + 1e-12:
            raise ValueError(
                f"reflex parameter {name!r}: {value} is outside [{spec.low}, {spec.high}]"
            )
        vector[INDEX[name]] = value
    return vector


def parameter_values(vector: np.ndarray) -> dict[str, float]:
    """``vector`` [n_parameters] by name, clipped to the bounds."""
    clipped = np.clip(vector, LOWER, UPPER)
    return {name: float(v) for name, v in zip(NAMES, clipped, strict=True)}
