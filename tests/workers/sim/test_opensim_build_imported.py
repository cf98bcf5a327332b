"""The OpenSim builder on the features that imported OpenSim models use.

A small hand-made leg (no simulator mocks: real ``opensim`` models) has turned joint frames on
every kind of joint the builder makes (planar, pin, slider, custom, weld), products of
inertia, a knee whose translations follow splines of its angle (coupled within the joint)
and a patella coupled to that angle from another joint, conditional and moving path points
and ellipsoid and turned cylinder wraps. The schema's kinematics are computed here
independently (:func:`_expected_frames`: joint frame at ``location_in_parent`` turned by the
body-fixed X-Y-Z ``orientation_in_parent``, then each dof in order in the frame the ones before
left) and OpenSim's segment frames and path lengths must agree to 1e-9 m.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import opensim
import pytest
from gaitforge.workers.bodies.functions import Linear, Spline, evaluate
from gaitforge.workers.bodies.schema import (
    GROUND,
    ActiveRange,
    Body,
    Coupling,
    Dof,
    Joint,
    JointLimit,
    MovingLocation,
    Muscle,
    PathPoint,
    Segment,
    WrapObject,
    WrapRef,
)
from gaitforge.workers.scenes.prune import PrunePlan
from gaitforge.workers.sim.opensim.build import OpenSimBuild, build_model, locked_values

TOL = 1e-9  # m (and rotation matrix entries)
KNEE_TX = Spline(x=[-2.0, -1.5, -1.0, -0.5, 0.0, 0.2], y=[-0.003, 0.002, 0.004, 0.003, 0.0, -0.001])
KNEE_TY = Linear(slope=0.01, intercept=0.0)
PATELLA_TY = Spline(x=[-2.0, -1.0, 0.0, 0.2], y=[-0.02, -0.012, 0.0, 0.001])
MOVING_X = Spline(x=[-2.0, -1.0, 0.0], y=[0.06, 0.04, 0.03])
CONDITION = (-2.0, -1.0)  # rad of knee_angle where the conditional point is part of the path
INERTIA_PRODUCTS = (0.004, -0.003, 0.002)  # kg m^2


def _dof(
    name: str,
    kind: str,
    axis: tuple[float, float, float],
    *,
    coupled: Coupling | None = None,
    limit: JointLimit | None = None,
    span: float = 2.1,
) -> Dof:
    """A dof over ``(-span, span)`` (rad or m), default 0."""
    return Dof(
        name=name,
        type=kind,  # type: ignore[arg-type]
        axis=axis,
        range=(-span, span),
        coupled=coupled,
        limit=limit,
    )


def _leg() -> Body:
    """Pelvis (planar root), thigh (pin hip), shank (custom knee with coupled translations),
    patella (slider coupled to the knee angle), foot (custom ankle); every joint frame turned."""
    knee_limit = JointLimit(range=(-2.0, 0.0), stiffness=50.0, transition=0.1)
    segments = [
        Segment(name="pelvis", mass=10.0, inertia=(0.1, 0.1, 0.1)),
        Segment(
            name="thigh",
            mass=5.0,
            com=(0.0, -0.17, 0.0),
            inertia=(0.08, 0.02, 0.08),
            inertia_products=INERTIA_PRODUCTS,
        ),
        Segment(name="shank", mass=3.0, com=(0.0, -0.18, 0.0), inertia=(0.04, 0.01, 0.04)),
        Segment(name="patella", mass=0.1, inertia=(1e-4, 1e-4, 1e-4)),
        Segment(name="foot", mass=1.0, inertia=(0.002, 0.004, 0.004)),
    ]
    joints = [
        Joint(
            name="ground_pelvis",
            parent=GROUND,
            child="pelvis",
            location_in_parent=(0.0, 1.0, 0.0),
            orientation_in_parent=(0.2, -0.1, 0.3),
            dofs=[
                _dof("pelvis_tx", "slide", (1, 0, 0), span=5.0),
                _dof("pelvis_ty", "slide", (0, 1, 0), span=5.0),
                _dof("pelvis_tilt", "hinge", (0, 0, 1)),
            ],
        ),
        Joint(
            name="hip",
            parent="pelvis",
            child="thigh",
            location_in_parent=(-0.05, -0.08, 0.08),
            orientation_in_parent=(0.1, 0.4, -0.2),
            dofs=[_dof("hip_flexion", "hinge", (0, 0, 1))],
        ),
        Joint(
            name="knee",
            parent="thigh",
            child="shank",
            location_in_parent=(0.0, -0.4, 0.0),
            orientation_in_parent=(0.05, -0.1, 0.15),
            dofs=[
                _dof(
                    "knee_tx",
                    "slide",
                    (1, 0, 0),
                    coupled=Coupling(coordinate="knee_angle", function=KNEE_TX),
                    limit=JointLimit(range=(-0.01, 0.01), stiffness=1e4),
                    span=0.05,
                ),
                _dof(
                    "knee_ty",
                    "slide",
                    (0, 1, 0),
                    coupled=Coupling(coordinate="knee_angle", function=KNEE_TY),
                    span=0.05,
                ),
                _dof("knee_angle", "hinge", (0, 0, 1), limit=knee_limit),
            ],
        ),
        Joint(
            name="patellofemoral",
            parent="thigh",
            child="patella",
            location_in_parent=(0.05, -0.38, 0.0),
            orientation_in_parent=(0.0, 0.0, -0.3),
            dofs=[
                _dof(
                    "patella_ty",
                    "slide",
                    (0, 1, 0),
                    coupled=Coupling(coordinate="knee_angle", function=PATELLA_TY),
                    span=0.05,
                )
            ],
        ),
        Joint(
            name="ankle",
            parent="shank",
            child="foot",
            location_in_parent=(0.0, -0.42, 0.0),
            orientation_in_parent=(0.3, 0.2, -0.1),
            dofs=[
                _dof("ankle_shift", "slide", (0, 0, 1), span=0.1),
                _dof("ankle_angle", "hinge", (0, 0, 1)),
                _dof("subtalar", "hinge", (0.6, 0.8, 0.0)),
            ],
        ),
    ]
    muscles = [
        Muscle(
            name="vasti",
            max_isometric_force=1000.0,
            optimal_fiber_length=0.1,
            tendon_slack_length=0.2,
            path=[
                PathPoint(segment="thigh", location=(0.03, -0.2, 0.0)),
                PathPoint(
                    segment="shank",
                    location=(0.05, 0.02, 0.0),
                    active_when=ActiveRange(coordinate="knee_angle", range=CONDITION),
                ),
                PathPoint(
                    segment="shank",
                    location=(0.03, -0.06, 0.0),  # at knee_angle 0
                    moves_with=MovingLocation(
                        coordinate="knee_angle",
                        x=MOVING_X,
                        y=Linear(slope=0.0, intercept=-0.06),
                        z=Linear(slope=0.01, intercept=0.0),
                    ),
                ),
            ],
        ),
        Muscle(
            name="glutes",
            max_isometric_force=1000.0,
            optimal_fiber_length=0.1,
            tendon_slack_length=0.1,
            path=[
                PathPoint(segment="pelvis", location=(-0.1, 0.0, 0.0)),
                WrapRef(wrap="hip_ellipsoid"),
                PathPoint(segment="thigh", location=(-0.1, -0.2, 0.0)),
            ],
        ),
        Muscle(
            name="gastroc",
            max_isometric_force=1000.0,
            optimal_fiber_length=0.1,
            tendon_slack_length=0.3,
            path=[
                PathPoint(segment="thigh", location=(-0.02, -0.38, 0.0)),
                WrapRef(wrap="knee_cylinder"),
                PathPoint(segment="foot", location=(-0.05, 0.0, 0.0)),
            ],
        ),
    ]
    wraps = [
        WrapObject(
            name="hip_ellipsoid",
            segment="thigh",
            type="ellipsoid",
            location=(-0.03, -0.07, -0.04),  # the glutes' straight line runs through it
            radii=(0.06, 0.1, 0.05),
            orientation=(0.0, 0.0, 0.3),
            radius=0.06,
            side=(-0.12, -0.07, -0.04),
        ),
        WrapObject(
            name="knee_cylinder",
            segment="thigh",
            type="cylinder",
            location=(0.0, -0.4, 0.0),
            orientation=(0.0, 0.2, 0.0),
            radius=0.03,
            side=(-0.05, -0.4, 0.0),
        ),
    ]
    return Body(
        name="imported_leg", segments=segments, joints=joints, muscles=muscles, wrap_objects=wraps
    )


def _plan(body: Body, locked: dict[str, float] | None = None) -> PrunePlan:
    locked = locked or {}
    return PrunePlan(
        kept_dofs=[d for d in body.dof_names if d not in locked],
        locked_dofs=locked,
        kept_muscles=[m.name for m in body.muscles],
        removed_muscles={},
        contact_geoms=[],
        obstacles=0,
    )


# ------------------------------------------------- the schema's kinematics, independently


def _rotation(axis: tuple[float, float, float], angle: float) -> np.ndarray:
    """Rotation by ``angle`` (rad) about ``axis``, Rodrigues."""
    k = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * cross + (1 - math.cos(angle)) * cross @ cross


def _euler(angles: tuple[float, float, float]) -> np.ndarray:
    """Body-fixed X-Y-Z: ``Rx(a) @ Ry(b) @ Rz(c)``."""
    return (
        _rotation((1, 0, 0), angles[0])
        @ _rotation((0, 1, 0), angles[1])
        @ _rotation((0, 0, 1), angles[2])
    )


def _all_values(body: Body, free: dict[str, float]) -> dict[str, float]:
    """Every dof's value (rad or m): ``free`` (missing free dofs at 0), coupled dofs from
    their drivers."""
    values = {name: free.get(name, 0.0) for name in body.dof_names}
    for coupled, driver in body.coupled_dofs.items():
        values[coupled] = float(evaluate(body.dof(coupled).coupled.function, values[driver]))
    return values


def _expected_frames(body: Body, values: dict[str, float]) -> dict[str, tuple[np.ndarray, ...]]:
    """Segment -> (rotation, origin) in the ground frame, by the schema's conventions."""
    frames: dict[str, tuple[np.ndarray, ...]] = {GROUND: (np.eye(3), np.zeros(3))}
    for joint in body.ordered_joints():
        parent_rot, parent_pos = frames[joint.parent]
        pos = parent_pos + parent_rot @ np.asarray(joint.location_in_parent)
        rot = parent_rot @ _euler(joint.orientation_in_parent)
        for d in joint.dofs:
            if d.type == "hinge":
                rot = rot @ _rotation(d.axis, values[d.name])
            else:
                pos = pos + rot @ (np.asarray(d.axis) / np.linalg.norm(d.axis)) * values[d.name]
        frames[joint.child] = (rot, pos)
    return frames


