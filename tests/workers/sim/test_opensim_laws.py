"""MuJoCo's forces on OpenSim's laws: ``contact_model: hunt-crossley``
(``workers.sim.osim_laws.hunt_crossley``), ``joint_limits: opensim``
(``workers.sim.osim_laws.limit_springs``), ``muscle_curves`` and ``muscle_passive: opensim``
(``workers.sim.osim_laws.muscles``).

The laws are checked against real OpenSim, gait2d as ``opensim.build`` builds it, in states
set by hand: a heel sphere pressed into the floor while moving and turning, a knee past its
limit while moving, every muscle active in a bent, moving pose; then the options on a real
MuJoCo gait2d.
"""

from __future__ import annotations

import mujoco
import numpy as np
import opensim
import pytest
from gaitforge.workers.bodies import load_body
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.sim import make_simulator
from gaitforge.workers.sim.mujoco.compile import compile_scene
from gaitforge.workers.sim.osim_laws.hunt_crossley import hertz_coefficient, sphere_force
from gaitforge.workers.sim.osim_laws.limit_springs import limit_torque
from gaitforge.workers.sim.osim_laws.muscles import OpenSimMuscles
from pydantic import ValidationError

GAIT2D = load_body("gait2d")


def _scene(**options) -> Scene:
    scene = load_scene("walk-2d+clock")
    return Scene.model_validate({**scene.model_dump(), **options})


@pytest.fixture(scope="module")
def opensim_gait2d():
    """walk-2d+clock on OpenSim, reset by each test that uses it."""
    return make_simulator(_scene(), "opensim")


def _heel_on_opensim(sim, lift_m: float, speeds: dict[str, float]):
    """OpenSim's right heel sphere with the body lowered by ``-lift_m`` and the given
    coordinate speeds: (its depth m, its overlap middle's velocity [3] m/s, OpenSim's
    Hunt-Crossley force on it [3] N)."""
    sim.reset(0)
    state, coords = sim.osim_state, sim._coords
    lift = coords["pelvis_ty"]
    lift.setValue(state, lift.getValue(state) + lift_m, False)
    for name, speed in speeds.items():
        coords[name].setSpeedValue(state, speed)
    sim.model.realizeDynamics(state)
    sphere = opensim.ContactSphere.safeDownCast(sim.model.getContactGeometrySet().get("r_heel"))
    frame = sphere.getFrame()
    centre = frame.findStationLocationInGround(state, sphere.get_location()).to_numpy()
    depth = sphere.getRadius() - centre[1]
    middle = centre.copy()
    middle[1] = -0.5 * depth
    ground = sim.model.getGround()
    station = ground.findStationLocationInAnotherFrame(state, opensim.Vec3(*middle), frame)
    velocity = frame.findStationVelocityInGround(state, station).to_numpy()
    force = sim.model.getForceSet().get("contact_r_heel")
    labels, values = force.getRecordLabels(), force.getRecordValues(state)
    record = {labels.get(j): values.get(j) for j in range(labels.size())}
    on_heel = np.array([record[f"contact_r_heel.calcn_r.force.{a}"] for a in "XYZ"])
    return depth, velocity, on_heel


@pytest.mark.parametrize(
    ("lift_m", "speeds"),
    [
        (-0.02, {}),  # pressed in, at rest
        (-0.03, {"pelvis_ty": -0.2, "pelvis_tx": 0.05}),  # landing, slipping slowly
        (-0.02, {"pelvis_ty": 0.1, "pelvis_tx": 0.6, "ankle_angle_r": 3.0}),  # lifting, sliding
    ],
)
def test_the_heel_force_is_opensims_hunt_crossley(opensim_gait2d, lift_m, speeds) -> None:
    depth, velocity, opensim_force = _heel_on_opensim(opensim_gait2d, lift_m, speeds)
    assert depth > 0.005
    radius = next(s.radius for s in GAIT2D.contact_spheres if s.name == "r_heel")
    coefficient = hertz_coefficient(GAIT2D.contact.stiffness, radius)
    ours = sphere_force(depth, velocity, 1, coefficient, GAIT2D.contact)
    assert opensim_force[1] > 10.0  # it carries load
    np.testing.assert_allclose(ours, opensim_force, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize(("angle", "speed"), [(0.1, 0.0), (0.25, -0.5), (0.3, 1.0), (-2.5, -1.0)])
def test_the_knee_spring_is_opensims_coordinate_limit_force(opensim_gait2d, angle, speed) -> None:
    opensim_gait2d.reset(0)
    state = opensim_gait2d.osim_state
    knee = opensim_gait2d._coords["knee_angle_r"]
    knee.setValue(state, angle, False)
    knee.setSpeedValue(state, speed)
    opensim_gait2d.model.realizeDynamics(state)
    force = opensim_gait2d.model.getForceSet().get("knee_angle_r_limit")
    theirs = opensim.CoordinateLimitForce.safeDownCast(force).calcLimitForce(state)
    limit = next(d.limit for j in GAIT2D.joints for d in j.dofs if d.name == "knee_angle_r")
    assert limit_torque(angle, speed, limit) == pytest.approx(theirs, rel=1e-9, abs=1e-9)


def test_on_mujoco_mujocos_own_versions_are_taken_out() -> None:
    """The floor collides with no sphere, the limited joints have no MuJoCo limit, the
    muscles no MuJoCo force and their tendons no damping; the laws carry the body, and the
    muscles still start at their least activation."""
    scene = _scene(
        contact_model="hunt-crossley",
        joint_limits="opensim",
        muscle_min_activation=0.01,
        muscle_curves="opensim",
        muscle_passive="opensim",
    )
    model, _, _ = compile_scene(scene)
    floor = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    assert model.geom_conaffinity[floor] == 0
    knee = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "knee_angle_r")
    assert model.jnt_limited[knee] == 0
    assert np.abs(model.tendon_damping).max() == 0.0
    sim = make_simulator(scene, "mujoco")
    sim.reset(0)
    np.testing.assert_allclose(sim.state().activations, 0.01)
    for _ in range(10):  # 0.4 s relaxed
        assert sim.step(np.zeros(len(sim.muscle_names)), 0.04).ok
    assert sim.data.ncon == 0  # no MuJoCo contact with the floor
    assert np.abs(sim.data.actuator_force).max() == 0.0  # no MuJoCo muscle force
    weight = sim.report.mass * 9.81
    assert 0.5 < sim.state().foot_forces.sum() / weight < 2.0  # the law carries the body
    assert np.abs(sim.data.qfrc_applied).max() > 10.0


