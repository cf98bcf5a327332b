"""A real MuJoCo instability ends the episode with a named cause and never reaches the
observation; the env works again after reset."""

from __future__ import annotations

import numpy as np
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.scenes.profiles import FidelityProfile


def _unstable_walk_3d(control_hz: float = 50.0) -> Scene:
    """MyoLeg with explicit Euler at a 20 ms step: known to blow up under full excitation."""
    scene = load_scene("walk-3d")
    return scene.model_copy(
        update={
            "fidelity": FidelityProfile(integrator="euler", timestep=0.02),
            "control_hz": control_hz,
        }
    )


def _run_full_excitation(env: MuscleEnv, steps: int = 200) -> list[str]:
    """Full excitation until the first unhealthy step; every observation must be finite."""
    obs, _ = env.reset(seed=0)
    full = np.ones(env.action_space.shape, dtype=np.float32)
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(full)
        assert np.isfinite(obs).all() and np.isfinite(reward)
        if info["health"] != "ok":
            assert terminated and reward == 0.0
            return [info["health"]]
        if terminated or truncated:
            env.reset()
    return []


def test_myoleg_euler_20ms_full_excitation_is_flagged_not_propagated() -> None:
    env = MuscleEnv(_unstable_walk_3d())
    causes = _run_full_excitation(env)
    assert causes == ["diverged_speed"], causes
    obs, info = env.reset(seed=1)
    assert info["health"] == "ok" and np.isfinite(obs).all()
    obs, _, _, _, info = env.step(np.zeros(env.action_space.shape, dtype=np.float32))
    assert np.isfinite(obs).all() and info["health"] == "ok"


def test_mujoco_silent_reset_is_read_from_its_warning_counters() -> None:
    """With 10 substeps per control step, MuJoCo blows up, resets the state and carries on
    inside one env step: only its BADQACC counter tells, and the env must report it."""
    env = MuscleEnv(_unstable_walk_3d(control_hz=5.0))
    assert _run_full_excitation(env, steps=20) == ["mujoco_badqacc"]


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
