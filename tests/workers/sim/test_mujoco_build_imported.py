"""The MuJoCo builder on the features of bodies imported from OpenSim, with small hand-made
bodies built into real MuJoCo models:

* a joint frame turned by ``orientation_in_parent`` (X-Y-Z body-fixed Euler angles) puts the
  child where the rotation ``Rx(a) Ry(b) Rz(c)`` says (1e-12 m);
* products of inertia reach the model (the compiled principal inertia rebuilds the tensor);
  moments that MuJoCo would refuse (``A + B < C``) are balanced to their mean;
* a coupled dof (a knee's translations following gait10dof18musc's splines of the knee
  angle) is an unlimited joint with a joint equality; its polynomial fits the spline within
  0.5 mm over the knee's range; a hanging shank swinging under gravity keeps the coupled
  joints within ``HELD`` (2e-5 m) of the polynomial at every fidelity profile's timestep
  (8e-6 m measured), and a damped one at rest within half that (6e-6 m measured);
  ``set_coupled_qpos`` places them exactly;
  locking the knee locks its translations at the polynomial's value, and a simulator's
  reset puts them on the polynomial of the jittered knee;
* a conditional path point is a site iff its coordinate's default is in its range (or the
  path needs a site there); a moving point is a fixed site at ``location``;
* an ellipsoid wrap object is a sphere of ``radius``, turned by its ``orientation``.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml
from gaitforge.workers.bodies.functions import Linear, Spline, evaluate
from gaitforge.workers.bodies.schema import (
    ActiveRange,
    Body,
    Coupling,
    Dof,
    Joint,
    Marker,
    MovingLocation,
    Muscle,
    PathPoint,
    Segment,
    WrapObject,
    WrapRef,
)
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.sim.mujoco.build import build_spec, quat_from_euler_xyz, quat_from_z
from gaitforge.workers.sim.mujoco.couplings import (
    COUPLING_PREFIX,
    coupling_fits,
    set_coupled_qpos,
)
from gaitforge.workers.sim.mujoco.lock import lock_joints
from gaitforge.workers.sim.mujoco.simulator import MujocoSimulator

KNEE_TX = Spline(
    x=[
        -2.0944,
        -1.74533,
        -1.39626,
        -1.0472,
        -0.698132,
        -0.349066,
        -0.174533,
        0.197344,
        0.337395,
        0.490178,
        1.52146,
        2.0944,
    ],
    y=[
        -0.0032,
        0.00179,
        0.00411,
        0.0041,
        0.00212,
        -0.001,
        -0.0031,
        -0.005227,
        -0.005435,
        -0.005574,
        -0.005435,
        -0.00525,
    ],
)
"""gait10dof18musc's knee_r translation1 (m) of knee_angle_r (rad)."""
KNEE_TY = Spline(
    x=[-2.0944, -1.22173, -0.523599, -0.349066, -0.174533, 0.159149, 2.0944],
    y=[-0.4226, -0.4082, -0.399, -0.3976, -0.3966, -0.395264, -0.396],
)
"""gait10dof18musc's knee_r translation2 (m) of knee_angle_r (rad)."""
KNEE_RANGE = (-2.0944, 0.17453)
KNEE_TURN = (0.0, 0.0, 0.6)
"""rad: the knee frame turned about Z so that the hanging shank rests at knee_angle -0.6."""
HELD = 2e-5
"""m: how far a coupled slide may be from its polynomial while the shank swings or rests."""
SPLINE_FIT = 5e-4
"""m: the quartic's worst error against these splines over the knee's range."""
PROFILES = [(0.005, "implicitfast"), (0.002, "implicitfast"), (0.0005, "rk4")]
"""(timestep s, integrator) of the fidelity profiles fast, default and accurate."""


