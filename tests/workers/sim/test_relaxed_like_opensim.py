"""Two MuJoCo options that make the relaxed body behave as OpenSim's, checked on
the body let go from its reset pose with every muscle's excitation at 0 (real MuJoCo and
OpenSim, 0.2 s):

- ``muscle_min_activation: 0.01``: OpenSim's Millard muscles never go below 0.01 activation,
  and that much active force (gait2d's vasti: 1 % of 9594 N) holds the relaxed knee straight;
  MuJoCo's at 0 let it buckle. With the floor MuJoCo's knee straightens as OpenSim's does.
- ``contact_solimp``: MuJoCo's contact impedance against depth (soft for the first
  centimetres, stiff past 3 cm), so the feet sink about as far as OpenSim's Hunt-Crossley
  spheres.
"""

from __future__ import annotations

import numpy as np
import pytest
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.sim import make_simulator
from gaitforge.workers.sim.mujoco.compile import compile_scene
from pydantic import ValidationError

SHELL = [0.2, 0.95, 0.03, 0.9, 2]


def _scene(**options) -> Scene:
    scene = load_scene("walk-2d+clock")
    return Scene.model_validate({**scene.model_dump(), **options})


def _let_go(scene: Scene, backend: str, seconds: float = 0.2) -> tuple[float, float]:
    """(right knee angle in degrees, pelvis height in m) after ``seconds`` relaxed."""
    sim = make_simulator(scene, backend)
    sim.reset(0)
    for _ in range(round(seconds / 0.02)):
        assert sim.step(np.zeros(len(sim.muscle_names)), 0.02).ok
    state = sim.state()
    knee = sim.dof_names.index("knee_angle_r")
    return float(np.degrees(state.dof_pos[knee])), float(state.pelvis_pos[sim.up_axis])


def test_with_opensims_least_activation_the_relaxed_knee_straightens_as_on_opensim() -> None:
    opensim_knee, _ = _let_go(_scene(), "opensim")
    bare_knee, _ = _let_go(_scene(), "mujoco")
    floor_knee, _ = _let_go(_scene(muscle_min_activation=0.01), "mujoco")
    assert opensim_knee > 5.0  # straightened past the standing pose's 0
    assert bare_knee < -5.0  # buckled
    assert floor_knee > 5.0, (opensim_knee, bare_knee, floor_knee)


def test_the_floor_holds_activations_and_starts_there() -> None:
    sim = make_simulator(_scene(muscle_min_activation=0.01), "mujoco")
    sim.reset(0)
    np.testing.assert_allclose(sim.state().activations, 0.01)
    sim.step(np.zeros(len(sim.muscle_names)), 0.2)
    np.testing.assert_allclose(sim.state().activations, 0.01, atol=1e-6)
    sim.step(np.ones(len(sim.muscle_names)), 0.2)
    assert sim.state().activations.min() > 0.9


def test_a_contact_soft_near_the_surface_sinks_the_pelvis_as_opensims() -> None:
    _, opensim_pelvis = _let_go(_scene(), "opensim")
    _, stiff_pelvis = _let_go(_scene(muscle_min_activation=0.01), "mujoco")
    _, shell_pelvis = _let_go(_scene(muscle_min_activation=0.01, contact_solimp=SHELL), "mujoco")
    assert abs(shell_pelvis - opensim_pelvis) < 0.01 < abs(stiff_pelvis - opensim_pelvis)
    model, _, _ = compile_scene(_scene(contact_solimp=SHELL))
    np.testing.assert_allclose(model.geom_solimp, np.tile(SHELL, (model.ngeom, 1)))


@pytest.mark.parametrize(
    ("field", "bad"),
    [
        ("muscle_min_activation", -0.01),
        ("muscle_min_activation", 0.2),
        ("contact_solimp", [0.95, 0.2, 0.03, 0.9, 2]),
        ("contact_solimp", [0.2, 0.95, 0.0, 0.9, 2]),
        ("contact_solimp", [0.2, 0.95, 0.03]),
    ],
)
def test_bad_values_name_the_field(field: str, bad) -> None:
    with pytest.raises(ValidationError, match=field):
        _scene(**{field: bad})
