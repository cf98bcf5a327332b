"""The pelvis's assist (``task.assist``) on real MuJoCo MyoLeg: the hold keeps a body whose
reflexes hold its standing pose upright where it would topple, the push moves it forward and
only forward, and bad gains are refused at load."""

from __future__ import annotations

import numpy as np
import pytest
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.spec_io import SpecError

HOLD = {"upright_kp": 400.0, "upright_kd": 40.0}


def standing_still(assist: dict | None, seconds: float) -> tuple[float, bool, np.ndarray]:
    """MyoLeg on walk-3d with joint-target actions held at the standing pose (the reflex layer
    keeps it), for ``seconds`` or until it falls, with ``assist``: (the pelvis's tilt from
    upright in rad at the end, whether it fell, the pelvis's displacement [3] in m)."""
    overrides: dict = {"action.kind": "joint_targets", "control_hz": 25}
    if assist is not None:
        overrides["task.assist"] = assist
    env = MuscleEnv(load_scene("walk-3d", overrides))
    env.reset(seed=0)
    start = env.sim.state().pelvis_pos
    fell = False
    for _ in range(round(seconds * 25)):
        _, _, fell, _, info = env.step(np.full(env.action_space.shape, 0.5))
        assert info["health"] == "ok"
        if fell:
            break
    state = env.sim.state()
    tilt = float(np.arccos(np.clip(state.pelvis_up[env.sim.up_axis], -1.0, 1.0)))
    return tilt, fell, state.pelvis_pos - start


def test_the_hold_keeps_a_toppling_pelvis_upright() -> None:
    free_tilt, free_fell, _ = standing_still(None, 2.0)
    held_tilt, held_fell, _ = standing_still(HOLD, 2.0)
    assert free_fell and free_tilt > 0.5
    assert not held_fell and held_tilt < 0.2


def test_the_push_moves_the_held_body_forward_along_the_forward_axis_only() -> None:
    env = MuscleEnv(load_scene("walk-3d"))
    forward, up = env.sim.forward_axis, env.sim.up_axis
    across = 3 - forward - up
    _, _, held = standing_still(HOLD, 0.8)
    _, _, pushed = standing_still({**HOLD, "propel_kv": 400.0}, 0.8)
    assert abs(held[forward]) < 0.2
    assert pushed[forward] > held[forward] + 0.4
    assert abs(pushed[across] - held[across]) < 0.2 * (pushed[forward] - held[forward])


@pytest.mark.parametrize(
    ("scene", "overrides", "named"),
    [
        ("walk-3d", {"task.target_speed": None, "task.assist.propel_kv": 100.0}, "propel_kv"),
        ("walk-2d", {"backends": ["mujoco", "opensim"], "task.assist.upright_kp": 1.0}, "assist"),
        ("elbow-reach", {"task.assist.upright_kp": 1.0}, "assist"),
        ("walk-3d", {"task.assist.upright_kd": -1.0}, "upright_kd"),
        ("walk-3d", {"task.assist.pull": 1.0}, "pull"),
    ],
)
def test_bad_assists_are_refused_at_load(scene: str, overrides: dict, named: str) -> None:
    with pytest.raises(SpecError, match=named):
        load_scene(scene, overrides)
