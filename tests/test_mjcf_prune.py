"""MyoSuite MJCF loading and generic MjSpec pruning, with real MuJoCo."""

from __future__ import annotations

import logging

import mujoco
import numpy as np
import pytest

from workers.sim import mjcf_prune as prune
from workers.sim.mjcf_models import (
    FLOOR,
    MYOLEG_FOOT_GEOMS,
    MYOLEG_SAGITTAL_JOINTS,
    ROOT_JOINT,
    STAND_KEY,
    elbow_spec,
    myoleg_spec,
    myosim_models_dir,
)

logger = logging.getLogger(__name__)

OUT_OF_PLANE = [
    f"{j}_{s}" for s in "rl" for j in ("hip_adduction", "hip_rotation", "subtalar_angle")
]


@pytest.fixture(scope="module")
def myoleg_model() -> mujoco.MjModel:
    return myoleg_spec().compile()


def _names(model: mujoco.MjModel, obj: mujoco.mjtObj, n: int) -> list[str]:
    return [mujoco.mj_id2name(model, obj, i) for i in range(n)]


def _warnings(data: mujoco.MjData) -> dict[str, int]:
    return {
        mujoco.mjtWarning(i).name: int(data.warning[i].number)
        for i in range(len(data.warning))
        if data.warning[i].number
    }


# ----------------------------------------------------------------------------- models


def test_myoleg_loads_and_steps_without_warnings() -> None:
    before = {p for p in myosim_models_dir().rglob("*")}
    spec = myoleg_spec()
    model = spec.compile()
    assert {p for p in myosim_models_dir().rglob("*")} == before  # nothing written
    assert len(prune.muscle_ids(model)) == 80
    assert model.nu == 80 and model.ntendon == 80
    assert model.neq == 14  # knee/patella couplings
    assert model.jnt_type[model.joint(ROOT_JOINT).id] == mujoco.mjtJoint.mjJNT_FREE
    assert model.opt.gravity[2] < 0
    mesh = model.geom_type == mujoco.mjtGeom.mjGEOM_MESH
    assert mesh.sum() > 10
    assert not model.geom_contype[mesh].any() and not model.geom_conaffinity[mesh].any()

    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key(STAND_KEY).id)
    mujoco.mj_forward(model, data)
    assert np.abs(data.efc_pos[: data.ne]).max() < 1e-9  # couplings hold in "stand"
    fromto = np.zeros(6)
    floor = model.geom(FLOOR).id
    gaps = [
        mujoco.mj_geomDistance(model, data, floor, model.geom(g).id, 1.0, fromto)
        for g in MYOLEG_FOOT_GEOMS
    ]
    assert min(gaps) == pytest.approx(0.0, abs=2e-4)  # feet just touch the floor
    pelvis = data.xmat[model.body("pelvis").id].reshape(3, 3)
    assert pelvis[:, 0] @ [1, 0, 0] > 0.99  # faces +X
    assert data.xpos[model.body("femur_l").id][1] > data.xpos[model.body("femur_r").id][1]

    rng = np.random.default_rng(0)
    for _ in range(100):
        data.ctrl[:] = rng.uniform(0.0, 1.0, model.nu)
        mujoco.mj_step(model, data)
    assert _warnings(data) == {}
    assert data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number == 0
    assert np.isfinite(data.qpos).all()


def test_myoleg_spec_is_fresh_each_call() -> None:
    a, b = myoleg_spec(), myoleg_spec()
    prune.lock_joints(a, {"mtp_angle_r": 0.0})  # (a bare delete would break the keyframe)
    assert a.joint("mtp_angle_r") is None
    assert b.joint("mtp_angle_r") is not None
    assert b.compile().njnt == a.compile().njnt + 1


def test_myoleg_self_contacts_are_explicit_pairs() -> None:
    model = myoleg_spec(self_contacts=True).compile()
    assert model.npair == 26