def _expected_length(body: Body, muscle: str, values: dict[str, float]) -> float:
    """Straight-line length (m) through the muscle's active points at ``values``."""
    frames = _expected_frames(body, values)
    points = []
    for p in next(m for m in body.muscles if m.name == muscle).points:
        location = np.asarray(p.location, dtype=float)
        if p.active_when is not None:
            low, high = p.active_when.range
            if not low <= values[p.active_when.coordinate] <= high:
                continue
        if p.moves_with is not None:
            q = values[p.moves_with.coordinate]
            fns = (p.moves_with.x, p.moves_with.y, p.moves_with.z)
            location = np.array([float(evaluate(f, q)) for f in fns])
        rot, origin = frames[p.segment]
        points.append(origin + rot @ location)
    return float(sum(np.linalg.norm(b - a) for a, b in itertools.pairwise(points)))


# ---------------------------------------------------------------- posing OpenSim


def _pose(build: OpenSimBuild, body: Body, free: dict[str, float]) -> opensim.State:
    """A state with the free dofs at ``free`` (others 0) and each coupled dof that is a
    coordinate of its own at its function of the driver; position realized."""
    model = build.model
    state = model.initSystem()
    coords = model.getCoordinateSet()
    for name, value in _all_values(body, free).items():
        if coords.contains(name) and not coords.get(name).getDefaultLocked():
            coords.get(name).setValue(state, value, False)
    model.realizePosition(state)
    return state


