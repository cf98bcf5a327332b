"""The scene option ``muscle_curves: millard``: MuJoCo's muscles with their active
force-length (``lmin``, ``lmax``) and force-velocity (``vmax``, ``fvmax``) curves fitted to
Millard 2012's, the OpenSim backend's muscle.

The fits are redone here against OpenSim's own curve objects (``opensim.
ActiveForceLengthCurve``, ``opensim.ForceVelocityCurve``: their defaults are those of the
backend's ``Millard2012EquilibriumMuscle``) and MuJoCo's own gain function; then a compiled
scene's soleus is posed short and long and pulled shortening and lengthening, and its
active force compared with Millard's curves.
"""

from __future__ import annotations

from collections.abc import Callable

import mujoco
import numpy as np
import opensim
import pytest
from gaitforge.workers.bodies import load_body
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.sim.mujoco.build import ACTIVE_RANGE, MUSCLE_RANGE
from gaitforge.workers.sim.mujoco.compile import compile_scene
from gaitforge.workers.sim.muscle_curves import (
    FORCE_LENGTH_FIT_RANGE,
    FORCE_VELOCITY_FIT_RANGE,
    MILLARD_ACTIVE_RANGE,
    MILLARD_FVMAX,
    MILLARD_VMAX_SCALE,
)

LENGTHS = np.linspace(*FORCE_LENGTH_FIT_RANGE, 111)
"""Normalised fibre lengths fitted."""
VELOCITIES = np.linspace(*FORCE_VELOCITY_FIT_RANGE, 61)
"""Fibre velocities fitted, in max contraction velocities (shortening negative)."""


def _millard_length(lengths: np.ndarray) -> np.ndarray:
    curve = opensim.ActiveForceLengthCurve()
    return np.array([curve.calcValue(float(x)) for x in lengths])


def _millard_velocity(velocities: np.ndarray) -> np.ndarray:
    curve = opensim.ForceVelocityCurve()
    return np.array([curve.calcValue(float(v)) for v in velocities])


def _mujoco(
    lengths: np.ndarray,
    velocities: np.ndarray,
    active_range: tuple[float, float],
    vmax: float,
    fvmax: float,
) -> np.ndarray:
    """MuJoCo's active force / isometric at optimal length of a unit muscle (L0 = 1 m,
    vmax in L0/s, ``lmin, lmax = active_range``) at each (length, velocity) pair."""
    params = np.array([*MUSCLE_RANGE, 1.0, 200.0, *active_range, vmax, 0.0, fvmax])
    lengthrange = np.array(MUSCLE_RANGE)
    return np.array(
        [
            -mujoco.mju_muscleGain(float(x), float(v), lengthrange, 1.0, params)
            for x, v in zip(lengths, velocities, strict=True)
        ]
    )


def _rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2)))


def _best(fit_error: Callable[[float, float], float], a: np.ndarray, b: np.ndarray) -> tuple:
    return min((fit_error(x, y), x, y) for x in a for y in b)[1:]


def test_the_force_length_fit_is_the_least_squares_one() -> None:
    target, still = _millard_length(LENGTHS), np.zeros_like(LENGTHS)

    def error(lmin: float, lmax: float) -> float:
        return _rms(_mujoco(LENGTHS, still, (lmin, lmax), 1.0, 1.2), target)

    lmin, lmax = _best(error, np.arange(0.15, 0.35, 0.01), np.arange(1.75, 2.0, 0.01))
    assert (lmin, lmax) == pytest.approx(MILLARD_ACTIVE_RANGE, abs=0.011)
    assert error(*MILLARD_ACTIVE_RANGE) < 0.06 < 0.14 < error(*ACTIVE_RANGE)


def test_the_force_velocity_fit_is_the_least_squares_one() -> None:
    target, optimal = _millard_velocity(VELOCITIES), np.ones_like(VELOCITIES)

    def error(vmax: float, fvmax: float) -> float:
        return _rms(_mujoco(optimal, VELOCITIES, ACTIVE_RANGE, vmax, fvmax), target)

    vmax, fvmax = _best(error, np.arange(0.5, 0.81, 0.01), np.arange(1.2, 1.41, 0.01))
    assert (vmax, fvmax) == pytest.approx((MILLARD_VMAX_SCALE, MILLARD_FVMAX), abs=0.011)
    assert error(MILLARD_VMAX_SCALE, MILLARD_FVMAX) < 0.06 < 0.12 < error(1.0, 1.2)