def test_elbow_loads_with_six_muscles() -> None:
    model = elbow_spec().compile()
    assert len(prune.muscle_ids(model)) == 6
    assert _names(model, mujoco.mjtObj.mjOBJ_JOINT, model.njnt) == ["r_elbow_flex"]
    spans = prune.muscle_spans(model)
    assert all(v == ["r_elbow_flex"] for v in spans.values())


# ------------------------------------------------------------------------ lock_joints


def _poses_by_name(model: mujoco.MjModel, data: mujoco.MjData) -> dict[str, np.ndarray]:
    return {
        model.body(i).name: np.concatenate([data.xpos[i], data.xquat[i]])
        for i in range(1, model.nbody)
    }


def _quat_close(a: np.ndarray, b: np.ndarray) -> bool:
    return np.allclose(a[:3], b[:3], atol=1e-9) and (
        np.allclose(a[3:], b[3:], atol=1e-9) or np.allclose(a[3:], -b[3:], atol=1e-9)
    )


def test_lock_nonzero_keeps_world_pose_myoleg() -> None:
    values = {"knee_angle_r": 0.6, "hip_flexion_r": 0.3}
    ref_model = myoleg_spec().compile()
    ref_data = mujoco.MjData(ref_model)
    qpos = ref_model.qpos0.copy()
    for name, value in values.items():
        qpos[ref_model.jnt_qposadr[ref_model.joint(name).id]] = value
    prune._apply_couplings(ref_model, qpos)
    ref_data.qpos[:] = qpos
    mujoco.mj_kinematics(ref_model, ref_data)

    spec = myoleg_spec()
    removed = prune.lock_joints(spec, values)
    tibia = [
        "knee_angle_translation2_r",
        "knee_angle_translation1_r",
        "knee_angle_r",
        "knee_angle_rotation2_r",
        "knee_angle_rotation3_r",
    ]
    patella = [
        "knee_angle_beta_translation2_r",
        "knee_angle_beta_translation1_r",
        "knee_angle_beta_rotation1_r",
    ]
    assert set(removed) == {"hip_flexion_r", *tibia, *patella}
    model = spec.compile()
    assert model.neq == 7  # the right knee's couplings are gone
    assert model.nv == ref_model.nv - len(removed)
    data = mujoco.MjData(model)
    for j in range(model.njnt):  # same values for the joints that remain
        name = model.joint(j).name
        src = ref_model.jnt_qposadr[ref_model.joint(name).id]
        n = 7 if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE else 1
        data.qpos[model.jnt_qposadr[j] : model.jnt_qposadr[j] + n] = qpos[src : src + n]
    mujoco.mj_kinematics(model, data)
    got, want = _poses_by_name(model, data), _poses_by_name(ref_model, ref_data)
    assert got.keys() == want.keys()
    for body, pose in got.items():
        assert _quat_close(pose, want[body]), body
    assert len(spec.key(STAND_KEY).qpos) == model.nq  # keyframe rewritten


_TWO_HINGES = """
<mujoco>
  <compiler angle="degree"/>
  <worldbody>
    <body name="a" pos="0.1 0.2 0.3" euler="20 -30 45">
      <joint name="j1" type="hinge" axis="0 1 1" pos="0.05 0 0.02" range="-90 90"/>
      <joint name="j2" type="hinge" axis="1 0 0" pos="0 0.1 0" range="-90 90"/>
      <joint name="s" type="slide" axis="0 0 1" range="-1 1"/>
      <geom size="0.05" mass="1"/>
      <body name="b" pos="0 0 -0.4">
        <joint name="k" type="hinge" axis="0 1 0" pos="0 0 0.1"/>
        <joint name="k_follow" type="slide" axis="1 0 0"/>
        <geom size="0.05" mass="1"/>
      </body>
    </body>
  </worldbody>
  <equality>
    <joint joint1="k_follow" joint2="k" polycoef="0.01 0.02 0.03 0 0"/>
  </equality>
  <keyframe><key name="k0" qpos="0.1 0.2 0.05 0.3 0.0" ctrl=""/></keyframe>
</mujoco>
"""


