"""Walk the whole catalogue (bases, and the compositions recipes use): every scene
compiles, resets, steps, checks, seeds and pickles."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.scenes import catalogue, load_scene
from gaitforge.workers.scenes.migration import FORMER_NAMES
from gaitforge.workers.scenes.spec import Scene
from gymnasium.utils.env_checker import check_env

SCENES = catalogue() + sorted(set(FORMER_NAMES.values()))
SCENES += ["imitate-walk-3d+standing-starts", "walk-3d+clock"]
"""the bases, the compositions the former catalogue listed and those of the 3-D recipe"""
CASES = [(name, b) for name in SCENES for b in load_scene(name).backends]


def _rollout(env: MuscleEnv, seed: int, steps: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    obs, _ = env.reset(seed=seed)
    observations, rewards = [obs], []
    for _ in range(steps):
        obs, reward, terminated, truncated, _ = env.step(
            rng.uniform(0, 1, env.action_space.shape).astype(np.float32)
        )
        observations.append(obs)
        rewards.append(reward)
        if terminated or truncated:
            break
    return np.array(observations), np.array(rewards)


def test_catalogue_has_the_issue_scenes() -> None:
    assert {"elbow-reach", "stand-2d", "walk-2d", "run-2d", "obstacles-2d", "walk-3d"} <= set(
        catalogue()
    )


@pytest.mark.parametrize(("name", "backend"), CASES)
def test_scene_compiles_resets_and_steps(name: str, backend: str) -> None:
    env = MuscleEnv(name, backend)
    obs, info = env.reset(seed=1)
    assert obs.shape == env.observation_space.shape
    assert info["health"] == "ok"
    assert len(env.obs_names) == obs.size
    for _ in range(20):
        action = env.action_space.sample()
        obs, reward, terminated, truncated, info = env.step(action)
        assert np.isfinite(obs).all() and np.isfinite(reward)
        assert reward == pytest.approx(sum(info["reward_terms"].values()))
        if terminated or truncated:
            env.reset()


@pytest.mark.parametrize(("name", "backend"), CASES)
def test_gymnasium_env_checker(name: str, backend: str) -> None:
    check_env(MuscleEnv(name, backend), skip_render_check=True)


@pytest.mark.parametrize(("name", "backend"), CASES)
def test_same_seed_same_trajectory(name: str, backend: str) -> None:
    """20 control steps of two envs from one seed (a step of OpenSim's costs 20-100 ms
    here); another seed's trajectory, on the first env again, parts within its first 3."""
    env = MuscleEnv(name, backend)
    a_obs, a_rew = _rollout(env, seed=7, steps=20)
    b_obs, b_rew = _rollout(MuscleEnv(name, backend), seed=7, steps=20)
    # exactly: determinism is what is tested, both runs in this process on this machine
    np.testing.assert_array_equal(a_obs, b_obs)
    np.testing.assert_array_equal(a_rew, b_rew)
    c_obs, _ = _rollout(env, seed=8, steps=3)
    assert not np.array_equal(a_obs[: len(c_obs)], c_obs[: len(a_obs)])


@pytest.mark.parametrize(("name", "backend"), CASES)
def test_env_pickles_mid_episode_and_continues_identically(name: str, backend: str) -> None:
    env = MuscleEnv(name, backend)
    env.reset(seed=3)
    rng = np.random.default_rng(0)
    for _ in range(5):
        env.step(rng.uniform(0, 1, env.action_space.shape))
    clone = pickle.loads(pickle.dumps(env))
    actions = rng.uniform(0, 1, (5, *env.action_space.shape))
    for action in actions:
        a = env.step(action)
        b = clone.step(action)
        # exactly: the clone is the same state in this process, so it must step bit for bit
        np.testing.assert_array_equal(a[0], b[0])
        assert a[1:4] == b[1:4]


def test_obstacles_are_replaced_each_episode_and_the_nearest_one_ahead_is_observed() -> None:
    env = MuscleEnv("obstacles-2d")
    names = env.obs_names
    dx, radius = names.index("obstacle_dx"), names.index("obstacle_radius")
    obs_a, _ = env.reset(seed=1)
    first = env.sim.obstacles().copy()
    obs_b, _ = env.reset(seed=2)
    assert first.shape == (10, 3)
    assert not np.allclose(first, env.sim.obstacles())
    nearest = env.sim.obstacles()[np.argmin(env.sim.obstacles()[:, 0])]
    assert obs_b[dx] == pytest.approx(nearest[0] - env.sim.state().pelvis_pos[0], abs=1e-5)
    assert obs_b[radius] == pytest.approx(nearest[2], abs=1e-6)
    assert 0.05 <= obs_a[radius] <= 0.1


def test_a_scene_can_observe_more_spheres_ahead() -> None:
    scene = load_scene("obstacles-2d").model_dump()
    scene["obstacles"].update(x_range=(-3.0, 3.0), observe_ahead=2)
    env = MuscleEnv(Scene.model_validate(scene))
    names = env.obs_names
    obs, _ = env.reset(seed=3)
    here = env.sim.state().pelvis_pos[0]
    spheres = env.sim.obstacles()
    ahead = spheres[spheres[:, 0] + spheres[:, 2] > here]
    assert len(ahead) >= 2 and len(ahead) < len(spheres)  # some passed: not observed
    for prefix, sphere in [("obstacle", ahead[0]), ("obstacle_2", ahead[1])]:
        got = [obs[names.index(f"{prefix}_{field}")] for field in ("dx", "height", "radius")]
        assert got == pytest.approx([sphere[0] - here, sphere[1], sphere[2]], abs=1e-5)
    assert names.index("obstacle_radius") + 1 == names.index("obstacle_2_dx")
    assert names[-6:] == [
        f"{p}_{f}" for p in ("obstacle", "obstacle_2") for f in ("dx", "height", "radius")
    ]


def test_a_fall_terminates_the_episode() -> None:
    env = MuscleEnv("walk-2d")
    env.reset(seed=0)
    for _ in range(env.scene.steps_per_episode):
        _, _, terminated, truncated, info = env.step(np.zeros(env.action_space.shape))
        if terminated:
            assert info["fell"] and info["health"] == "ok" and not truncated
            break
    else:
        pytest.fail("a body with no excitation should fall within the episode")
    assert info["sim_time"] < 3.0