def test_the_relaxed_body_sinks_as_on_opensim() -> None:
    """Let go relaxed for 0.2 s: the pelvis ends within 5 mm of OpenSim's."""
    heights = {}
    for name, scene, backend in [
        ("opensim", _scene(), "opensim"),
        (
            "laws",
            _scene(
                contact_model="hunt-crossley", joint_limits="opensim", muscle_min_activation=0.01
            ),
            "mujoco",
        ),
    ]:
        sim = make_simulator(scene, backend)
        sim.reset(0)
        for _ in range(10):
            assert sim.step(np.zeros(len(sim.muscle_names)), 0.02).ok
        heights[name] = float(sim.state().pelvis_pos[sim.up_axis])
    assert abs(heights["laws"] - heights["opensim"]) < 0.005, heights


@pytest.mark.parametrize(
    ("option", "value"),
    [
        ("contact_model", "hunt-crossley"),
        ("joint_limits", "opensim"),
        ("muscle_curves", "opensim"),
        ("muscle_passive", "opensim"),
    ],
)
def test_a_mujoco_mjcf_body_is_refused_with_the_option_named(option: str, value: str) -> None:
    scene = load_scene("walk-3d")
    bad = Scene.model_validate({**scene.model_dump(), option: value})
    with pytest.raises(ValueError, match=option):
        compile_scene(bad)


@pytest.mark.parametrize(("field", "bad"), [("contact_model", "hertz"), ("joint_limits", "soft")])
def test_unknown_values_name_the_field(field: str, bad: str) -> None:
    with pytest.raises(ValidationError, match=field):
        _scene(**{field: bad})


@pytest.mark.parametrize("relaxed", [False, True], ids=["active", "relaxed-fast"])
def test_the_muscles_pull_as_opensims_millard_muscles(opensim_gait2d, relaxed: bool) -> None:
    """A pose with the knees and ankles bent, moving, and every muscle at its own activation
    (or, relaxed, at the least activation with the joints turning fast, where a shortening
    fibre's damping outweighs its force and OpenSim's tendon goes slack): each tendon force on
    MuJoCo (``muscle_curves`` and ``muscle_passive: opensim``) is OpenSim's within 0.5 % (the
    two simulators' path lengths differ by micrometres)."""
    pose = {
        "hip_flexion_r": 0.4,
        "knee_angle_r": -0.6,
        "ankle_angle_r": 0.15,
        "hip_flexion_l": -0.2,
        "knee_angle_l": -0.1,
        "ankle_angle_l": -0.2,
    }
    speeds = {
        "hip_flexion_r": 1.5,
        "knee_angle_r": -2.0,
        "ankle_angle_r": 1.0,
        "hip_flexion_l": -1.0,
        "knee_angle_l": 0.5,
        "ankle_angle_l": -2.0,
    }
    if relaxed:
        speeds = {name: 4.0 * speed for name, speed in speeds.items()}
    op = opensim_gait2d
    op.reset(0)
    state = op.osim_state
    for name, angle in pose.items():
        op._coords[name].setValue(state, angle, False)
        op._coords[name].setSpeedValue(state, speeds[name])
    activation = {
        m.getName(): 0.01 if relaxed else 0.05 + 0.05 * i for i, m in enumerate(op._muscles)
    }
    for muscle in op._muscles:
        muscle.setActivation(state, activation[muscle.getName()])
    op.model.realizeDynamics(state)
    theirs = {m.getName(): m.getActuation(state) for m in op._muscles}
    if relaxed:  # the case this checks: some tendons slack on OpenSim
        assert min(theirs.values()) == 0.0

    scene = _scene(muscle_curves="opensim", muscle_passive="opensim")
    sim = make_simulator(scene, "mujoco")
    sim.reset(0)
    m, d = sim.model, sim.data
    for name, angle in pose.items():
        joint = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
        d.qpos[m.jnt_qposadr[joint]] = angle
        d.qvel[m.jnt_dofadr[joint]] = speeds[name]
    for k, name in enumerate(sim.muscle_names):
        d.act[m.actuator_actadr[k]] = activation[name]
    mujoco.mj_forward(m, d)
    (muscles,) = [law for law in sim.opensim_laws.laws if isinstance(law, OpenSimMuscles)]
    muscles.add(m, d, np.zeros(m.nv))
    ours = dict(zip(sim.muscle_names, muscles.tension, strict=True))
    assert np.abs(d.actuator_force).max() == 0.0  # MuJoCo's own curves are out
    assert np.abs(d.qfrc_passive).max() == 0.0  # and its tendons' damping (the law damps)
    for name, force in theirs.items():
        assert ours[name] == pytest.approx(force, rel=0.005, abs=1.0), name
