"""``task.max_pelvis_tilt``: a pelvis leaning past it ends the episode as a fall, at the
first control step past it, while the pelvis is still above ``min_pelvis_height``."""

from __future__ import annotations

import numpy as np
import pytest
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.scenes.spec import Task


def test_a_pelvis_leaning_past_the_bound_ends_the_episode_as_a_fall() -> None:
    scene = load_scene("walk-3d")
    bound = 0.3
    task = scene.task.model_copy(update={"max_pelvis_tilt": bound})
    env = MuscleEnv(scene.model_copy(update={"task": task}))
    env.reset(seed=0)
    up = env.sim.up_axis
    tilts = []
    for _ in range(env.scene.steps_per_episode):
        _, _, terminated, truncated, info = env.step(np.full(env.action_space.shape, 0.5))
        state = env.sim.state()
        tilts.append(float(np.arccos(np.clip(state.pelvis_up[up], -1.0, 1.0))))
        if terminated or truncated:
            break
    env.close()
    assert terminated and info["fell"], "the standing pose with no policy should topple"
    assert tilts[-1] > bound and all(t <= bound for t in tilts[:-1])
    assert float(state.pelvis_pos[up]) > task.min_pelvis_height


def test_a_reach_task_has_no_pelvis_to_lean() -> None:
    with pytest.raises(ValueError, match="max_pelvis_tilt"):
        Task(kind="reach", reach_dof="elbow", reach_range=(0.1, 0.5), max_pelvis_tilt=0.5)
