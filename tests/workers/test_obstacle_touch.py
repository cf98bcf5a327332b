"""The ``obstacle_touch`` reward term: a scene may charge every control step that ends with a
foot in an obstacle sphere; a scene without obstacles may not weigh it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.scenes import load_scene, scene_fields
from gaitforge.workers.scenes.spec import Scene


def obstacle_scene(
    tmp_path: Path, x_range: list[float], name: str, touch_weight: float = 0.0
) -> Scene:
    """obstacles-2d for 0.3 s with its 10 spheres, each 10 cm, centred on the ground within
    ``x_range`` (m ahead of the start), the obstacle_touch term at ``touch_weight``."""
    data = scene_fields("obstacles-2d")
    data.update(name=name, episode_s=0.3)
    data["obstacles"].update(x_range=x_range, radius_range=[0.1, 0.1], height_range=[0, 0])
    data["task"]["reward"]["obstacle_touch"] = touch_weight
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data))
    return load_scene(path)


def touch_terms(scene: Scene) -> list[float]:
    """The weighted obstacle_touch term of each step of one episode, actions all zero."""
    env = MuscleEnv(scene)
    env.reset(seed=0)
    terms = []
    for _ in range(scene.steps_per_episode):
        _, reward, terminated, truncated, info = env.step(np.zeros(env.action_space.shape))
        assert reward == pytest.approx(sum(info["reward_terms"].values()))
        terms.append(info["reward_terms"]["obstacle_touch"])
        if terminated or truncated:
            break
    return terms


def test_steps_ending_on_a_sphere_are_charged_and_others_are_not(tmp_path: Path) -> None:
    under_the_feet = touch_terms(obstacle_scene(tmp_path, [0.0, 0.0], "under", touch_weight=2))
    assert under_the_feet and all(term == -2.0 for term in under_the_feet)
    far_ahead = obstacle_scene(tmp_path, [20.0, 30.0], "ahead", touch_weight=2)
    assert set(touch_terms(far_ahead)) == {0.0}
    assert set(touch_terms(obstacle_scene(tmp_path, [0.0, 0.0], "unweighed"))) == {0.0}


def test_a_scene_without_obstacles_cannot_weigh_the_touch(tmp_path: Path) -> None:
    data = scene_fields("run-2d")
    data["task"]["reward"]["obstacle_touch"] = 1.0
    path = tmp_path / "no-spheres.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ValueError, match=r"obstacle_touch 1\.0: the scene has no obstacles"):
        load_scene(path)
