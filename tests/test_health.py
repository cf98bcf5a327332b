"""A real MuJoCo instability ends the episode with a named cause and never reaches the
observation; the env works again after reset."""

from __future__ import annotations

import numpy as np

from workers.env import MuscleEnv
from workers.scenes import Scene, load_scene
from workers.scenes.profiles import FidelityProfile


def _unstable_walk_3d() -> Scene:
    """MyoLeg with explicit Euler at a 20 ms step: known to blow up under full excitation."""
    scene = load_scene("walk-3d")
    return scene.model_copy(
        update={
            "fidelity": FidelityProfile(integrator="euler", timestep=0.02),
            "control_hz": 50.0,
        }
    )


def test_myoleg_euler_20ms_full_excitation_is_flagged_not_propagated() -> None:
    env = MuscleEnv(_unstable_walk_3d())
    obs, _ = env.reset(seed=0)
    causes = []
    full = np.ones(env.action_space.shape, dtype=np.float32)
    for _ in range(200):
        obs, reward, terminated, truncated, info = env.step(full)
        assert np.isfinite(obs).all() and np.isfinite(reward)
        if info["health"] != "ok":
            causes.append(info["health"])
            assert terminated
            assert reward == 0.0
            break
        if terminated or truncated:
            env.reset()
    assert causes and causes[0].startswith("mujoco_"), causes
    obs, info = env.reset(seed=1)
    assert info["health"] == "ok" and np.isfinite(obs).all()
    obs, _, _, _, info = env.step(np.zeros(env.action_space.shape, dtype=np.float32))
    assert np.isfinite(obs).all()


def test_default_profile_full_excitation_stays_healthy_on_walk_2d() -> None:
    env = MuscleEnv("walk-2d")
    env.reset(seed=0)
    full = np.ones(env.action_space.shape, dtype=np.float32)
    for _ in range(100):
        _, _, terminated, truncated, info = env.step(full)
        assert info["health"] == "ok"
        if terminated or truncated:
            env.reset()


def test_nan_action_is_treated_as_zero_excitation() -> None:
    env = MuscleEnv("elbow-reach")
    env.reset(seed=0)
    action = np.full(env.action_space.shape, np.nan, dtype=np.float32)
    obs, reward, _, _, info = env.step(action)
    assert np.isfinite(obs).all() and np.isfinite(reward) and info["health"] == "ok"