def _rot(axis: int, angle: float) -> np.ndarray:
    """Rotation matrix about world axis ``axis`` (0, 1, 2) by ``angle`` rad; shape (3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    i, j = (axis + 1) % 3, (axis + 2) % 3
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


def _knee_body(*, turn: tuple[float, float, float] = KNEE_TURN) -> Body:
    """A femur welded to the ground 1 m up and a shank on a knee whose translations follow
    gait10dof18musc's splines of the knee angle (slides first, as the importer lists them)."""
    return Body(
        name="knee",
        segments=[
            Segment(name="femur", mass=8.0, inertia=(0.1, 0.03, 0.1)),
            Segment(name="tibia", mass=3.5, com=(0.0, -0.2, 0.0), inertia=(0.05, 0.005, 0.05)),
        ],
        joints=[
            Joint(
                name="ground_femur", parent="ground", child="femur", location_in_parent=(0, 1, 0)
            ),
            Joint(
                name="knee",
                parent="femur",
                child="tibia",
                orientation_in_parent=turn,
                dofs=[
                    Dof(
                        name="knee_tx",
                        type="slide",
                        axis=(1, 0, 0),
                        range=(-0.01, 0.01),
                        default=float(evaluate(KNEE_TX, 0.0)),
                        coupled=Coupling(coordinate="knee_angle", function=KNEE_TX),
                    ),
                    Dof(
                        name="knee_ty",
                        type="slide",
                        axis=(0, 1, 0),
                        range=(-0.43, -0.39),
                        default=float(evaluate(KNEE_TY, 0.0)),
                        coupled=Coupling(coordinate="knee_angle", function=KNEE_TY),
                    ),
                    Dof(name="knee_angle", type="hinge", axis=(0, 0, 1), range=KNEE_RANGE),
                ],
            ),
        ],
        markers=[Marker(name="ankle", segment="tibia", location=(0.0, -0.4, 0.0))],
    )


def _qadr(model: mujoco.MjModel, joint: str) -> int:
    return int(model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint)])


# ---- joint frames and inertia ----------------------------------------------------------


def test_turned_joint_frame_puts_the_child_where_the_euler_angles_say() -> None:
    turn = (0.3, -0.5, 0.8)
    body = Body(
        name="turned",
        segments=[
            Segment(name="base", mass=1.0, inertia=(0.01, 0.01, 0.01)),
            Segment(name="arm", mass=1.0, inertia=(0.01, 0.01, 0.01)),
        ],
        joints=[
            Joint(name="weld", parent="ground", child="base", location_in_parent=(0, 1, 0)),
            Joint(
                name="elbow",
                parent="base",
                child="arm",
                location_in_parent=(0.1, -0.2, 0.05),
                orientation_in_parent=turn,
                dofs=[Dof(name="flex", type="hinge", axis=(0, 0, 1), range=(-2.0, 2.0))],
            ),
        ],
        markers=[Marker(name="hand", segment="arm", location=(0.0, -0.3, 0.02))],
    )
    model = build_spec(body).compile()
    data = mujoco.MjData(model)
    flex = 0.7
    data.qpos[_qadr(model, "flex")] = flex
    mujoco.mj_kinematics(model, data)
    joint_frame = _rot(0, turn[0]) @ _rot(1, turn[1]) @ _rot(2, turn[2])
    arm = joint_frame @ _rot(2, flex)  # the dof acts in the joint frame
    origin = np.array([0.1, 1.0 - 0.2, 0.05])
    arm_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "arm")
    np.testing.assert_allclose(data.xmat[arm_id].reshape(3, 3), arm, atol=1e-12)
    np.testing.assert_allclose(data.xpos[arm_id], origin, atol=1e-12)
    np.testing.assert_allclose(
        data.site("hand").xpos, origin + arm @ np.array([0.0, -0.3, 0.02]), atol=1e-12
    )


