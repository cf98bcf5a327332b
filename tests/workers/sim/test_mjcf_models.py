"""MyoSuite MJCF loading, with real MuJoCo."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from gaitforge.workers.sim.mujoco.lock import lock_joints
from gaitforge.workers.sim.mujoco.mjcf_models import (
    FLOOR,
    MYOLEG_FOOT_GEOMS,
    ROOT_JOINT,
    STAND_KEY,
    elbow_spec,
    myoleg_spec,
    myosim_models_dir,
)
from gaitforge.workers.sim.mujoco.moment_arms import muscle_ids, muscle_spans
from mjcf_helpers import object_names, warning_counts


def test_myoleg_loads_and_steps_without_warnings() -> None:
    before = {p for p in myosim_models_dir().rglob("*")}
    spec = myoleg_spec()
    model = spec.compile()
    assert {p for p in myosim_models_dir().rglob("*")} == before  # nothing written
    assert len(muscle_ids(model)) == 80
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
    assert warning_counts(data) == {}
    assert data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number == 0
    assert np.isfinite(data.qpos).all()


def test_myoleg_carries_its_torso_upright_above_the_pelvis() -> None:
    """MyoSuite's walking MyoLeg weighs about 80 kg with its rigid torso; ours 75.2 kg, the
    torso's centre of mass above the pelvis, a little behind it, not off to a side."""
    model = myoleg_spec().compile()
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("stand").id)
    mujoco.mj_forward(model, data)
    assert model.body_subtreemass[model.body("root").id] == pytest.approx(75.2, abs=0.5)
    torso = data.xipos[model.body("torso").id] - data.xpos[model.body("pelvis").id]
    assert abs(torso[1]) < 0.01  # across (Y): centred
    assert -0.15 < torso[0] < 0.0  # forward (X): a little behind
    assert 0.2 < torso[2] < 0.4  # up (Z)


def test_myoleg_spec_is_fresh_each_call() -> None:
    a, b = myoleg_spec(), myoleg_spec()
    lock_joints(a, {"mtp_angle_r": 0.0})  # (a bare delete would break the keyframe)
    assert a.joint("mtp_angle_r") is None
    assert b.joint("mtp_angle_r") is not None
    assert b.compile().njnt == a.compile().njnt + 1


def test_myoleg_self_contacts_are_explicit_pairs() -> None:
    model = myoleg_spec(self_contacts=True).compile()
    assert model.npair == 26


def test_elbow_loads_with_six_muscles() -> None:
    model = elbow_spec().compile()
    assert len(muscle_ids(model)) == 6
    assert object_names(model, mujoco.mjtObj.mjOBJ_JOINT, model.njnt) == ["r_elbow_flex"]
    spans = muscle_spans(model)
    assert all(v == ["r_elbow_flex"] for v in spans.values())
