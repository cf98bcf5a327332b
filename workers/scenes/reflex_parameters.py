"""The reflex gait controller's parameters: a named vector with defaults and bounds.

Units: gains on a sensed force are excitation per unit of force over the maximum isometric
force; gains on a sensed length, excitation per optimal fibre length; angle gains,
excitation per rad (and per rad/s); angles in rad, speeds in m/s. ``pose.*`` are the start
pose the optimiser may choose (from rest: zero speeds, both feet on the ground); the right
leg leads. The gains' defaults are of the magnitudes of Geyer and Herr (2010) and Song and
Geyer (2015), not their tuned values; the length offsets sit near gait14dof22musc's lengths
in quiet standing. CMA-ES (``learner.cmaes``) tunes within the bounds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Parameter:
    """One parameter: its name, default, bounds (inclusive) and what it is."""

    name: str
    default: float
    low: float
    high: float
    meaning: str


PARAMETERS: tuple[Parameter, ...] = (
    Parameter("pre_stim", 0.01, 0.0, 0.1, "every muscle's excitation floor"),
    Parameter("contact_load", 0.1, 0.02, 0.4, "foot load (body weights) that counts as stance"),
    # stance: leg compliance (M1) and knee protection (M2)
    Parameter("stance.sol_force", 1.2, 0.0, 3.0, "SOL positive force feedback"),
    Parameter("stance.gas_force", 1.1, 0.0, 3.0, "GAS positive force feedback"),
    Parameter("stance.vas_force", 1.15, 0.0, 3.0, "VAS positive force feedback"),
    Parameter("stance.glu_force", 0.2, 0.0, 2.0, "GLU positive force feedback"),
    Parameter("stance.ta_length", 1.1, 0.0, 4.0, "TA length feedback"),
    Parameter("stance.ta_length_offset", 1.0, 0.6, 1.3, "TA length above which it fires"),
    Parameter("stance.sol_ta", 0.3, 0.0, 2.0, "SOL force inhibiting TA"),
    Parameter("stance.knee_offset", 0.15, 0.0, 0.6, "knee flexion below which VAS is inhibited"),
    Parameter("stance.knee_stop", 2.0, 0.0, 8.0, "VAS inhibition per rad of knee overextension"),
    Parameter("stance.bfsh_knee_stop", 1.0, 0.0, 8.0, "BFSH per rad of knee overextension"),
    # stance: trunk balance (M3)
    Parameter("trunk.lean", 0.1, -0.2, 0.4, "sagittal trunk lean held in stance (forward +)"),
    Parameter("trunk.kp", 1.9, 0.0, 8.0, "hip torque for trunk lean error"),
    Parameter("trunk.kd", 0.2, 0.0, 2.0, "hip torque for trunk lean rate"),
    Parameter("trunk.ham_share", 0.65, 0.0, 1.5, "HAM's share of GLU's trunk excitation"),
    Parameter("trunk.list_kp", 1.0, 0.0, 8.0, "hip ab/adduction for frontal lean error"),
    Parameter("trunk.list_kd", 0.1, 0.0, 2.0, "hip ab/adduction for frontal lean rate"),
    # swing initiation in double support, trailing leg (M4)
    Parameter("swing_init.hfl", 0.25, 0.0, 1.0, "HFL added"),
    Parameter("swing_init.glu", 0.25, 0.0, 1.0, "GLU taken away"),
    Parameter("swing_init.rf", 0.1, 0.0, 1.0, "RF added"),
    Parameter("swing_init.bfsh", 0.1, 0.0, 1.0, "BFSH added"),
    Parameter(
        "swing_init.vas_load", 1.2, 0.0, 4.0, "VAS inhibition per body weight on the other leg"
    ),
    # swing: leg placement (M5)
    Parameter("swing.leg_angle", 0.3, 0.0, 0.7, "leg angle aimed at (forward of vertical)"),
    Parameter("swing.speed_gain", 0.1, -0.3, 0.5, "rad more leg angle per m/s of pelvis speed"),
    Parameter("swing.hip_kp", 1.0, 0.0, 6.0, "hip flexion per rad the leg is short of its aim"),
    Parameter("swing.hip_kd", 0.1, 0.0, 1.0, "hip damping per rad/s of leg angle rate"),
    Parameter("swing.hfl_length", 0.35, 0.0, 3.0, "HFL length feedback"),
    Parameter("swing.hfl_length_offset", 1.1, 0.7, 1.4, "HFL length above which it fires"),
    Parameter("swing.ham_length", 0.6, 0.0, 4.0, "HAM length feedback (late swing retraction)"),
    Parameter("swing.ham_length_offset", 1.0, 0.7, 1.3, "HAM length above which it fires"),
    Parameter("swing.knee_flexion", 0.8, 0.2, 1.4, "knee flexion aimed at early in swing"),
    Parameter("swing.knee_kp", 1.0, 0.0, 6.0, "knee excitation per rad off its aim"),
    Parameter("swing.knee_kd", 0.05, 0.0, 1.0, "knee damping per rad/s"),
    Parameter("swing.extend_before", 0.15, 0.0, 0.5, "rad short of the aim where the knee extends"),
    Parameter("swing.ta_length", 1.1, 0.0, 4.0, "TA length feedback (toe clearance)"),
    Parameter("swing.adduction", -0.05, -0.3, 0.2, "hip adduction aimed at"),
    Parameter("swing.lateral_gain", 0.2, -0.5, 1.0, "rad more abduction per m/s toward the leg"),
    Parameter("swing.adduction_kp", 1.0, 0.0, 6.0, "hip ab/adduction per rad off its aim"),
    Parameter("swing.adduction_kd", 0.1, 0.0, 1.0, "hip ab/adduction damping per rad/s"),
    # the start pose, from rest
    Parameter("pose.lean", 0.05, -0.1, 0.3, "trunk lean at the start (forward +)"),
    Parameter("pose.lead_hip", 0.2, -0.2, 0.6, "leading (right) hip flexion at the start"),
    Parameter("pose.trail_hip", -0.1, -0.5, 0.3, "trailing (left) hip flexion at the start"),
    Parameter("pose.lead_knee", 0.1, 0.0, 0.8, "leading knee flexion at the start"),
    Parameter("pose.trail_knee", 0.1, 0.0, 0.8, "trailing knee flexion at the start"),
    Parameter("pose.ankle", 0.05, -0.2, 0.3, "both ankles' dorsiflexion at the start"),
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
        if not spec.low <= value <= spec.high:
            raise ValueError(
                f"reflex parameter {name!r}: {value} is outside [{spec.low}, {spec.high}]"
            )
        vector[INDEX[name]] = value
    return vector


def parameter_values(vector: np.ndarray) -> dict[str, float]:
    """``vector`` [n_parameters] by name, clipped to the bounds."""
    clipped = np.clip(vector, LOWER, UPPER)
    return {name: float(v) for name, v in zip(NAMES, clipped, strict=True)}