def test_products_of_inertia_reach_the_model() -> None:
    moments, products = (0.1, 0.08, 0.05), (0.01, -0.005, 0.002)
    body = Body(
        name="skewed",
        segments=[
            Segment(
                name="block",
                mass=2.0,
                com=(0.01, 0.02, 0.03),
                inertia=moments,
                inertia_products=products,
            ),
            Segment(name="plain", mass=1.0, inertia=(0.03, 0.02, 0.01)),
        ],
        joints=[
            Joint(name="weld", parent="ground", child="block"),
            Joint(
                name="pin",
                parent="block",
                child="plain",
                dofs=[Dof(name="spin", type="hinge", axis=(0, 0, 1), range=(-1.0, 1.0))],
            ),
        ],
    )
    model = build_spec(body).compile()
    block = model.body("block")
    principal = np.zeros(9)
    mujoco.mju_quat2Mat(principal, block.iquat)
    principal = principal.reshape(3, 3)
    tensor = principal @ np.diag(block.inertia) @ principal.T
    ixy, ixz, iyz = products
    expected = np.array([[moments[0], ixy, ixz], [ixy, moments[1], iyz], [ixz, iyz, moments[2]]])
    np.testing.assert_allclose(tensor, expected, atol=1e-12)
    np.testing.assert_allclose(block.ipos, (0.01, 0.02, 0.03), atol=1e-15)
    plain = model.body("plain")  # no products: the diagonal, unturned
    np.testing.assert_allclose(plain.inertia, (0.03, 0.02, 0.01), atol=1e-15)
    np.testing.assert_allclose(plain.iquat, (1, 0, 0, 0), atol=1e-15)


def test_moments_that_break_the_triangle_inequality_are_balanced() -> None:
    """OpenSim accepts leg6dof9musc's toes (1e-6, 1e-6, 9e-4 kg m^2); MuJoCo would refuse."""
    toes = (1e-6, 1e-6, 9.0462e-4)
    body = Body(
        name="toes",
        segments=[Segment(name="toes", mass=0.186, inertia=toes)],
        joints=[Joint(name="weld", parent="ground", child="toes")],
    )
    model = build_spec(body).compile()
    np.testing.assert_allclose(model.body("toes").inertia, np.full(3, np.mean(toes)), rtol=1e-12)


# ---- coupled dofs -------------------------------------------------------------------------


def test_coupled_dof_is_an_unlimited_joint_held_by_its_fitted_polynomial() -> None:
    body = _knee_body()
    fits = coupling_fits(body)
    assert set(fits) == {"knee_tx", "knee_ty"}
    x = np.linspace(*KNEE_RANGE, 5001)
    for dof, spline in (("knee_tx", KNEE_TX), ("knee_ty", KNEE_TY)):
        fit = fits[dof]
        assert fit.driver == "knee_angle" and fit.driver_range == KNEE_RANGE
        seen = float(np.max(np.abs(fit(x) - evaluate(spline, x))))
        assert seen == pytest.approx(fit.max_error, rel=0.01)  # the reported error is the worst
        assert fit.max_error < SPLINE_FIT
    model = build_spec(body).compile()
    for dof in ("knee_tx", "knee_ty"):
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, dof)
        assert model.jnt_limited[jid] == 0
        eq = model.equality(f"{COUPLING_PREFIX}{dof}")
        assert eq.type == mujoco.mjtEq.mjEQ_JOINT
        assert eq.obj1id == jid
        assert eq.obj2id == mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "knee_angle")
        # exactly: the model holds the very fit made here (same body, process and machine)
        np.testing.assert_array_equal(eq.data[:5], fits[dof].coefficients)
    assert model.jnt_limited[model.joint("knee_angle").id] == 1
    assert np.all(model.qpos0 == 0.0)  # the polynomial reads y = poly(x)


def test_a_linear_coupling_is_fitted_exactly() -> None:
    body = _knee_body()
    joints = list(body.joints)
    knee = joints[1]
    linear = knee.dofs[0].model_copy(
        update={
            "range": (-0.1, 0.1),
            "default": 0.001,
            "coupled": Coupling(
                coordinate="knee_angle", function=Linear(slope=0.02, intercept=0.001)
            ),
        }
    )
    joints[1] = knee.model_copy(update={"dofs": [linear, *knee.dofs[1:]]})
    fit = coupling_fits(body.model_copy(update={"joints": joints}))["knee_tx"]
    np.testing.assert_allclose(fit.coefficients, (0.001, 0.02, 0.0, 0.0, 0.0), atol=1e-14)
    assert fit.max_error < 1e-15


