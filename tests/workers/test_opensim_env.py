"""The 2-D scenes on OpenSim: step, seed, pickle, fail and recover, and stay quiet."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys

import numpy as np
import pytest
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.scenes.profiles import FidelityProfile
from gaitforge.workers.sim.opensim.simulator import OpenSimSimulator


def _rollout(env: MuscleEnv, seed: int, steps: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    observations = [env.reset(seed=seed)[0]]
    for _ in range(steps):
        obs, _, terminated, truncated, _ = env.step(rng.uniform(0, 1, env.action_space.shape))
        observations.append(obs)
        if terminated or truncated:
            break
    return np.array(observations)


def test_same_seed_same_trajectory_on_opensim() -> None:
    a = _rollout(MuscleEnv("walk-2d", "opensim"), seed=4, steps=15)
    b = _rollout(MuscleEnv("walk-2d", "opensim"), seed=4, steps=15)
    np.testing.assert_array_equal(a, b)  # exactly: both runs in this process, same machine


def test_opensim_env_pickles_and_continues() -> None:
    """A new Manager starts from the restored state, so the error-controlled integrator's
    step-size history is lost: the continuation agrees to its accuracy, not bit for bit."""
    env = MuscleEnv("stand-2d", "opensim")
    env.reset(seed=0)
    for _ in range(3):
        env.step(np.full(env.action_space.shape, 0.2))
    clone = pickle.loads(pickle.dumps(env))
    for _ in range(5):
        a, *_ = env.step(np.full(env.action_space.shape, 0.3))
        b, *_ = clone.step(np.full(env.action_space.shape, 0.3))
        np.testing.assert_allclose(a, b, rtol=1e-2, atol=1e-3)


def _failing_scene() -> Scene:
    """Explicit Euler at a fixed 50 ms step: the stiff foot contact blows the state up.

    (OpenSim 4.6's error-controlled integrators survive even accuracy 0.99 with a 50 ms
    largest step on this model, so a loose accuracy does not make a failure here.)"""
    scene = load_scene("walk-2d")
    profile = FidelityProfile(integrator="explicit-euler", timestep=0.05, fixed_step=True)
    return scene.model_copy(update={"fidelity": {"opensim": profile}, "backends": ["opensim"]})


def test_a_forced_integrator_failure_is_named_and_the_next_reset_works() -> None:
    env = MuscleEnv(_failing_scene(), "opensim")
    env.reset(seed=0)
    causes = []
    for _ in range(100):
        obs, reward, terminated, truncated, info = env.step(np.ones(env.action_space.shape))
        assert np.isfinite(obs).all() and np.isfinite(reward)
        if info["health"] != "ok":
            causes.append(info["health"])
            break
        if terminated or truncated:
            env.reset()
    assert causes, "the failing profile should fail"
    assert causes[0] in {"opensim_integrator_failed", "nan_state", "diverged_speed"}
    obs, info = env.reset(seed=1)
    assert info["health"] == "ok" and np.isfinite(obs).all()
    obs, _, _, _, info = env.step(np.zeros(env.action_space.shape))
    assert np.isfinite(obs).all()


def test_opensim_prints_nothing_per_episode(capfd: pytest.CaptureFixture[str]) -> None:
    env = MuscleEnv("stand-2d", "opensim")
    capfd.readouterr()
    for seed in range(2):
        env.reset(seed=seed)
        for _ in range(3):
            env.step(np.zeros(env.action_space.shape))
    out, _ = capfd.readouterr()
    assert out == ""


def test_model_is_rebuilt_every_n_episodes() -> None:
    sim = OpenSimSimulator(load_scene("stand-2d"), rebuild_every=2)
    for seed in range(5):
        sim.reset(seed)
        sim.step(np.zeros(len(sim.muscle_names)), 0.01)
    assert sim.rebuilds == 2


def test_a_step_reads_no_freed_state_under_a_poisoning_allocator() -> None:
    """``Manager.integrate`` returns a reference into its Manager; reading it once that
    Manager is freed read garbage now and then (a pickled run-2d+clock diverged in CI). With
    glibc filling freed memory with a pattern (tcache off, so every free is filled), such a
    read segfaults or goes wrong every time rather than now and then."""
    script = (
        "import numpy as np\n"
        "from gaitforge.workers.env import MuscleEnv\n"
        "env = MuscleEnv('run-2d+clock', 'opensim')\n"
        "env.reset(seed=3)\n"
        "for _ in range(4):\n"
        "    before = env.sim.state().time\n"
        "    env.step(np.full(env.action_space.shape, 0.5))\n"
        "    assert abs(env.sim.state().time - before - 1 / 25) < 1e-9, env.sim.state().time\n"
    )
    poisoning = {"GLIBC_TUNABLES": "glibc.malloc.tcache_count=0", "MALLOC_PERTURB_": "165"}
    done = subprocess.run(
        [sys.executable, "-c", script],
        env={**os.environ, **poisoning},
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-2000:]


def _clock_scene(profile: FidelityProfile) -> Scene:
    scene = load_scene("walk-2d+clock")
    return scene.model_copy(update={"fidelity": {"opensim": profile}, "backends": ["opensim"]})


def _reflex_states(env: MuscleEnv, one_manager_a_step: bool, steps: int) -> np.ndarray:
    """OpenSim's state vector after each of ``steps`` reflex control steps from seed 0 under
    fixed random joint targets: through ``step_reflex`` (one Manager a control step), or
    through one ``step_reflex`` of a single update (a new Manager) per reflex update."""
    env.reset(seed=0)
    sim, reflex, rng = env.sim, env.reflex, np.random.default_rng(3)
    pose = np.array([env.sim.coordinates()[d] for d in sim.dof_names])
    states = []
    for _ in range(steps):
        reflex.set_targets(rng.uniform(0, 1, len(pose)), pose, np.zeros_like(pose))
        updates = env.scene.reflex_chunks
        if one_manager_a_step:
            sim.step_reflex(reflex, env.dt, updates)
        else:
            for _ in range(updates):
                sim.step_reflex(reflex, env.dt / updates, 1)
        states.append(sim.osim_state.getY().to_numpy().copy())
    return np.array(states)


def test_reflex_updates_share_a_manager_without_changing_the_state() -> None:
    """The reflex updates of a control step go on in one Manager, each with its own
    excitations: at a fixed step the state is bit for bit that of a new Manager per update
    (excitations taken up one update late put it metres and radians apart within 4 steps);
    with error control it agrees to the accuracy asked."""
    fixed = FidelityProfile(integrator="semi-explicit-euler2", timestep=0.001, fixed_step=True)
    env = MuscleEnv(_clock_scene(fixed), "opensim")
    np.testing.assert_array_equal(
        _reflex_states(env, True, steps=4), _reflex_states(env, False, steps=4)
    )
    tight = FidelityProfile(integrator="rk-merson", timestep=0.01, accuracy=1e-7)
    env = MuscleEnv(_clock_scene(tight), "opensim")
    np.testing.assert_allclose(
        _reflex_states(env, True, steps=3), _reflex_states(env, False, steps=3), atol=1e-5
    )