def _vector(v: opensim.Vec3) -> np.ndarray:
    return np.array([v.get(i) for i in range(3)])


def _frames(build: OpenSimBuild, state: opensim.State) -> dict[str, tuple[np.ndarray, ...]]:
    out = {}
    bodies = build.model.getBodySet()
    for i in range(bodies.getSize()):
        transform = bodies.get(i).getTransformInGround(state)
        r = transform.R()
        rot = np.array([[r.get(a, b) for b in range(3)] for a in range(3)])
        out[bodies.get(i).getName()] = (rot, _vector(transform.p()))
    return out


def _assert_frames_match(
    build: OpenSimBuild, body: Body, state: opensim.State, values: dict[str, float]
) -> None:
    """Every OpenSim segment frame is the schema's at ``values`` (every dof, rad or m)."""
    expected = _expected_frames(body, values)
    for name, (rot, pos) in _frames(build, state).items():
        assert np.allclose(pos, expected[name][1], atol=TOL), (name, pos, expected[name][1])
        assert np.allclose(rot, expected[name][0], atol=TOL), name


def _joint_types(build: OpenSimBuild) -> dict[str, str]:
    joints = build.model.getJointSet()
    return {
        joints.get(i).getName(): joints.get(i).getConcreteClassName()
        for i in range(joints.getSize())
    }