def test_set_coupled_qpos_places_coupled_joints_exactly() -> None:
    body = _knee_body()
    fits = coupling_fits(body)
    model = build_spec(body).compile()
    data = mujoco.MjData(model)
    knee = _qadr(model, "knee_angle")
    for angle in (-2.0, -1.1, -0.3, 0.1):
        data.qpos[knee] = angle
        data.qvel[model.joint("knee_angle").dofadr[0]] = 1.5
        set_coupled_qpos(model, data)
        mujoco.mj_forward(model, data)
        for dof, spline in (("knee_tx", KNEE_TX), ("knee_ty", KNEE_TY)):
            fit = fits[dof]
            assert data.qpos[_qadr(model, dof)] == pytest.approx(float(fit(angle)), abs=1e-15)
            assert abs(data.qpos[_qadr(model, dof)] - evaluate(spline, angle)) <= fit.max_error
        rows = data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY
        np.testing.assert_allclose(data.efc_pos[rows], 0.0, atol=1e-15)
        np.testing.assert_allclose(data.efc_vel[rows], 0.0, atol=1e-14)  # speeds follow too


def _drop_shank(timestep: float, integrator: str, damping: float) -> tuple[np.ndarray, ...]:
    """The knee body dropped from knee_angle -1.2 and stepped for 3 s under gravity.

    Returns:
        knee angles (rad), the coupled slides' worst distance from their polynomials (m),
        and the last ``qpos``; the first two of shape (steps,).
    """
    body = _knee_body()
    fits = coupling_fits(body)
    spec = build_spec(body)
    spec.option.timestep = timestep
    spec.option.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{integrator.upper()}")
    model = spec.compile()
    model.dof_damping[model.joint("knee_angle").dofadr[0]] = damping
    knee, slides = _qadr(model, "knee_angle"), {d: _qadr(model, d) for d in fits}
    data = mujoco.MjData(model)
    data.qpos[knee] = -1.2
    set_coupled_qpos(model, data)
    angles, off = [], []
    for _ in range(round(3.0 / timestep)):
        mujoco.mj_step(model, data)
        angle = data.qpos[knee]
        angles.append(angle)
        off.append(max(abs(data.qpos[a] - fits[d](angle)) for d, a in slides.items()))
    return np.array(angles), np.array(off), data.qpos.copy()


@pytest.mark.parametrize(("timestep", "integrator"), PROFILES)
def test_swinging_shank_keeps_its_knee_on_the_spline(timestep: float, integrator: str) -> None:
    """Undamped, the shank swings through about [-1.2, 0] (its rest is at -0.6)."""
    angles, off, _ = _drop_shank(timestep, integrator, damping=0.0)
    assert angles.min() < -1.1 and angles.max() > -0.2  # it did swing
    assert off.max() < HELD, f"{off.max():.2e} m off the polynomial"


@pytest.mark.parametrize(("timestep", "integrator"), PROFILES)
def test_shank_at_rest_sits_on_the_spline(timestep: float, integrator: str) -> None:
    """With the knee damped (2 N m s/rad) the shank settles at -0.6. Implicit integrators damp
    the driver's speed after the constraint solver, so while it settles the slides lag by up
    to 5e-5 m (at the fast profile's 5 ms step); at rest they are back within ``HELD``."""
    angles, off, qpos = _drop_shank(timestep, integrator, damping=2.0)
    assert angles[-1] == pytest.approx(-KNEE_TURN[2], abs=0.02)
    assert off.max() < 1e-4
    assert off[-1] < HELD / 2, f"{off[-1]:.2e} m off the polynomial at rest"
    tx, ty, knee = qpos  # the joints in the order of the knee's dofs
    fits = coupling_fits(_knee_body())
    assert abs(tx - evaluate(KNEE_TX, knee)) < fits["knee_tx"].max_error + HELD
    assert abs(ty - evaluate(KNEE_TY, knee)) < fits["knee_ty"].max_error + HELD