def _world_poses(spec: mujoco.MjSpec, values: dict[str, float]) -> dict[str, np.ndarray]:
    model = spec.compile()
    data = mujoco.MjData(model)
    qpos = model.qpos0.copy()
    for name, value in values.items():
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if jid >= 0:
            qpos[model.jnt_qposadr[jid]] = value
    prune._apply_couplings(model, qpos)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    return _poses_by_name(model, data)


@pytest.mark.parametrize(
    "lock",
    [
        {"j1": 0.4},
        {"j1": 0.4, "j2": -0.7},
        {"j1": 0.4, "j2": -0.7, "s": 0.15},
        {"j2": 0.0},
        {"j1": 0.0, "s": 0.0},
        {"k": 0.8},
    ],
)
def test_lock_synthetic_keeps_world_pose(lock: dict[str, float]) -> None:
    state = {"j1": 0.4, "j2": -0.7, "s": 0.15, "k": 0.8}
    state.update(lock)
    want = _world_poses(mujoco.MjSpec.from_string(_TWO_HINGES), state)
    spec = mujoco.MjSpec.from_string(_TWO_HINGES)
    removed = prune.lock_joints(spec, lock)
    assert set(removed) == set(lock) | ({"k_follow"} if "k" in lock else set())
    got = _world_poses(spec, state)
    for body, pose in got.items():
        assert _quat_close(pose, want[body]), (body, pose, want[body])
    model = spec.compile()
    assert len(spec.key("k0").qpos) == model.nq


def test_lock_nonzero_after_free_joint_raises() -> None:
    spec = mujoco.MjSpec.from_string(_TWO_HINGES)
    with pytest.raises(ValueError, match="'j2'"):
        prune.lock_joints(spec, {"j2": 0.3})
    with pytest.raises(ValueError, match="'k_follow'"):
        prune.lock_joints(spec, {"k_follow": 0.01})
    with pytest.raises(KeyError):
        prune.lock_joints(spec, {"nope": 0.0})
    assert spec.compile().njnt == 5  # untouched after the failures


def test_lock_subtalar_and_mtp_myoleg() -> None:
    spec = myoleg_spec()
    before = prune.model_size(spec.compile())
    names = ["subtalar_angle_r", "subtalar_angle_l", "mtp_angle_r", "mtp_angle_l"]
    removed = prune.lock_joints(spec, dict.fromkeys(names, 0.0))
    assert sorted(removed) == sorted(names)
    model = spec.compile()
    after = prune.model_size(model)
    logger.info("MyoLeg before %s after subtalar+mtp lock %s", before, after)
    assert after["dofs"] == before["dofs"] - 4
    assert after["joints"] == before["joints"] - 4
    assert after["muscles"] == 80 and after["equalities"] == 14
    remaining = set(_names(model, mujoco.mjtObj.mjOBJ_JOINT, model.njnt))
    assert not remaining & set(names)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key(STAND_KEY).id)
    for _ in range(20):
        mujoco.mj_step(model, data)
    assert _warnings(data) == {}


# --------------------------------------------------------------------- remove_muscles