POSES = [
    {},
    {"pelvis_tx": 0.3, "pelvis_ty": -0.1, "pelvis_tilt": 0.4, "hip_flexion": 0.8},
    {"hip_flexion": -0.5, "knee_angle": -1.3, "ankle_shift": 0.05, "ankle_angle": 0.3},
    {"knee_angle": -1.9, "subtalar": -0.4, "pelvis_tilt": -0.2, "ankle_angle": -0.6},
    {"knee_angle": 0.15, "hip_flexion": 1.4},
]


# ---------------------------------------------------------------------------- tests


def test_joint_kinds_and_couplings() -> None:
    build = build_model(_leg(), _plan(_leg()))
    assert _joint_types(build) == {
        "ground_pelvis": "PlanarJoint",
        "hip": "PinJoint",
        "knee": "CustomJoint",
        "patellofemoral": "SliderJoint",
        "ankle": "CustomJoint",
    }
    coords = build.model.getCoordinateSet()
    names = {coords.get(i).getName() for i in range(coords.getSize())}
    assert "knee_tx" not in names and "knee_ty" not in names  # axes the knee angle moves
    assert "patella_ty" in names  # a coordinate held by a coupler
    coupler = opensim.CoordinateCouplerConstraint.safeDownCast(
        build.model.getConstraintSet().get("patella_ty_coupler")
    )
    assert coupler.getDependentCoordinateName() == "patella_ty"
    assert coupler.getIndependentCoordinateNames().get(0) == "knee_angle"
    assert build.model.getConstraintSet().getSize() == 1
    forces = build.model.getForceSet()
    assert not forces.contains("knee_tx_limit")  # a coupled dof has no limit force
    knee = opensim.CoordinateLimitForce.safeDownCast(forces.get("knee_angle_limit"))
    assert knee.get_lower_limit() == pytest.approx(-2.0 / math.pi * 180.0)  # deg: rotational