def test_locking_the_driver_locks_its_coupled_dofs_at_the_polynomial() -> None:
    body = _knee_body()
    angle = -1.0
    free = build_spec(body).compile()
    data = mujoco.MjData(free)
    data.qpos[_qadr(free, "knee_angle")] = angle
    set_coupled_qpos(free, data)
    mujoco.mj_kinematics(free, data)
    spec = build_spec(body)
    assert lock_joints(spec, {"knee_angle": angle}) == ["knee_tx", "knee_ty", "knee_angle"]
    locked = spec.compile()
    assert locked.njnt == 0 and locked.neq == 0
    locked_data = mujoco.MjData(locked)
    mujoco.mj_kinematics(locked, locked_data)
    np.testing.assert_allclose(locked_data.site("ankle").xpos, data.site("ankle").xpos, atol=1e-12)


def test_a_reset_puts_coupled_dofs_on_their_jittered_drivers_polynomial(tmp_path: Path) -> None:
    """A scene on a body file: the coupled dofs are neither kept nor jittered; the reset
    moves them with their driver (``MujocoSimulator.reset``)."""
    body_file = tmp_path / "knee.yaml"
    body_file.write_text(yaml.safe_dump(_knee_body().model_dump(mode="json"), sort_keys=False))
    reach = load_scene("elbow-reach")
    scene = reach.model_copy(
        update={
            "body": str(body_file),
            "init_noise": 0.3,
            "task": reach.task.model_copy(update={"reach_dof": "knee_angle"}),
        }
    )
    sim = MujocoSimulator(scene)
    assert sim.dof_names == ["knee_angle"]
    fits = coupling_fits(_knee_body())
    model, data = sim.model, sim.data
    angles = []
    for seed in range(4):
        sim.reset(seed)
        angle = data.qpos[_qadr(model, "knee_angle")]
        angles.append(angle)
        for dof, fit in fits.items():
            assert data.qpos[_qadr(model, dof)] == pytest.approx(float(fit(angle)), abs=1e-15)
    assert np.ptp(angles) > 0.05  # the driver was jittered


# ---- path points and wraps ---------------------------------------------------------------


def _muscle(name: str, path: list) -> Muscle:
    return Muscle(
        name=name,
        max_isometric_force=500.0,
        optimal_fiber_length=0.1,
        tendon_slack_length=0.3,
        path=path,
    )


def _with_muscles(muscles: list[Muscle], wraps: list[WrapObject]) -> Body:
    return _knee_body().model_copy(update={"muscles": muscles, "wrap_objects": wraps})