def test_remove_muscles_exactly_the_named() -> None:
    spec = myoleg_spec()
    model0 = spec.compile()
    spec.add_key(
        name="busy",
        qpos=model0.qpos0.tolist(),
        ctrl=np.linspace(0, 1, 80).tolist(),
        act=np.linspace(0, 1, model0.na).tolist(),
    )
    gone = ["glmin1_r", "piri_l", "soleus_r"]
    prune.remove_muscles(spec, gone)
    model = spec.compile()
    act0 = set(_names(model0, mujoco.mjtObj.mjOBJ_ACTUATOR, model0.nu))
    act1 = set(_names(model, mujoco.mjtObj.mjOBJ_ACTUATOR, model.nu))
    ten0 = set(_names(model0, mujoco.mjtObj.mjOBJ_TENDON, model0.ntendon))
    ten1 = set(_names(model, mujoco.mjtObj.mjOBJ_TENDON, model.ntendon))
    assert act0 - act1 == set(gone) and act1 <= act0
    assert ten0 - ten1 == {f"{n}_tendon" for n in gone} and ten1 <= ten0
    assert model.nsite < model0.nsite
    # collision geoms untouched
    assert (model.geom_contype > 0).sum() == (model0.geom_contype > 0).sum()
    kept = np.delete(np.linspace(0, 1, 80), [model0.actuator(n).id for n in gone])
    np.testing.assert_allclose(model.key("busy").ctrl, kept)
    assert model.key("busy").act.shape == (model.na,)
    with pytest.raises(KeyError):
        prune.remove_muscles(spec, ["glmin1_r"])


def test_remove_muscles_keeps_shared_path_points() -> None:
    xml = """
    <mujoco><worldbody>
      <site name="o"/><body pos="0 0 -0.5"><joint name="h" axis="0 1 0"/>
      <geom size="0.05" mass="1"/><geom name="wrap" type="cylinder" size="0.03 0.05"
            contype="0" conaffinity="0" mass="0" pos="0 0 0.5"/>
      <geom name="solid" size="0.03" pos="0.05 0 0.4"/>
      <site name="shared" pos="0.03 0 0.1"/><site name="only_a" pos="0.03 0 0.2"/>
      <site name="mid_a" pos="0.04 0 0.45"/>
      <site name="side" pos="0.1 0 0.5"/></body></worldbody>
    <tendon>
      <spatial name="ta"><site site="o"/><geom geom="wrap" sidesite="side"/>
        <site site="mid_a"/><geom geom="solid"/><site site="only_a"/></spatial>
      <spatial name="tb"><site site="o"/><site site="shared"/></spatial>
    </tendon>
    <actuator><muscle name="a" tendon="ta"/><muscle name="b" tendon="tb"/></actuator>
    </mujoco>"""
    spec = mujoco.MjSpec.from_string(xml)
    prune.remove_muscles(spec, ["a"])
    model = spec.compile()
    assert _names(model, mujoco.mjtObj.mjOBJ_SITE, model.nsite) == ["o", "shared"]
    geoms = _names(model, mujoco.mjtObj.mjOBJ_GEOM, model.ngeom)
    assert "wrap" not in geoms and "solid" in geoms  # "solid" collides and has mass


# ------------------------------------------------------------------ spans and planar


def test_muscle_spans_myoleg(myoleg_model: mujoco.MjModel) -> None:
    spans = prune.muscle_spans(myoleg_model)
    assert len(spans) == 80
    for side in "rl":
        for vastus in ("vasmed", "vaslat", "vasint"):
            assert spans[f"{vastus}_{side}"] == [f"knee_angle_{side}"]
        assert f"ankle_angle_{side}" in spans[f"soleus_{side}"]
        assert f"knee_angle_{side}" not in spans[f"soleus_{side}"]
        assert {f"knee_angle_{side}", f"ankle_angle_{side}"} <= set(spans[f"gasmed_{side}"])
        assert spans[f"bfsh_{side}"] == [f"knee_angle_{side}"]
        assert f"hip_flexion_{side}" in spans[f"recfem_{side}"]
    assert all(ROOT_JOINT not in v for v in spans.values())
    driven = {"knee_angle_beta_rotation1_r", "knee_angle_translation1_l"}
    assert all(not driven & set(v) for v in spans.values())
    assert spans == prune.muscle_spans(myoleg_model)  # seeded