@pytest.mark.parametrize("pose", POSES)
def test_turned_joint_frames_and_coupled_axes_place_segments(pose: dict[str, float]) -> None:
    """Every segment where the schema puts it; the patella's coupler holds at f(knee)."""
    body = _leg()
    build = build_model(body, _plan(body))
    state = _pose(build, body, pose)
    q_err = state.getQErr()
    assert max((abs(q_err.get(i)) for i in range(q_err.size())), default=0.0) < 1e-12
    _assert_frames_match(build, body, state, _all_values(body, pose))


def test_coupled_translation_follows_its_spline_as_the_driver_moves() -> None:
    """Only the knee angle is set: the shank's origin follows KNEE_TX and KNEE_TY."""
    body = _leg()
    build = build_model(body, _plan(body))
    state = build.model.initSystem()
    knee = build.model.getCoordinateSet().get("knee_angle")
    thigh = _expected_frames(body, _all_values(body, {}))["thigh"]
    joint = next(j for j in body.joints if j.name == "knee")
    frame = thigh[0] @ _euler(joint.orientation_in_parent)
    centre = thigh[1] + thigh[0] @ np.asarray(joint.location_in_parent)
    for q in (-2.05, -1.7, -1.0, -0.3, 0.0, 0.18):
        knee.setValue(state, q, False)
        build.model.realizePosition(state)
        origin = _vector(build.model.getBodySet().get("shank").getPositionInGround(state))
        along = frame.T @ (origin - centre)  # translation in the knee's joint frame
        expected = [float(evaluate(KNEE_TX, q)), float(evaluate(KNEE_TY, q)), 0.0]
        assert np.allclose(along, expected, atol=TOL), (q, along, expected)


def test_coupled_dof_of_another_joint_follows_its_driver() -> None:
    """The knee angle locked in the state, assembly moves the patella to PATELLA_TY."""
    body = _leg()
    build = build_model(body, _plan(body))
    model = build.model
    state = model.initSystem()
    coords = model.getCoordinateSet()
    for q in (-1.8, -0.6, 0.1):
        coords.get("knee_angle").setValue(state, q, False)
        coords.get("knee_angle").setLocked(state, True)
        model.assemble(state)
        coords.get("knee_angle").setLocked(state, False)
        model.realizePosition(state)
        assert coords.get("knee_angle").getValue(state) == pytest.approx(q, abs=1e-12)
        patella = coords.get("patella_ty").getValue(state)
        assert patella == pytest.approx(float(evaluate(PATELLA_TY, q)), abs=1e-8)
        expected = _expected_frames(body, _all_values(body, {"knee_angle": q}))["patella"]
        origin = _vector(model.getBodySet().get("patella").getPositionInGround(state))
        assert np.allclose(origin, expected[1], atol=1e-8), q


@pytest.mark.parametrize("knee", [-1.5, -0.4])
def test_locked_driver_welds_its_coupled_dofs_at_their_functions(knee: float) -> None:
    body = _leg()
    locked = {"hip_flexion": 0.3, "knee_angle": knee, "knee_tx": 0.0}  # plan's knee_tx ignored
    locked |= {"ankle_shift": 0.02, "ankle_angle": -0.2, "subtalar": 0.1}
    build = build_model(body, _plan(body, locked))
    types = _joint_types(build)
    assert types["hip"] == types["knee"] == types["patellofemoral"] == types["ankle"]
    assert types["knee"] == "WeldJoint"
    assert locked_values(body, _plan(body, locked))["knee_tx"] == pytest.approx(
        float(evaluate(KNEE_TX, knee))
    )
    assert build.model.getConstraintSet().getSize() == 0
    pose = {"pelvis_tilt": 0.2, "pelvis_ty": 0.1}
    state = _pose(build, body, pose)
    _assert_frames_match(build, body, state, _all_values(body, pose | locked))
    # The knee locked on either side of the conditional point's range (-2, -1).
    vasti = build.model.getMuscles().get("vasti")
    expected = _expected_length(body, "vasti", _all_values(body, pose | locked))
    assert vasti.getLength(state) == pytest.approx(expected, abs=TOL)
    n_points = vasti.getGeometryPath().getPathPointSet().getSize()
    assert n_points == (3 if CONDITION[0] <= knee <= CONDITION[1] else 2)


