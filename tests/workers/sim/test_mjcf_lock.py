"""Locking joints of an MjSpec, with real MuJoCo."""

from __future__ import annotations

import logging

import mujoco
import numpy as np
import pytest
from gaitforge.workers.sim.mujoco.contacts import model_size
from gaitforge.workers.sim.mujoco.lock import coupled_qpos, lock_joints
from gaitforge.workers.sim.mujoco.mjcf_models import STAND_KEY, myoleg_spec
from mjcf_helpers import object_names, warning_counts

logger = logging.getLogger(__name__)


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
    qpos = coupled_qpos(ref_model, qpos)
    ref_data.qpos[:] = qpos
    mujoco.mj_kinematics(ref_model, ref_data)

    spec = myoleg_spec()
    removed = lock_joints(spec, values)
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
    qpos = coupled_qpos(model, qpos)
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
    removed = lock_joints(spec, lock)
    assert set(removed) == set(lock) | ({"k_follow"} if "k" in lock else set())
    got = _world_poses(spec, state)
    for body, pose in got.items():
        assert _quat_close(pose, want[body]), (body, pose, want[body])
    model = spec.compile()
    assert len(spec.key("k0").qpos) == model.nq


def test_lock_nonzero_after_free_joint_raises() -> None:
    spec = mujoco.MjSpec.from_string(_TWO_HINGES)
    with pytest.raises(ValueError, match="'j2'"):
        lock_joints(spec, {"j2": 0.3})
    with pytest.raises(ValueError, match="'k_follow'"):
        lock_joints(spec, {"k_follow": 0.01})
    with pytest.raises(KeyError):
        lock_joints(spec, {"nope": 0.0})
    assert spec.compile().njnt == 5  # untouched after the failures


def test_lock_subtalar_and_mtp_myoleg() -> None:
    spec = myoleg_spec()
    before = model_size(spec.compile())
    names = ["subtalar_angle_r", "subtalar_angle_l", "mtp_angle_r", "mtp_angle_l"]
    removed = lock_joints(spec, dict.fromkeys(names, 0.0))
    assert sorted(removed) == sorted(names)
    model = spec.compile()
    after = model_size(model)
    logger.info("MyoLeg before %s after subtalar+mtp lock %s", before, after)
    assert after["dofs"] == before["dofs"] - 4
    assert after["joints"] == before["joints"] - 4
    assert after["muscles"] == 80 and after["equalities"] == 14
    remaining = set(object_names(model, mujoco.mjtObj.mjOBJ_JOINT, model.njnt))
    assert not remaining & set(names)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key(STAND_KEY).id)
    for _ in range(20):
        mujoco.mj_step(model, data)
    assert warning_counts(data) == {}
