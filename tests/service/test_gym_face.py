"""Gymnasium's face: the scenes registered as ``gaitforge/<scene>-v0`` (``import gaitforge``,
or the ``gaitforge:`` prefix with no import), frames from ``render_mode="rgb_array"``,
actions in [-1, 1] for libraries that expect them, the env checker, and Stable-Baselines3's
PPO training on a scene (real MuJoCo throughout)."""

from __future__ import annotations

import subprocess
import sys
import warnings

import gaitforge
import gymnasium as gym
import numpy as np
import pytest
from gaitforge.gym_env import GymMuscleEnv
from gaitforge.gym_registration import ANY_SCENE, scene_ids
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.scenes.compose import base_names
from gymnasium.utils.env_checker import check_env

NO_IMPORT = """
import gymnasium as gym
env = gym.make("gaitforge:gaitforge/walk-2d-v0")
obs, _ = env.reset(seed=0)
print(type(env.unwrapped).__name__, obs.shape[0])
"""


def test_every_base_scene_is_registered_once_gaitforge_is_imported() -> None:
    assert sorted(scene_ids().values()) == base_names()
    registered = {k for k in gym.registry if k.startswith("gaitforge/")}
    assert registered == set(scene_ids()) | {ANY_SCENE}
    gaitforge.register_scenes()  # a second call leaves them as they are
    env = gym.make("gaitforge/walk-2d-v0")
    assert env.unwrapped.scene.name == "walk-2d" and env.action_space.high.max() == 1.0


def test_the_prefix_imports_gaitforge_when_nothing_did() -> None:
    made = subprocess.run([sys.executable, "-c", NO_IMPORT], capture_output=True, text=True)
    assert made.returncode == 0, made.stderr[-2000:]
    assert made.stdout.split() == ["GymMuscleEnv", "61"]


def test_any_composition_by_name_with_actions_in_minus_one_to_one() -> None:
    env = gym.make("gaitforge/Scene-v0", scene="walk-2d+clock", action_range="symmetric")
    plain = MuscleEnv("walk-2d+clock")
    assert env.action_space.low.min() == -1.0 and env.action_space.shape == (6,)
    obs, _ = env.reset(seed=3)
    plain_obs, _ = plain.reset(seed=3)
    # exactly: the wrapper is the same env in this process, its action mapped as below
    np.testing.assert_array_equal(obs, plain_obs)
    action = np.linspace(-1.0, 1.0, 6, dtype=np.float32)
    obs, reward, *_ = env.step(action)
    plain_obs, plain_reward, *_ = plain.step((action.astype(np.float64) + 1.0) / 2.0)
    np.testing.assert_array_equal(obs, plain_obs)
    assert reward == plain_reward


def test_rgb_array_frames_show_the_body_moving() -> None:
    env = gym.make("gaitforge/Scene-v0", scene="walk-2d+clock", render_mode="rgb_array")
    env.reset(seed=0)
    first = env.render()
    for _ in range(10):
        env.step(env.action_space.sample())
    later = env.render()
    env.close()
    assert first.shape == (360, 480, 3) and first.dtype == np.uint8
    assert first.std() > 10 and np.abs(first.astype(int) - later).mean() > 0.5
    assert env.metadata["render_fps"] == 25


def test_the_checker_passes_and_bad_options_name_themselves() -> None:
    env = gym.make("gaitforge/elbow-reach-v0", action_range="symmetric")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # unbounded observation space: by design
        check_env(env.unwrapped)
    with pytest.raises(ValueError, match=r"render_mode 'human': allowed \['rgb_array'\]"):
        GymMuscleEnv("walk-2d", render_mode="human")
    human = gym.make("gaitforge/walk-2d-v0", render_mode="human")  # a window, where one opens
    assert "HumanRendering" in str(human) and human.unwrapped.render_mode == "rgb_array"
    with pytest.raises(ValueError, match=r"action_range 'wide': allowed"):
        gym.make("gaitforge/walk-2d-v0", action_range="wide")


def test_stable_baselines3_ppo_trains_on_a_scene() -> None:
    from stable_baselines3 import PPO

    env = gym.make("gaitforge/elbow-reach-v0", action_range="symmetric")
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)  # SB3 warns on a non-symmetric box
        model = PPO("MlpPolicy", env, n_steps=256, batch_size=128, n_epochs=2, seed=0)
    model.learn(total_timesteps=512)  # two rollouts, two updates
    assert model.num_timesteps >= 512
    obs, _ = env.reset(seed=1)
    action, _ = model.predict(obs, deterministic=True)
    assert env.action_space.contains(action.astype(np.float32))
