"""The scene option ``muscle_passive: thelen``: MuJoCo's passive muscle force (``biasprm``'s
``lmax`` and ``fpmax``) fitted to Thelen 2003's curve over its whole strain, where the default
fits ``fpmax`` alone over the first part of it and is far softer beyond (gait2d's
gastrocnemius is stretched past that part when the knee is straight and the ankle bent up).

The fit is checked as the least-squares optimum on its grid; a compiled walk-2d's relaxed
gastrocnemius is posed long and its passive pull compared with Thelen's curve.
``muscle_passive: thelen-fibre`` fits the same curve of the pennated fibre's own length,
projected on the tendon (OpenSim's rigid-tendon muscle): checked against the parallelogram's
geometry, and as the same fit for an unpennated muscle.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from gaitforge.workers.bodies import load_body
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.sim.mujoco.build import ACTIVE_RANGE, MUSCLE_RANGE
from gaitforge.workers.sim.mujoco.compile import compile_scene
from gaitforge.workers.sim.muscle_curves import (
    WHOLE_STRAIN_POINTS,
    fit_mujoco_fpmax,
    fit_mujoco_passive_whole,
    mujoco_passive,
    thelen_passive,
    thelen_passive_on_tendon,
)

GASTROC = next(m for m in load_body("gait2d").muscles if m.name == "gastroc_r")


def _error(lmax: float, fpmax: float, strain: float, shape: float) -> float:
    lengths = np.linspace(1.0, 1.0 + strain, WHOLE_STRAIN_POINTS)
    return float(
        np.sum((mujoco_passive(lengths, lmax, fpmax) - thelen_passive(lengths, strain, shape)) ** 2)
    )


def test_the_fit_is_the_least_squares_one_on_its_grid() -> None:
    strain, shape = GASTROC.passive_fibre_strain, GASTROC.passive_shape
    lmax, fpmax = fit_mujoco_passive_whole(strain, shape)
    best = _error(lmax, fpmax, strain, shape)
    for other in (lmax - 0.05, lmax - 0.01, lmax + 0.01, lmax + 0.05):
        other_fpmax = fit_mujoco_fpmax(strain, shape, other, up_to=1.0, points=WHOLE_STRAIN_POINTS)
        assert best <= _error(other, other_fpmax, strain, shape)
    default = _error(
        ACTIVE_RANGE[1], fit_mujoco_fpmax(strain, shape, ACTIVE_RANGE[1]), strain, shape
    )
    assert best < 0.25 * default


def _relaxed_gastroc_pull(passive: str, ankle: float) -> tuple[float, float]:
    """(normalised fibre length, passive force / peak force) of a compiled walk-2d's relaxed
    right gastrocnemius, knee straight, ankle at ``ankle`` rad, nothing moving."""
    scene = load_scene("walk-2d", {"mujoco.muscle_passive": passive})
    m, _, _ = compile_scene(scene)
    d = mujoco.MjData(m)
    actuator = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, "gastroc_r")
    tendon = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_TENDON, "gastroc_r")
    joint = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "ankle_angle_r")
    d.qpos[:] = m.qpos0
    d.qpos[m.jnt_qposadr[joint]] = ankle
    d.act[:] = 0.0
    mujoco.mj_forward(m, d)
    low, high = m.actuator_lengthrange[actuator]
    optimal = (high - low) / (MUSCLE_RANGE[1] - MUSCLE_RANGE[0])
    length = MUSCLE_RANGE[0] + (d.ten_length[tendon] - low) / optimal
    return float(length), -float(d.actuator_force[actuator]) / float(
        m.actuator_gainprm[actuator, 2]
    )


@pytest.mark.parametrize("ankle", [0.0, 0.17])  # fibre about 1.47 and 1.64 l_opt
def test_a_thelen_scene_pulls_as_thelens_curve_where_the_default_is_soft(ankle: float) -> None:
    length, fitted = _relaxed_gastroc_pull("thelen", ankle)
    _, default = _relaxed_gastroc_pull("gait", ankle)
    thelen = float(
        thelen_passive(np.array([length]), GASTROC.passive_fibre_strain, GASTROC.passive_shape)[0]
    )
    assert length > 1.0 + 0.6 * GASTROC.passive_fibre_strain  # past the default's fitted part
    assert default < 0.85 * thelen  # the default is the softer here
    assert abs(fitted - thelen) < 0.6 * abs(default - thelen)  # about half the gap closed


def test_only_the_passive_force_changes() -> None:
    own, _, _ = compile_scene(load_scene("walk-2d"))
    fitted, _, _ = compile_scene(load_scene("walk-2d", {"mujoco.muscle_passive": "thelen"}))
    np.testing.assert_array_equal(fitted.actuator_gainprm, own.actuator_gainprm)
    changed = [5, 7]
    kept = [i for i in range(own.actuator_biasprm.shape[1]) if i not in changed]
    np.testing.assert_array_equal(fitted.actuator_biasprm[:, kept], own.actuator_biasprm[:, kept])
    assert np.all(fitted.actuator_biasprm[:, 5] != own.actuator_biasprm[:, 5])


def test_an_mjcf_body_is_refused_with_the_option_named() -> None:
    scene = load_scene("walk-3d", {"mujoco.muscle_passive": "thelen"})
    with pytest.raises(ValueError, match=r"muscle_passive 'thelen'.*myoleg"):
        compile_scene(scene)


def test_thelen_on_the_tendon_follows_the_pennated_fibre() -> None:
    """At MuJoCo's length 1 the fibre is at its optimal length; past it the fibre is shorter
    than MuJoCo's length (its height stays ``sin(pennation)``) and pulls along the tendon by
    ``cos`` of its angle; unpennated, it is Thelen's curve itself."""
    strain, shape, pennation = GASTROC.passive_fibre_strain, GASTROC.passive_shape, 0.3
    x = np.array([1.0, 1.2, 1.458])
    fibre = np.sqrt((x * np.cos(pennation)) ** 2 + np.sin(pennation) ** 2)
    np.testing.assert_allclose(fibre[0], 1.0)
    assert np.all(fibre[1:] < x[1:])
    expected = thelen_passive(fibre, strain, shape) * x * np.cos(pennation) / fibre
    np.testing.assert_allclose(
        thelen_passive_on_tendon(x, strain, shape, pennation) * np.cos(pennation), expected
    )
    np.testing.assert_allclose(
        thelen_passive_on_tendon(x, strain, shape, 0.0), thelen_passive(x, strain, shape)
    )


def test_the_fibre_fit_changes_only_the_pennated_muscles() -> None:
    """Compiled walk-2d: ``thelen-fibre`` equals ``thelen`` for gait2d's unpennated gluteus
    maximus and is the softer for the gastrocnemius (its fibre shorter than MuJoCo's length)
    at the standing gastrocnemius's 1.46."""

    def compiled(option: str) -> mujoco.MjModel:
        return compile_scene(load_scene("walk-2d", {"mujoco.muscle_passive": option}))[0]

    thelen, fibre = compiled("thelen"), compiled("thelen-fibre")

    def actuator(name: str) -> int:
        return mujoco.mj_name2id(thelen, mujoco.mjtObj.mjOBJ_ACTUATOR, name)

    glut, gastroc = actuator("glut_max_r"), actuator("gastroc_r")
    np.testing.assert_array_equal(fibre.actuator_biasprm[glut], thelen.actuator_biasprm[glut])
    pull = {
        name: mujoco_passive(np.array([1.458]), *m.actuator_biasprm[gastroc, [5, 7]])[0]
        for name, m in (("thelen", thelen), ("fibre", fibre))
    }
    assert pull["fibre"] < 0.95 * pull["thelen"]