def test_conditional_points_follow_the_default_and_moving_points_sit_at_location() -> None:
    moving = MovingLocation(
        coordinate="knee_angle",
        x=Linear(slope=0.01, intercept=0.03),
        y=Spline(x=[-2.0, 0.0, 0.2], y=[-0.1, -0.05, -0.04]),
        z=Linear(slope=0.0, intercept=0.0),
    )
    body = _with_muscles(
        [
            _muscle(
                "flexor",
                [
                    PathPoint(segment="femur", location=(0.0, -0.1, 0.0)),
                    PathPoint(  # the default (0) outside (-2, -1): dropped
                        segment="femur",
                        location=(0.02, -0.3, 0.0),
                        active_when=ActiveRange(coordinate="knee_angle", range=(-2.0, -1.0)),
                    ),
                    PathPoint(  # the default inside (-0.5, 0.5): kept
                        segment="femur",
                        location=(0.03, -0.35, 0.0),
                        active_when=ActiveRange(coordinate="knee_angle", range=(-0.5, 0.5)),
                    ),
                    PathPoint(segment="tibia", location=(0.03, -0.05, 0.0), moves_with=moving),
                    PathPoint(segment="tibia", location=(0.0, -0.3, 0.0)),
                ],
            ),
            _muscle(
                "wrapped",
                [
                    PathPoint(segment="femur", location=(-0.02, -0.1, 0.0)),
                    WrapRef(wrap="condyle"),
                    PathPoint(  # inactive at the default, but the wrap needs a site after it
                        segment="tibia",
                        location=(-0.03, -0.05, 0.0),
                        active_when=ActiveRange(coordinate="knee_angle", range=(-2.0, -1.0)),
                    ),
                    PathPoint(segment="tibia", location=(0.0, -0.3, 0.0)),
                ],
            ),
        ],
        [
            WrapObject(
                name="condyle", segment="femur", type="cylinder", location=(0, -0.4, 0), radius=0.03
            )
        ],
    )
    model = build_spec(body).compile()
    sites = {model.site(i).name for i in range(model.nsite)}
    assert {"flexor_p0", "flexor_p2", "flexor_p3", "flexor_p4"} <= sites
    assert "flexor_p1" not in sites
    assert "wrapped_p2" in sites
    np.testing.assert_allclose(model.site("flexor_p3").pos, (0.03, -0.05, 0.0))
    np.testing.assert_allclose(model.site("flexor_p2").pos, (0.03, -0.35, 0.0))
    assert model.tendon_num[model.tendon("flexor").id] == 4  # four sites, no wrap
    assert model.tendon_num[model.tendon("wrapped").id] == 4  # site, cylinder, site, site


def test_ellipsoid_wrap_is_a_sphere_of_its_radius_turned_by_its_orientation() -> None:
    orientation = (0.2, -0.4, 1.1)
    body = _with_muscles(
        [
            _muscle(
                "over_ellipsoid",
                [
                    PathPoint(segment="femur", location=(0.05, -0.1, 0.0)),
                    WrapRef(wrap="patella"),
                    PathPoint(segment="tibia", location=(0.05, -0.1, 0.0)),
                ],
            )
        ],
        [
            WrapObject(
                name="patella",
                segment="femur",
                type="ellipsoid",
                location=(0.04, -0.4, 0.0),
                radii=(0.05, 0.03, 0.04),
                orientation=orientation,
                radius=0.04,
            ),
            WrapObject(
                name="turned_cylinder",
                segment="femur",
                type="cylinder",
                location=(0.0, -0.2, 0.0),
                orientation=orientation,
                radius=0.02,
            ),
            WrapObject(
                name="plain_cylinder",
                segment="femur",
                type="cylinder",
                location=(0.0, -0.2, 0.0),
                axis=(1.0, 0.0, 0.0),
                radius=0.02,
            ),
        ],
    )
    model = build_spec(body).compile()
    patella = model.geom("patella")
    assert patella.type == mujoco.mjtGeom.mjGEOM_SPHERE
    assert patella.size[0] == pytest.approx(0.04)
    expected = quat_from_euler_xyz(orientation)
    np.testing.assert_allclose(patella.quat, expected, atol=1e-12)
    np.testing.assert_allclose(model.geom("turned_cylinder").quat, expected, atol=1e-12)
    np.testing.assert_allclose(
        model.geom("plain_cylinder").quat, quat_from_z((1.0, 0.0, 0.0)), atol=1e-12
    )
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert np.isfinite(data.ten_length).all() and data.ten_length[0] > 0


def test_quat_from_euler_xyz_is_the_body_fixed_sequence() -> None:
    angles = (0.3, -1.2, 2.0)
    matrix = np.zeros(9)
    mujoco.mju_quat2Mat(matrix, quat_from_euler_xyz(angles))
    expected = _rot(0, angles[0]) @ _rot(1, angles[1]) @ _rot(2, angles[2])
    np.testing.assert_allclose(matrix.reshape(3, 3), expected, atol=1e-12)
