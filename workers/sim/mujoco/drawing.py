"""What a MuJoCo model shows of its state for drawing, recording and observing: each body's
frame in the world and each muscle's tendon path (``MujocoSimulator.body_frames``,
``muscle_paths``). Positions are as of the last kinematics pass: ``mj_step`` computes them at
the start of its last substep, so they lag the state by one timestep at most."""

from __future__ import annotations

import mujoco
import numpy as np
from gaitforge.workers.sim.base import BodyPose


def body_frames(model: mujoco.MjModel, data: mujoco.MjData) -> dict[str, BodyPose]:
    """Every body's position (m) and orientation (quaternion w, x, y, z) in the world, with
    the body it hangs from ("" for the world)."""
    names = [model.body(i).name or f"body{i}" for i in range(model.nbody)]
    return {
        names[i]: BodyPose(
            data.xpos[i].copy(),
            data.xquat[i].copy(),
            names[p] if (p := model.body_parentid[i]) else "",
        )
        for i in range(1, model.nbody)
    }


def muscle_paths(
    model: mujoco.MjModel, data: mujoco.MjData, muscle_names: list[str]
) -> dict[str, np.ndarray]:
    """Each actuator's tendon path points ([n, 3], m: sites and wrap tangent points, pulley
    markers dropped), by the names ``muscle_names`` gives the actuators in order; none for an
    actuator that pulls no tendon."""
    points = data.wrap_xpos.reshape(-1, 3)
    kinds = data.wrap_obj.ravel()
    paths = {}
    for i, name in enumerate(muscle_names):
        if int(model.actuator_trntype[i]) != int(mujoco.mjtTrn.mjTRN_TENDON):
            paths[name] = np.zeros((0, 3))
            continue
        tendon = model.actuator_trnid[i, 0]
        span = slice(data.ten_wrapadr[tendon], data.ten_wrapadr[tendon] + data.ten_wrapnum[tendon])
        paths[name] = points[span][kinds[span] != -2].copy()
    return paths
