"""Physics sanity for gait2d on MuJoCo: a passive collapse rests on the floor, and each
muscle alone moves its joints the anatomical way."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from gaitforge.workers.bodies import load_body
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.sim.mujoco.build import build_spec
from gaitforge.workers.sim.mujoco.lock import lock_joints
from gaitforge.workers.sim.mujoco.simulator import MujocoSimulator

# OpenSim's signs: hip_flexion + is flexion, knee_angle + is extension (its range is
# about -2.09 to 0.17), ankle_angle + is dorsiflexion.
EXPECTED = {
    "hamstrings": {"hip_flexion": -1, "knee_angle": -1},
    "bifemsh": {"knee_angle": -1},
    "glut_max": {"hip_flexion": -1},
    "iliopsoas": {"hip_flexion": +1},
    "rect_fem": {"hip_flexion": +1, "knee_angle": +1},
    "vasti": {"knee_angle": +1},
    "gastroc": {"ankle_angle": -1, "knee_angle": -1},
    "soleus": {"ankle_angle": -1},
    "tib_ant": {"ankle_angle": +1},
}
START_POSE = {"hip_flexion": 0.3, "knee_angle": -0.6, "ankle_angle": 0.0}


def test_passive_collapse_rests_on_the_floor_without_sinking_or_jitter() -> None:
    scene = load_scene("stand-2d")
    scene = scene.model_copy(update={"keep": scene.keep.model_copy(update={"contacts": "all"})})
    sim = MujocoSimulator(scene)
    sim.reset(seed=0)
    off = np.zeros(len(sim.muscle_names))
    for _ in range(300):  # 3 s at 100 Hz: falls, lands, settles
        assert sim.step(off, 0.01).ok
    m, d = sim.model, sim.data
    floor_penetration = []
    speeds = []
    for _ in range(100):  # 1 more second at rest
        assert sim.step(off, 0.01).ok
        depth = [-d.contact[i].dist for i in range(d.ncon)]
        floor_penetration.append(max(depth, default=0.0))
        speeds.append(np.abs(d.qvel).max())
    state = sim.state()
    assert state.pelvis_pos[1] < 0.3, "the body should have collapsed onto the floor"
    assert max(floor_penetration) < 0.01, "sank more than 1 cm into the floor"
    assert max(speeds[-50:]) < 0.05, f"still moving at rest: {max(speeds[-50:]):.3f}"
    lowest = min(
        d.geom_xpos[g][1] - m.geom_size[g][0]
        for g in range(m.ngeom)
        if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE
    )
    assert lowest > -0.01


def _held_model() -> tuple[mujoco.MjModel, mujoco.MjData]:
    """gait2d with the pelvis welded in the air and gravity off: only muscles act."""
    spec = build_spec(load_body("gait2d"))
    lock_joints(spec, {"pelvis_tx": 0.0, "pelvis_ty": 0.0, "pelvis_tilt": 0.0})
    spec.option.gravity = [0.0, 0.0, 0.0]
    model = spec.compile()
    return model, mujoco.MjData(model)


def _acceleration(excited: str | None, side: str) -> dict[str, float]:
    """Joint accelerations (rad/s^2) at START_POSE, at rest, with one muscle fully active."""
    model, data = _held_model()
    for dof, value in START_POSE.items():
        for s in "rl":
            data.joint(f"{dof}_{s}").qpos = value
    if excited is not None:
        data.act[model.actuator(excited).id] = 1.0
    mujoco.mj_forward(model, data)
    return {dof: float(data.joint(f"{dof}_{side}").qacc[0]) for dof in START_POSE}


@pytest.mark.parametrize("side", ["r", "l"])
@pytest.mark.parametrize("muscle", sorted(EXPECTED))
def test_single_muscle_moves_its_joints_the_anatomical_way(muscle: str, side: str) -> None:
    """The acceleration a fully active muscle adds to the passive one (pelvis held, no
    gravity), so that passive forces and joint limits do not mask it."""
    passive = _acceleration(None, side)
    active = _acceleration(f"{muscle}_{side}", side)
    for dof, sign in EXPECTED[muscle].items():
        added = active[dof] - passive[dof]
        assert np.sign(added) == sign, f"{muscle}_{side} accelerates {dof} by {added:+.1f}"
        assert abs(added) > 1.0, f"{muscle}_{side} barely acts on {dof}: {added:+.3f} rad/s^2"


def test_the_body_moves_on_past_its_roots_nominal_range() -> None:
    """gait2d's pelvis_tx has a nominal range of +-5 m (OpenSim's, never clamped); it is no
    wall: a body launched forward from 4.9 m passes 5.5 m. The root is never limited."""
    sim = MujocoSimulator(load_scene("walk-2d"))
    sim.reset(seed=0)
    m, d = sim.model, sim.data
    tx = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "pelvis_tx")
    d.qpos[m.jnt_qposadr[tx]] = 4.9
    d.qvel[m.jnt_dofadr[tx]] = 3.0
    mujoco.mj_forward(m, d)
    off = np.zeros(len(sim.muscle_names))
    for _ in range(30):  # 0.3 s
        assert sim.step(off, 0.01).ok
    assert d.qpos[m.jnt_qposadr[tx]] > 5.5
    for name in ("pelvis_tx", "pelvis_ty", "pelvis_tilt"):
        assert not m.jnt_limited[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)]