def test_planar_muscles_myoleg(myoleg_model: mujoco.MjModel) -> None:
    names = _names(myoleg_model, mujoco.mjtObj.mjOBJ_ACTUATOR, myoleg_model.nu)
    sagittal = list(MYOLEG_SAGITTAL_JOINTS)
    # threshold test only: at qpos0 a few hip muscles lack a 5 mm sagittal arm ...
    at_rest = prune.planar_muscles(myoleg_model, sagittal, n_poses=1, out_of_plane_joints=())
    dropped_rest = [n for n in names if n not in at_rest]
    logger.info("planar (threshold, qpos0 only) drops %s", dropped_rest)
    assert dropped_rest and all(n.startswith(("add", "gl", "piri")) for n in dropped_rest)
    # ... but over the random poses all of them reach it somewhere
    over_poses = prune.planar_muscles(myoleg_model, sagittal, out_of_plane_joints=())
    assert set(at_rest) <= set(over_poses)

    kept = prune.planar_muscles(myoleg_model, sagittal)  # + ratio against all other joints
    dropped = [n for n in names if n not in kept]
    logger.info("planar (default: threshold + ratio) drops %s", dropped)
    assert kept == prune.planar_muscles(myoleg_model, sagittal, out_of_plane_joints=OUT_OF_PLANE)
    oop = (
        "addbrev",
        "addmagMid",
        "addmagProx",
        "glmed1",
        "glmin1",
        "glmin2",
        "glmin3",
        "perbrev",
        "perlong",
        "piri",
    )
    assert {f"{m}_{s}" for m in oop for s in "rl"} <= set(dropped)
    for keep in (
        "vasmed",
        "soleus",
        "gasmed",
        "tibant",
        "recfem",
        "glmax2",
        "iliacus",
        "bfsh",
        "semiten",
        "bflh",
        "psoas",
    ):
        assert f"{keep}_r" in kept and f"{keep}_l" in kept
    assert {n[:-2] for n in dropped if n.endswith("_r")} == {
        n[:-2] for n in dropped if n.endswith("_l")
    }  # mirrored poses: same verdict both sides
    with pytest.raises(KeyError):
        prune.planar_muscles(myoleg_model, ["nope"])


# -------------------------------------------------------------- contacts and model size


def test_restrict_contacts_feet_floor() -> None:
    spec = myoleg_spec(self_contacts=True)
    prune.restrict_contacts(spec, list(MYOLEG_FOOT_GEOMS), [FLOOR])
    model = spec.compile()
    assert model.npair == 0
    assert prune.model_size(model)["contact_pairs"] == len(MYOLEG_FOOT_GEOMS) * 1
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key(STAND_KEY).id)
    data.qpos[2] -= 0.02  # sink into the floor
    mujoco.mj_forward(model, data)
    assert data.ncon > 0
    feet = {model.geom(g).id for g in MYOLEG_FOOT_GEOMS}
    floor = model.geom(FLOOR).id
    for c in data.contact[: data.ncon]:
        assert {int(c.geom1), int(c.geom2)} & feet and floor in (c.geom1, c.geom2)
    with pytest.raises(KeyError):
        prune.restrict_contacts(spec, ["nope"], [FLOOR])


_OVERLAP = """
<mujoco>
  <option><flag {flag}/></option>
  <worldbody>
    <geom name="w0" type="sphere" size="1"/>
    <geom name="w1" type="sphere" size="1"/>
    <body name="A"><joint type="hinge"/><geom name="a0" size="1"/><geom name="a1" size="1"/>
      <body name="B"><joint type="hinge"/><geom name="b0" size="1"/>
        <geom name="b_off" size="1" contype="2" conaffinity="2"/>
        <body name="B_welded"><geom name="bw" size="1"/>
          <body name="C"><joint type="slide"/><geom name="c0" size="1"/></body>
        </body>
      </body>
    </body>
    <body name="D"><freejoint/><geom name="d0" size="1"/>
      <geom name="d_mesh_like" type="box" size="1 1 1" contype="2" conaffinity="1"/></body>
    <body name="E"><freejoint/><geom name="e0" size="1" contype="0" conaffinity="0"/></body>
  </worldbody>
  <contact>
    <exclude body1="A" body2="D"/>
    <pair geom1="a0" geom2="b0"/>
    <pair geom1="e0" geom2="w0"/>
    <pair geom1="w0" geom2="d0"/>
  </contact>
</mujoco>
"""


