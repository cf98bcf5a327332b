"""The pelvis's turn about the vertical (``workers.sim.pose.turn_about_up``, the env's
``info["turned"]``): exact on fixed frames, exactly 0 on a planar body, and as set on MyoLeg."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.sim.pose import pelvis_frame, pelvis_rotation, turn_about_up


def _about(axis: np.ndarray, angle: float) -> np.ndarray:
    """[3, 3] rotation by ``angle`` rad about the unit ``axis`` (Rodrigues)."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * k @ k


@pytest.mark.parametrize(("up_axis", "forward_axis"), [(2, 0), (1, 0)])
@pytest.mark.parametrize("angle", [0.3, -1.2, 2.5])
def test_a_frame_turned_about_the_vertical_turns_by_that_angle_however_it_leans(
    up_axis: int, forward_axis: int, angle: float
) -> None:
    start = pelvis_rotation(0.4, -0.3, 0.7, up_axis, forward_axis)  # pitched, listed, turned
    up = np.eye(3)[up_axis]
    assert turn_about_up(start, _about(up, angle) @ start, up_axis) == pytest.approx(angle)
    # tipping about any horizontal axis is no turn, however far
    horizontal = np.cross(up, np.array([0.6, 0.8, 0.0]) if up_axis == 2 else np.eye(3)[2])
    horizontal /= np.linalg.norm(horizontal)
    tipped = _about(horizontal, 1.4) @ start
    assert turn_about_up(start, tipped, up_axis) == pytest.approx(0.0, abs=1e-12)


def test_the_frame_of_a_pelvis_is_its_rotation() -> None:
    rotation = pelvis_rotation(0.2, 0.1, -0.5, 2, 0)
    np.testing.assert_allclose(pelvis_frame(rotation[:, 1], rotation[:, 0]), rotation)


@pytest.mark.parametrize("backend", ["mujoco", "opensim"])
def test_a_planar_body_never_turns(backend: str) -> None:
    env = MuscleEnv(load_scene("walk-2d"), backend)
    try:
        env.reset(seed=1)
        turned = []
        for _ in range(25):  # relaxed, it folds and pitches over
            _, _, terminated, truncated, info = env.step(np.zeros(env.action_space.shape))
            turned.append(info["turned"])
            if terminated or truncated:
                break
        assert turned == [0.0] * len(turned)  # exactly: a planar frame has exact zeros
    finally:
        env.close()


@pytest.mark.parametrize("turn", [0.4, -0.9])
def test_myolegs_pelvis_turned_after_the_reset_reads_as_that_turn(turn: float) -> None:
    env = MuscleEnv(load_scene("imitate-walk-3d"))
    try:
        env.reset(seed=2)
        start = env.clock.reference(0)
        pose = env.imitation.pose_of(start)
        env.sim.set_pose(dataclasses.replace(pose, pelvis_rotation=start.pelvis_rotation + turn))
        _, _, _, _, info = env.step(np.full(env.action_space.shape, 0.5))
        assert info["turned"] == pytest.approx(turn, abs=0.05)  # one 0.04 s step of motion
    finally:
        env.close()