def test_a_locked_driver_in_a_joint_that_keeps_moving() -> None:
    """A knee with a free rotation besides its (locked) angle stays a custom joint: its coupled
    translations are constants at f(locked angle); the patella is welded at its own f."""
    raw = _leg().model_dump()
    knee = next(j for j in raw["joints"] if j["name"] == "knee")
    knee["dofs"].append(_dof("knee_rotation", "hinge", (0, 1, 0), span=0.5).model_dump())
    body = Body.model_validate(raw)
    build = build_model(body, _plan(body, {"knee_angle": -1.2}))
    assert _joint_types(build)["knee"] == "CustomJoint"
    assert _joint_types(build)["patellofemoral"] == "WeldJoint"  # at PATELLA_TY(-1.2)
    coords = build.model.getCoordinateSet()
    assert coords.get("knee_angle").getDefaultLocked()
    assert not coords.contains("knee_tx")
    assert build.model.getConstraintSet().getSize() == 0
    for pose in ({"knee_rotation": 0.3, "ankle_angle": 0.4}, {"knee_rotation": -0.2}):
        state = _pose(build, body, pose)
        _assert_frames_match(build, body, state, _all_values(body, pose | {"knee_angle": -1.2}))


def test_conditional_and_moving_points_give_the_expected_path_length() -> None:
    body = _leg()
    build = build_model(body, _plan(body))
    points = build.model.getMuscles().get("vasti").getGeometryPath().getPathPointSet()
    kinds = [points.get(i).getConcreteClassName() for i in range(points.getSize())]
    assert kinds == ["PathPoint", "ConditionalPathPoint", "MovingPathPoint"]
    for knee in (-2.05, -1.6, -1.0, -0.7, 0.0, 0.15):
        pose = {"knee_angle": knee, "hip_flexion": 0.3}
        state = _pose(build, body, pose)
        length = build.model.getMuscles().get("vasti").getLength(state)
        expected = _expected_length(body, "vasti", _all_values(body, pose))
        assert length == pytest.approx(expected, abs=TOL), knee


def test_ellipsoid_and_turned_cylinder_wraps() -> None:
    body = _leg()
    build = build_model(body, _plan(body))
    thigh = build.model.getBodySet().get("thigh")
    ellipsoid = opensim.WrapEllipsoid.safeDownCast(thigh.getWrapObject("hip_ellipsoid"))
    assert ellipsoid is not None
    assert np.allclose(_vector(ellipsoid.get_dimensions()), (0.06, 0.1, 0.05))
    assert np.allclose(_vector(ellipsoid.get_xyz_body_rotation()), (0.0, 0.0, 0.3))
    assert ellipsoid.get_quadrant() == "-x"
    cylinder = opensim.WrapCylinder.safeDownCast(thigh.getWrapObject("knee_cylinder"))
    assert np.allclose(_vector(cylinder.get_xyz_body_rotation()), (0.0, 0.2, 0.0))
    # The glutes' straight line runs through the ellipsoid: the path goes round it.
    state = _pose(build, body, {})
    glutes = build.model.getMuscles().get("glutes")
    straight = _expected_length(body, "glutes", _all_values(body, {}))
    assert glutes.getGeometryPath().getCurrentPath(state).getSize() == 4  # two wrap points
    assert glutes.getLength(state) > straight + 1e-3