@pytest.mark.parametrize("flag", ['filterparent="enable"', 'filterparent="disable"'])
def test_contact_pairs_match_mujoco(flag: str) -> None:
    """Every geom overlaps every other: MuJoCo's contacts enumerate the allowed pairs."""
    model = mujoco.MjSpec.from_string(_OVERLAP.format(flag=flag)).compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    seen = {tuple(sorted((int(c.geom1), int(c.geom2)))) for c in data.contact[: data.ncon]}
    assert prune.model_size(model)["contact_pairs"] == len(seen)
    mask = prune.contact_pair_mask(model)
    dynamic = {(int(i), int(j)) for i, j in zip(*np.nonzero(mask), strict=True)}
    explicit = {
        tuple(sorted((int(a), int(b))))
        for a, b in zip(model.pair_geom1, model.pair_geom2, strict=True)
    }
    assert dynamic | explicit == seen


def test_model_size_consistent(myoleg_model: mujoco.MjModel) -> None:
    size = prune.model_size(myoleg_model)
    m = myoleg_model
    assert size["dofs"] == m.nv and size["joints"] == m.njnt and size["bodies"] == m.nbody
    assert size["tendons"] == m.ntendon and size["geoms"] == m.ngeom
    assert size["sites"] == m.nsite and size["muscles"] == 80
    assert 0 < size["wrap_objects"] <= m.ngeom
    wrap_geoms = {
        int(o)
        for t, o in zip(m.wrap_type, m.wrap_objid, strict=True)
        if t in (int(mujoco.mjtWrap.mjWRAP_SPHERE), int(mujoco.mjtWrap.mjWRAP_CYLINDER))
    }
    assert size["wrap_objects"] == len(wrap_geoms)
    # 20 leg collision geoms (contype 1, conaffinity 0) against the floor only
    assert size["contact_pairs"] == 20


def test_planar_pipeline_size_report() -> None:
    """Lock out-of-plane joints, drop out-of-plane muscles: logs the size at each step."""
    spec = myoleg_spec()
    sizes = {"full": prune.model_size(spec.compile())}
    prune.lock_joints(
        spec,
        dict.fromkeys([f"{j}_{s}" for s in "rl" for j in ("subtalar_angle", "mtp_angle")], 0.0),
    )
    sizes["locked subtalar+mtp"] = prune.model_size(spec.compile())
    model = spec.compile()
    kept = prune.planar_muscles(
        model,
        list(MYOLEG_SAGITTAL_JOINTS),
        out_of_plane_joints=[j for j in OUT_OF_PLANE if "subtalar" not in j],
    )
    names = _names(model, mujoco.mjtObj.mjOBJ_ACTUATOR, model.nu)
    prune.remove_muscles(spec, [n for n in names if n not in kept])
    prune.lock_joints(
        spec,
        dict.fromkeys([f"{j}_{s}" for s in "rl" for j in ("hip_adduction", "hip_rotation")], 0.0),
    )
    prune.restrict_contacts(spec, list(MYOLEG_FOOT_GEOMS), [FLOOR])
    model = spec.compile()
    sizes["planar"] = prune.model_size(model)
    for label, size in sizes.items():
        logger.info("%s: %s", label, size)
    assert sizes["planar"]["muscles"] == len(kept) < 80
    assert sizes["planar"]["dofs"] == 34 - 8
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key(STAND_KEY).id)
    for _ in range(50):
        data.ctrl[:] = 0.2
        mujoco.mj_step(model, data)
    assert _warnings(data) == {}