def _scene(curves: str) -> Scene:
    return load_scene("walk-2d", {"mujoco.muscle_curves": curves})


class _Soleus:
    """The right soleus of a compiled ``walk-2d``, moved by its ankle."""

    def __init__(self, curves: str) -> None:
        self.model, _, _ = compile_scene(_scene(curves))
        self.data = mujoco.MjData(self.model)
        m = self.model
        self.muscle = next(x for x in load_body("gait2d").muscles if x.name == "soleus_r")
        self.actuator = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, "soleus_r")
        self.tendon = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_TENDON, "soleus_r")
        joint = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "ankle_angle_r")
        self.ankle_q, self.ankle_v = m.jnt_qposadr[joint], m.jnt_dofadr[joint]
        low, high = m.actuator_lengthrange[self.actuator]
        self.optimal = (high - low) / (MUSCLE_RANGE[1] - MUSCLE_RANGE[0])  # l_opt cos(penn.)

    def active(self, ankle: float, fibre_velocity: float) -> tuple[float, float]:
        """(normalised fibre length, active force / peak isometric) at ankle angle ``ankle``
        (rad), the ankle turning so that the fibre moves at ``fibre_velocity`` max
        contraction velocities; the active force is activation 1's less activation 0's."""
        m, d = self.model, self.data
        d.qpos[:] = m.qpos0
        d.qpos[self.ankle_q] = ankle
        d.qvel[:] = 0.0
        d.qvel[self.ankle_v] = 1.0
        mujoco.mj_forward(m, d)
        tendon_per_ankle = float(d.ten_velocity[self.tendon])  # m/s per rad/s, dL/dq
        speed = fibre_velocity * self.muscle.max_contraction_velocity * self.optimal
        d.qvel[self.ankle_v] = speed / tendon_per_ankle
        forces = []
        for activation in (1.0, 0.0):
            d.act[:] = 0.0
            d.act[self.actuator] = activation
            mujoco.mj_forward(m, d)
            forces.append(-float(d.actuator_force[self.actuator]))
        length = (
            MUSCLE_RANGE[0]
            + (d.ten_length[self.tendon] - m.actuator_lengthrange[self.actuator, 0]) / self.optimal
        )
        return float(length), (forces[0] - forces[1]) / float(m.actuator_gainprm[self.actuator, 2])


@pytest.mark.parametrize("ankle", [-0.5, -0.4, 0.2, 0.3])  # fibre 0.57, 0.70, 1.41, 1.51 l_opt
def test_a_millard_scene_pulls_as_millards_force_length_curve(ankle: float) -> None:
    length, fitted = _Soleus("millard").active(ankle, 0.0)
    _, own = _Soleus("mujoco").active(ankle, 0.0)
    millard = float(_millard_length(np.array([length]))[0])
    assert fitted == pytest.approx(millard, abs=0.1)
    assert abs(fitted - millard) <= abs(own - millard)


@pytest.mark.parametrize("fibre_velocity", [-0.3, -0.2, -0.1, 0.1])
def test_a_millard_scene_pulls_as_millards_force_velocity_curve(fibre_velocity: float) -> None:
    def force_velocity(curves: str) -> float:
        soleus = _Soleus(curves)
        return soleus.active(0.0, fibre_velocity)[1] / soleus.active(0.0, 0.0)[1]

    millard = float(_millard_velocity(np.array([fibre_velocity]))[0])
    fitted, own = force_velocity("millard"), force_velocity("mujoco")
    assert fitted == pytest.approx(millard, abs=0.1)
    assert abs(fitted - millard) < abs(own - millard)


def test_only_the_active_force_changes() -> None:
    own, _, _ = compile_scene(load_scene("walk-2d"))
    fitted, _, _ = compile_scene(_scene("millard"))
    np.testing.assert_array_equal(fitted.actuator_gainprm[:, 4:6], [MILLARD_ACTIVE_RANGE] * own.nu)
    np.testing.assert_allclose(
        fitted.actuator_gainprm[:, 6], own.actuator_gainprm[:, 6] * MILLARD_VMAX_SCALE
    )
    assert np.all(fitted.actuator_gainprm[:, 8] == MILLARD_FVMAX)
    np.testing.assert_array_equal(
        fitted.actuator_gainprm[:, [0, 1, 2, 3, 7]], own.actuator_gainprm[:, [0, 1, 2, 3, 7]]
    )
    np.testing.assert_array_equal(fitted.actuator_biasprm, own.actuator_biasprm)
