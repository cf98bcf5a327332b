"""The OpenSim model builder, and static agreement of its models with the MuJoCo build.

Both simulators are built from the same neutral body (``gait2d``) and compared at the same
poses (every dof its default, then the values below):

* total mass, and every segment origin in the ground frame at the default pose (1e-9 m);
* muscle-tendon length within 1 % at every pose;
* moment arm (``-dL/dq``; OpenSim ``computeMomentArm``, MuJoCo ``-ten_J``) about each dof
  the muscle spans within ``max(1 % of the muscle's peak |moment arm| about that dof over
  the poses, 0.5 mm)`` at every pose: a relative rule alone would demand sub-micrometre
  agreement where a moment arm crosses zero;
* each wrapped muscle is wrapped at some pose and straight at another, the same in both;
* isometric force at optimal fibre length (activation 1, zero speed, each simulator posed
  so that its own path length is ``tendon_slack + l_opt cos(pennation)``) within 5 %.
  OpenSim's rigid-tendon Millard muscle gives ``F_max cos(pennation)`` along the tendon;
  MuJoCo's muscle has no pennation, so ``mujoco.build`` sets its force to the same
  projection (without it, ``bifemsh`` and ``soleus`` were 7.9 % and 9.4 % apart).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import cache

import mujoco
import numpy as np
import opensim
import pytest
from gaitforge.workers.bodies import load_body
from gaitforge.workers.bodies.schema import Body
from gaitforge.workers.bodies.topology import topology_for
from gaitforge.workers.scenes import load_scene, plan_pruning
from gaitforge.workers.scenes.prune import PrunePlan
from gaitforge.workers.sim.mujoco.build import build_spec
from gaitforge.workers.sim.opensim.build import OpenSimBuild, build_model

opensim.Logger.setLevelString("error")

POSES: list[dict[str, float]] = [
    {},
    {"hip_flexion_r": 0.5, "knee_angle_r": -0.5, "ankle_angle_r": 0.2},
    {"hip_flexion_l": -0.3, "knee_angle_l": -1.2, "ankle_angle_l": -0.4},
    {"hip_flexion_r": 1.2, "knee_angle_r": -1.8, "ankle_angle_r": 0.3, "knee_angle_l": 0.05},
    {"hip_flexion_r": -0.4, "knee_angle_r": -0.1, "ankle_angle_r": -0.5, "hip_flexion_l": 0.9},
    {"hip_flexion_l": 1.5, "knee_angle_l": -2.0, "pelvis_tilt": 0.2, "lumbar_extension": 0.1},
]
LEN_TOL = 0.01
ARM_REL, ARM_ABS = 0.01, 0.0005  # of the peak |moment arm|; m
FORCE_TOL = 0.05


def _body() -> Body:
    return load_body("gait2d")


def _keep_all(body: Body) -> PrunePlan:
    return PrunePlan(
        kept_dofs=body.dof_names,
        locked_dofs={},
        kept_muscles=[m.name for m in body.muscles],
        removed_muscles={},
        contact_geoms=[c.name for c in body.contact_spheres],
        obstacles=0,
    )


def _plan(scene: str, **keep: object) -> PrunePlan:
    s = load_scene(scene)
    if keep:
        s = s.model_copy(update={"keep": s.keep.model_copy(update=keep)})
    return plan_pruning(s, topology_for("gait2d"))


def _joint_types(build: OpenSimBuild) -> dict[str, str]:
    joints = build.model.getJointSet()
    return {
        joints.get(i).getName(): joints.get(i).getConcreteClassName()
        for i in range(joints.getSize())
    }


class _Pair:
    """The same body built for both simulators, posed together."""

    def __init__(self, body: Body, plan: PrunePlan | None = None) -> None:
        self.body = body
        self.build = build_model(body, plan or _keep_all(body))
        self.state = self.build.model.initSystem()
        self.coords = self.build.model.getCoordinateSet()
        self.mj = build_spec(body).compile()
        self.data = mujoco.MjData(self.mj)

    def jid(self, name: str) -> int:
        return mujoco.mj_name2id(self.mj, mujoco.mjtObj.mjOBJ_JOINT, name)

    def pose(self, values: dict[str, float]) -> None:
        """Every dof to its default, then ``values``; position stage in both."""
        for name in self.body.dof_names:
            q = values.get(name, self.body.dof(name).default)
            self.coords.get(name).setValue(self.state, q, False)
            self.data.qpos[self.mj.jnt_qposadr[self.jid(name)]] = q
        self.build.model.realizePosition(self.state)
        mujoco.mj_fwdPosition(self.mj, self.data)

    def tendon_jacobian(self) -> np.ndarray:
        """``data.ten_J`` dense (ntendon, nv), sparse storage or not."""
        m, d = self.mj, self.data
        if hasattr(m, "ten_J_rownnz"):
            dense = np.zeros((m.ntendon, m.nv))
            mujoco.mju_sparse2dense(dense, d.ten_J, m.ten_J_rownnz, m.ten_J_rowadr, m.ten_J_colind)
            return dense
        return np.asarray(d.ten_J).reshape(m.ntendon, m.nv)


@cache
def _pair() -> _Pair:
    return _Pair(_body())


@cache
def _geometry() -> dict[str, dict[str, np.ndarray]]:
    """Per muscle: lengths (pose,), arms (pose, spanned dof, [opensim, mujoco]), wrapped."""
    pair, body = _pair(), _body()
    out: dict[str, dict[str, list]] = {
        m.name: {"len": [], "arm": [], "wrapped": []} for m in body.muscles
    }
    for pose in POSES:
        pair.pose(pose)
        jac = pair.tendon_jacobian()
        for m in body.muscles:
            om = pair.build.model.getMuscles().get(m.name)
            tid = mujoco.mj_name2id(pair.mj, mujoco.mjtObj.mjOBJ_TENDON, m.name)
            rec = out[m.name]
            rec["len"].append([om.getLength(pair.state), pair.data.ten_length[tid]])
            rec["arm"].append(
                [
                    [
                        om.computeMomentArm(pair.state, pair.coords.get(dof)),
                        -jac[tid, pair.mj.jnt_dofadr[pair.jid(dof)]],
                    ]
                    for dof in body.dofs_spanned(m)
                ]
            )
            n_os = om.getGeometryPath().getCurrentPath(pair.state).getSize()
            rec["wrapped"].append(
                [n_os > len(m.points), pair.data.ten_wrapnum[tid] > len(m.points)]
            )
    return {k: {f: np.array(v) for f, v in rec.items()} for k, rec in out.items()}


# ---------------------------------------------------------------- building and pruning


def test_walk_2d_builds_with_every_muscle() -> None:
    plan = _plan("walk-2d")
    build = build_model(_body(), plan)
    model = build.model
    state = model.initSystem()
    assert model.getMuscles().getSize() == 18 == len(plan.kept_muscles)
    coords = [model.getCoordinateSet().get(i).getName() for i in range(model.getNumCoordinates())]
    assert sorted(coords) == sorted(["pelvis_tx", "pelvis_ty", "pelvis_tilt", *plan.kept_dofs])
    assert _joint_types(build)["ground_pelvis"] == "PlanarJoint"
    assert _joint_types(build)["back"] == "WeldJoint"  # lumbar locked by the scene
    assert build.controller.getName() == "excitations"
    functions = build.controller.get_ControlFunctions()
    assert functions.getSize() == 18
    assert opensim.Constant.safeDownCast(functions.get(0)).calcValue(opensim.Vector(1, 0.0)) == 0
    assert build.foot_forces == {
        "foot_right": ["contact_r_heel", "contact_r_toe"],
        "foot_left": ["contact_l_heel", "contact_l_toe"],
    }
    assert build.obstacle_geometry == []
    assert model.getGravity().get(1) == pytest.approx(-9.81)
    assert model.getTotalMass(state) == pytest.approx(_body().total_mass)


def test_locked_knees_are_welds_at_their_value() -> None:
    plan = _plan(
        "walk-2d",
        joints=["hip_flexion_r", "ankle_angle_r", "hip_flexion_l", "ankle_angle_l"],
        lock_at={"knee_angle_r": -0.5},
    )
    assert plan.locked_dofs["knee_angle_r"] == -0.5
    build = build_model(_body(), plan)
    types = _joint_types(build)
    assert types["knee_r"] == types["knee_l"] == types["back"] == "WeldJoint"
    muscles = {build.model.getMuscles().get(i).getName() for i in range(16 - 2)}
    assert not {"vasti_r", "vasti_l", "bifemsh_r", "bifemsh_l"} & muscles
    assert build.model.getMuscles().getSize() == 14
    state = build.model.initSystem()
    # The weld carries the locked angle: the ankle sits where a knee at -0.5 rad puts it.
    pair = _pair()
    pair.pose({"knee_angle_r": -0.5})
    for name, knee in (("talus_r", -0.5), ("talus_l", 0.0)):
        build.model.realizePosition(state)
        p = build.model.getBodySet().get(name).getPositionInGround(state)
        mj = pair.data.xpos[mujoco.mj_name2id(pair.mj, mujoco.mjtObj.mjOBJ_BODY, name)]
        assert np.allclose([p.get(i) for i in range(3)], mj, atol=1e-9), (name, knee)


def test_obstacles_touch_every_kept_sphere() -> None:
    plan = _plan("obstacles-2d")
    build = build_model(_body(), plan)
    assert build.obstacle_geometry == [f"obstacle_{i}" for i in range(10)]
    geometry = build.model.getContactGeometrySet()
    for name in build.obstacle_geometry:
        sphere = opensim.ContactSphere.safeDownCast(geometry.get(name))
        assert sphere.getFrame().getName() == "ground"
        assert sphere.get_location().get(0) == -100.0
    # An obstacle under the right heel of a body held 1 m up pushes that heel only.
    obstacle = opensim.ContactSphere.safeDownCast(geometry.get("obstacle_9"))
    state = build.model.initSystem()
    build.model.getCoordinateSet().get("pelvis_ty").setValue(state, 2.0)
    heel = build.model.getContactGeometrySet().get("r_heel")
    centre = heel.getFrame().findStationLocationInGround(state, heel.get_location())
    # Not concentric with the heel: Simbody finds no contact between concentric spheres.
    obstacle.set_location(opensim.Vec3(centre.get(0), centre.get(1) - 0.08, centre.get(2)))
    state = build.model.initSystem()
    build.model.getCoordinateSet().get("pelvis_ty").setValue(state, 2.0)
    build.model.realizeDynamics(state)
    for foot, forces in build.foot_forces.items():
        for name in forces:
            values = build.model.getForceSet().get(name).getRecordValues(state)
            up = values.get(1)  # vertical force on the sphere's body
            assert (up > 1.0) == (name == "contact_r_heel"), (foot, name, up)
    assert len(build_model(_body(), _plan("walk-2d"), obstacles=3).obstacle_geometry) == 3
    build.model.initSystem()


def test_joint_limits_in_opensim_units() -> None:
    build = build_model(_body(), _plan("walk-2d"))
    clf = opensim.CoordinateLimitForce.safeDownCast(
        build.model.getForceSet().get("hip_flexion_r_limit")
    )
    assert clf.get_upper_limit() == pytest.approx(120.0, abs=1e-3)  # deg
    assert clf.get_lower_limit() == pytest.approx(-30.0, abs=1e-3)
    assert clf.get_upper_stiffness() == pytest.approx(20.0, rel=1e-3)  # N m/deg
    assert clf.get_damping() == pytest.approx(0.25, rel=1e-3)  # N m s/deg
    assert clf.get_transition() == pytest.approx(10.0, abs=1e-3)  # deg


def test_tilted_and_custom_joints_match_mujoco() -> None:
    """Hinges off the Z axis (PinJoint with turned frames) and a 5-dof root (CustomJoint)."""
    raw = _body().model_dump()
    root = raw["joints"][0]
    root["dofs"].insert(
        2, {"name": "pelvis_tz", "type": "slide", "axis": (0, 0, 1), "range": (-1, 1)}
    )
    root["dofs"].insert(
        3, {"name": "pelvis_list", "type": "hinge", "axis": (1, 0, 0), "range": (-1, 1)}
    )
    for joint in raw["joints"]:
        if joint["name"] in {"knee_r", "ankle_l"}:
            joint["dofs"][0]["axis"] = (0.6, 0.0, 0.8)
        if joint["name"] == "hip_r":
            joint["dofs"][0]["axis"] = (1.0, 0.0, 0.0)
    pair = _Pair(Body.model_validate(raw))
    assert _joint_types(pair.build)["ground_pelvis"] == "CustomJoint"
    values = {"pelvis_tz": 0.1, "pelvis_list": 0.3, "pelvis_tilt": -0.4, "hip_flexion_r": 0.7}
    pair.pose(values | {"knee_angle_r": -0.9, "ankle_angle_l": 0.4, "knee_angle_l": -0.3})
    bodies = pair.build.model.getBodySet()
    for seg in pair.body.segments:
        transform = bodies.get(seg.name).getTransformInGround(pair.state)
        bid = mujoco.mj_name2id(pair.mj, mujoco.mjtObj.mjOBJ_BODY, seg.name)
        p, r = transform.p(), transform.R()
        assert np.allclose([p.get(i) for i in range(3)], pair.data.xpos[bid], atol=1e-9), seg.name
        rot = np.array([[r.get(i, j) for j in range(3)] for i in range(3)])
        assert np.allclose(rot, pair.data.xmat[bid].reshape(3, 3), atol=1e-9), seg.name


# ------------------------------------------------------------ agreement with MuJoCo


def test_total_mass_and_default_segment_origins() -> None:
    pair, body = _pair(), _body()
    assert pair.build.model.getTotalMass(pair.state) == pytest.approx(
        float(pair.mj.body_mass.sum())
    )
    pair.pose({})
    mujoco.mj_kinematics(pair.mj, pair.data)
    for seg in body.segments:
        p = pair.build.model.getBodySet().get(seg.name).getPositionInGround(pair.state)
        bid = mujoco.mj_name2id(pair.mj, mujoco.mjtObj.mjOBJ_BODY, seg.name)
        assert np.allclose([p.get(i) for i in range(3)], pair.data.xpos[bid], atol=1e-9), seg.name


@pytest.mark.parametrize("muscle", [m.name for m in load_body("gait2d").muscles])
def test_length_and_moment_arms(muscle: str) -> None:
    rec = _geometry()[muscle]
    os_len, mj_len = rec["len"].T
    err = np.abs(os_len - mj_len) / mj_len
    assert err.max() <= LEN_TOL, f"{muscle}: length off by {err.max():.2%}"
    dofs = _body().dofs_spanned(_body().muscles[[m.name for m in _body().muscles].index(muscle)])
    for k, dof in enumerate(dofs):
        os_arm, mj_arm = rec["arm"][:, k, 0], rec["arm"][:, k, 1]
        tol = max(ARM_REL * np.abs(mj_arm).max(), ARM_ABS)
        worst = np.abs(os_arm - mj_arm).max()
        assert worst <= tol, f"{muscle} about {dof}: {worst * 1e3:.2f} mm > {tol * 1e3:.2f} mm"


def test_wraps_engage_alike() -> None:
    for m in _body().muscles:
        wrapped = _geometry()[m.name]["wrapped"]
        assert np.array_equal(wrapped[:, 0], wrapped[:, 1]), m.name
        if m.wraps:  # the poses exercise both sides of every wrap
            assert wrapped[:, 0].any() and not wrapped[:, 0].all(), m.name


def _solve(length: Callable[[float], float], target: float, lo: float, hi: float) -> float | None:
    """A ``q`` in ``[lo, hi]`` with ``length(q) == target`` (grid, then bisection), or None."""
    grid = np.linspace(lo, hi, 101)
    sign = np.sign([length(q) - target for q in grid])
    crossings = np.nonzero(sign[:-1] != sign[1:])[0]
    if not len(crossings):
        return None
    a, b = grid[crossings[0]], grid[crossings[0] + 1]
    sa = sign[crossings[0]]
    for _ in range(40):
        mid = 0.5 * (a + b)
        if np.sign(length(mid) - target) == sa:
            a = mid
        else:
            b = mid
    return 0.5 * (a + b)


def _isometric(muscle: str) -> tuple[float, float]:
    """(OpenSim, MuJoCo) tendon force at optimal fibre length, full activation, at rest."""
    pair, body = _pair(), _body()
    m = next(x for x in body.muscles if x.name == muscle)
    target = m.tendon_slack_length + m.optimal_fiber_length * math.cos(m.pennation_angle)
    om = pair.build.model.getMuscles().get(muscle)
    tid = mujoco.mj_name2id(pair.mj, mujoco.mjtObj.mjOBJ_TENDON, muscle)

    def os_length(dof: str, q: float) -> float:
        pair.pose({dof: q})
        return om.getLength(pair.state)

    def mj_length(dof: str, q: float) -> float:
        pair.pose({dof: q})
        return float(pair.data.ten_length[tid])

    for dof in body.dofs_spanned(m):
        spec = body.dof(dof)
        lo, hi = spec.limit.range if spec.limit else spec.range
        q_os = _solve(lambda q, d=dof: os_length(d, q), target, lo, hi)
        q_mj = _solve(lambda q, d=dof: mj_length(d, q), target, lo, hi)
        if q_os is not None and q_mj is not None:
            break
    else:
        pytest.fail(f"{muscle}: no pose puts the fibre at optimal length")
    pair.pose({dof: q_os})
    om.setActivation(pair.state, 1.0)
    pair.build.model.realizeDynamics(pair.state)
    assert om.getNormalizedFiberLength(pair.state) == pytest.approx(1.0, abs=1e-6)
    f_os = om.getTendonForce(pair.state)
    pair.pose({dof: q_mj})
    aid = mujoco.mj_name2id(pair.mj, mujoco.mjtObj.mjOBJ_ACTUATOR, muscle)
    pair.data.qvel[:] = 0.0
    pair.data.act[:] = 0.0
    pair.data.act[aid] = 1.0
    mujoco.mj_forward(pair.mj, pair.data)
    return f_os, -float(pair.data.actuator_force[aid])


@pytest.mark.parametrize(
    "muscle",
    [m.name for m in load_body("gait2d").muscles if m.name.endswith("_r")],
)
def test_isometric_force_at_optimal_length(muscle: str) -> None:
    f_os, f_mj = _isometric(muscle)
    m = next(x for x in _body().muscles if x.name == muscle)
    assert f_os == pytest.approx(m.max_isometric_force * math.cos(m.pennation_angle), rel=1e-4)
    assert f_os == pytest.approx(f_mj, rel=FORCE_TOL), f"{muscle}: {f_os:.1f} N vs {f_mj:.1f} N"
