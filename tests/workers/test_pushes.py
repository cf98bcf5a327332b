"""Random pelvis pushes (the scene's ``pushes``, the ``pushes`` option): drawn per episode,
checked early, and felt alike on MuJoCo and OpenSim."""

from __future__ import annotations

import numpy as np
import pytest
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.spec_io import SpecError


def _pushes(force: float) -> dict:
    """A 1 s episode with one push of ``force`` N from 0.3 s to 0.5 s (the next would
    start after the episode)."""
    return {
        "episode_s": 1.0,
        "pushes": {"force_n": [force, force], "duration_s": 0.2, "every_s": [0.3, 0.3]},
    }


def _pelvis_path(backend: str, force: float) -> tuple[np.ndarray, np.ndarray]:
    """The pelvis's positions [steps, 3] (m) under the tuned-nothing reflex controller,
    and the push's direction [3] (unit, world)."""
    env = MuscleEnv(load_scene("reflex-walk-3d", _pushes(force)), backend)
    env.reset(seed=4)
    positions = []
    for _ in range(60):
        positions.append(env.sim.state().pelvis_pos.copy())
        env.step(np.full(22, 0.5, dtype=np.float32))
    direction = env.push_force(0.35) / max(force, 1e-9)
    return np.array(positions), direction


@pytest.mark.parametrize("backend", ["mujoco", "opensim"])
def test_a_push_moves_the_pelvis_its_way(backend: str) -> None:
    """Until the push the path is the unpushed one (to 1e-12 m: the same arithmetic);
    0.1 s after a 300 N push of 0.2 s (60 N s on 75 kg) the pelvis has moved at least 2 cm
    further its way than without it, and mostly its way."""
    pushed, direction = _pelvis_path(backend, 300.0)
    plain, _ = _pelvis_path(backend, 0.0)
    np.testing.assert_allclose(pushed[:31], plain[:31], atol=1e-12)
    moved = pushed[59] - plain[59]
    along = float(moved @ direction)
    assert along > 0.02
    assert along > 0.7 * float(np.linalg.norm(moved))  # mostly its way
    assert np.linalg.norm(direction) == pytest.approx(1.0, abs=1e-12)


def test_pushes_are_drawn_per_episode_within_their_ranges() -> None:
    """Each push lasts duration_s, starts every_s after the one before, and has a magnitude
    in force_n; a different episode draws other pushes."""
    scene = load_scene("reflex-walk-3d+pushes")
    assert scene.pushes is not None
    first = scene.pushes.draw(np.random.default_rng(1), 30.0)
    second = scene.pushes.draw(np.random.default_rng(2), 30.0)
    assert len(first) >= 10 and not np.array_equal(first[:5], second[:5])
    np.testing.assert_allclose(first[:, 1] - first[:, 0], 0.2, atol=1e-9)
    gaps = np.diff(first[:, 0])
    assert gaps.min() >= 2.0 and gaps.max() <= 3.0
    assert first[:, 3].min() >= 60.0 and first[:, 3].max() <= 120.0
    assert first[-1, 0] < 30.0


def test_pushes_are_checked_at_load() -> None:
    with pytest.raises(SpecError, match=r"every_s.*at least duration_s"):
        load_scene("reflex-walk-3d", {"pushes": {"force_n": [50, 60], "every_s": [0.1, 1.0]}})
    with pytest.raises(SpecError, match=r"force_n must be \(low, high\)"):
        load_scene("reflex-walk-3d", {"pushes": {"force_n": [80, 60]}})
    with pytest.raises(SpecError, match=r"pushes.*locomotion task"):
        load_scene("elbow-reach", {"pushes": {"force_n": [50, 60]}})
