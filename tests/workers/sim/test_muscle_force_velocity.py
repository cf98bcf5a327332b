"""The scene option ``muscle_force_velocity: millard``: MuJoCo's muscles with ``vmax`` and
``fvmax`` fitted to Millard 2012's force-velocity curve, the OpenSim backend's muscle.

The fit is redone here against OpenSim's own curve object (``opensim.ForceVelocityCurve``,
its defaults are those of the backend's ``Millard2012EquilibriumMuscle``) and MuJoCo's own
gain function; then a compiled scene's soleus is pulled shortening and lengthening and its
active force compared with Millard's curve.
"""

from __future__ import annotations

import mujoco
import numpy as np
import opensim
import pytest
from gaitforge.workers.bodies import load_body
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.sim.mujoco_build import ACTIVE_RANGE, MUSCLE_RANGE
from gaitforge.workers.sim.mujoco_compile import compile_scene
from gaitforge.workers.sim.muscle_curves import (
    FORCE_VELOCITY_FIT_RANGE,
    MILLARD_FVMAX,
    MILLARD_VMAX_SCALE,
)

VELOCITIES = np.linspace(*FORCE_VELOCITY_FIT_RANGE, 61)
"""Fibre velocities fitted, in max contraction velocities (shortening negative)."""


def _millard(velocities: np.ndarray) -> np.ndarray:
    curve = opensim.ForceVelocityCurve()
    return np.array([curve.calcValue(float(v)) for v in velocities])


def _mujoco(velocities: np.ndarray, vmax: float, fvmax: float) -> np.ndarray:
    """MuJoCo's active force / isometric at optimal length, for a unit muscle (L0 = 1)."""
    params = np.array([*MUSCLE_RANGE, 1.0, 200.0, *ACTIVE_RANGE, vmax, 0.0, fvmax])
    lengthrange = np.array(MUSCLE_RANGE)
    return np.array(
        [-mujoco.mju_muscleGain(1.0, float(v), lengthrange, 1.0, params) for v in velocities]
    )


def _rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2)))


def test_the_constants_are_the_least_squares_fit_to_millard() -> None:
    target = _millard(VELOCITIES)
    grid = [
        (_rms(_mujoco(VELOCITIES, scale, fvmax), target), scale, fvmax)
        for scale in np.arange(0.50, 0.81, 0.01)
        for fvmax in np.arange(1.20, 1.41, 0.01)
    ]
    _, best_scale, best_fvmax = min(grid)
    assert best_scale == pytest.approx(MILLARD_VMAX_SCALE, abs=0.011)
    assert best_fvmax == pytest.approx(MILLARD_FVMAX, abs=0.011)
    fitted = _rms(_mujoco(VELOCITIES, MILLARD_VMAX_SCALE, MILLARD_FVMAX), target)
    own = _rms(_mujoco(VELOCITIES, 1.0, 1.2), target)
    assert fitted < 0.06 < 0.12 < own


def _scene(curve: str) -> Scene:
    return load_scene("walk-2d").model_copy(update={"muscle_force_velocity": curve})


def _soleus_force_velocity(curve: str, fibre_velocity: float) -> float:
    """Soleus's active force at ``fibre_velocity`` (max contraction velocities, shortening
    negative) over its active force at rest, on a compiled ``walk-2d`` at its default pose:
    the ankle turned at the speed that moves the tendon so, activation 1 and 0 told apart."""
    model, _, _ = compile_scene(_scene(curve))
    data = mujoco.MjData(model)
    muscle = next(m for m in load_body("gait2d").muscles if m.name == "soleus_r")
    actuator = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, muscle.name)
    tendon = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TENDON, muscle.name)
    ankle = model.jnt_dofadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "ankle_angle_r")]
    mujoco.mj_forward(model, data)
    jacobian = np.zeros((model.ntendon, model.nv))
    mujoco.mju_sparse2dense(
        jacobian, data.ten_J, model.ten_J_rownnz, model.ten_J_rowadr, model.ten_J_colind
    )
    low, high = model.actuator_lengthrange[actuator]
    optimal = (high - low) / (MUSCLE_RANGE[1] - MUSCLE_RANGE[0])  # L0: l_opt cos(pennation), m
    tendon_speed = fibre_velocity * muscle.max_contraction_velocity * optimal

    def active(speed: float) -> float:
        forces = []
        for activation in (1.0, 0.0):
            data.qvel[:] = 0.0
            data.qvel[ankle] = speed / jacobian[tendon, ankle]
            data.act[:] = 0.0
            data.act[actuator] = activation
            mujoco.mj_forward(model, data)
            forces.append(-float(data.actuator_force[actuator]))
        return forces[0] - forces[1]

    return active(tendon_speed) / active(0.0)


@pytest.mark.parametrize("fibre_velocity", [-0.3, -0.2, -0.1, 0.1])
def test_a_millard_scene_pulls_as_millards_curve(fibre_velocity: float) -> None:
    millard = float(_millard(np.array([fibre_velocity]))[0])
    fitted = _soleus_force_velocity("millard", fibre_velocity)
    own = _soleus_force_velocity("mujoco", fibre_velocity)
    assert fitted == pytest.approx(millard, abs=0.1)
    assert abs(fitted - millard) < abs(own - millard)


def test_the_option_is_mujocos_own_by_default() -> None:
    own, _, _ = compile_scene(load_scene("walk-2d"))
    fitted, _, _ = compile_scene(_scene("millard"))
    np.testing.assert_allclose(
        fitted.actuator_gainprm[:, 6], own.actuator_gainprm[:, 6] * MILLARD_VMAX_SCALE
    )
    assert np.all(fitted.actuator_gainprm[:, 8] == MILLARD_FVMAX)
    assert np.all(own.actuator_gainprm[:, 8] == pytest.approx(1.2))
    unchanged = [0, 1, 2, 3, 4, 5, 7]
    np.testing.assert_array_equal(
        fitted.actuator_gainprm[:, unchanged], own.actuator_gainprm[:, unchanged]
    )
    np.testing.assert_array_equal(fitted.actuator_biasprm, own.actuator_biasprm)
