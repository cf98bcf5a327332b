"""Touch detection on obstacle scenes: ``MuscleEnv.touching_obstacle()`` says whether a
foot's contact sphere is in an obstacle sphere (the evaluation's touched_rate,
obstacle_contact_steps and first_obstacle_touch_s come from it); no reward term charges it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.rewards import TERMS
from gaitforge.workers.scenes import load_scene, scene_fields
from gaitforge.workers.scenes.spec import Scene


def obstacle_scene(tmp_path: Path, x_range: list[float], name: str) -> Scene:
    """obstacles-2d for 0.3 s with its 10 spheres, each 10 cm, centred on the ground within
    ``x_range`` (m ahead of the start)."""
    data = scene_fields("obstacles-2d")
    data.update(name=name, episode_s=0.3)
    data["obstacles"].update(x_range=x_range, radius_range=[0.1, 0.1], height_range=[0, 0])
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data))
    return load_scene(path)


def touches(scene: Scene) -> list[bool | None]:
    """Whether a foot touches an obstacle at the end of each step of one episode, actions
    all zero; each step's reward terms are the scene's own, none for a touch."""
    env = MuscleEnv(scene)
    env.reset(seed=0)
    seen = []
    for _ in range(scene.steps_per_episode):
        _, _, terminated, truncated, info = env.step(np.zeros(env.action_space.shape))
        assert set(TERMS) <= set(info["reward_terms"]) and "obstacle_touch" not in TERMS
        seen.append(env.touching_obstacle())
        if terminated or truncated:
            break
    return seen


def test_spheres_under_the_feet_are_touched_and_spheres_far_ahead_are_not(
    tmp_path: Path,
) -> None:
    under_the_feet = touches(obstacle_scene(tmp_path, [0.0, 0.0], "under"))
    assert under_the_feet and all(touch is True for touch in under_the_feet)
    far_ahead = touches(obstacle_scene(tmp_path, [20.0, 30.0], "ahead"))
    assert far_ahead and all(touch is False for touch in far_ahead)


def test_a_scene_without_obstacles_has_nothing_to_touch() -> None:
    assert set(touches(load_scene("walk-2d").model_copy(update={"episode_s": 0.05}))) == {None}
