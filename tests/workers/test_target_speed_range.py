"""A target speed drawn per episode (``task.target_speed_range``), on real MuJoCo: observed,
rewarded, and with the gait clock its main motion's tempo scaled to match; the
evaluation's speed sweep pins it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from gaitforge.learner.evaluation.episodes import with_target_speed
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.scenes import load_scene, scene_fields
from gaitforge.workers.scenes.spec import Scene
from gaitforge.workers.spec_io import SpecError

NOMINAL = 3.0


def _ranged(low: float, high: float) -> Scene:
    data = load_scene("run-2d+clock+one-leg+forward").model_dump(mode="json")
    assert data["task"]["target_speed"] == NOMINAL
    data["task"]["target_speed_range"] = (low, high)
    return Scene.model_validate(data)


def _drawn(env: MuscleEnv, seed: int) -> float:
    obs, _ = env.reset(seed=seed)
    return float(obs[env.obs_names.index("target_speed")])


def test_each_episode_draws_its_target_and_the_clock_plays_at_its_pace() -> None:
    env = MuscleEnv(_ranged(2.0, 3.0))
    clock = env.clock
    drawn = [_drawn(env, seed) for seed in range(8)]
    assert all(2.0 <= v <= 3.0 for v in drawn) and max(drawn) - min(drawn) > 0.3
    assert drawn == [_drawn(env, seed) for seed in range(8)]  # seeded
    v = _drawn(env, 3)
    assert clock.tempo == pytest.approx(clock.spec.tempo * v / NOMINAL)
    # well past the lead-in's fade the phase advances at the scaled run's rate
    steps = int(4.0 * env.scene.control_hz)
    played = (clock.phase(steps + 1) - clock.phase(steps)) % 1.0
    run_rate = clock.tempo / clock.motion.period_s  # cycles/s
    assert played == pytest.approx(run_rate * env.dt, rel=1e-6)
    # the target_speed term's target is the draw once the clock runs faster than it
    assert clock.target_speed(steps, v) == pytest.approx(v)


def test_the_reward_aims_at_the_draw_once_the_clock_is_faster() -> None:
    env = MuscleEnv(_ranged(1.0, 1.0))  # the lead-in walks at 1.27 m/s once ramped in
    env.reset(seed=0)
    hold = np.full(env.action_space.shape, 0.5, dtype=np.float32)  # on the clock's pose
    for _ in range(22):  # 0.88 s: past the 0.8-s ramp, before this body falls (1 s)
        obs, _, terminated, _, _ = env.step(hold)
        assert not terminated
    assert env.clock.reference(22).forward_speed > 1.1
    assert env.target_speed() == pytest.approx(1.0)
    assert obs[env.obs_names.index("target_speed")] == pytest.approx(1.0)


def test_the_sweep_pins_a_drawn_target_and_scales_the_clock_from_the_nominal() -> None:
    env = MuscleEnv(with_target_speed(_ranged(2.0, 3.0), 2.4))
    assert [_drawn(env, seed) for seed in range(3)] == pytest.approx([2.4] * 3)
    assert env.scene.task.target_speed == NOMINAL
    assert env.clock.tempo == pytest.approx(env.clock.spec.tempo * 0.8)
    fixed = with_target_speed(load_scene("run-2d+clock+one-leg+forward"), 2.4)
    assert fixed.task.target_speed == 2.4 and fixed.task.target_speed_range is None


@pytest.mark.parametrize(
    ("speeds", "target"), [((3.0, 2.0), 3.0), ((0.0, 2.0), 3.0), ((1.0, 2.0), None)]
)
def test_a_bad_range_fails_with_one_line(tmp_path: Path, speeds, target) -> None:
    raw = scene_fields("walk-2d")
    raw["task"].update(target_speed=target, target_speed_range=list(speeds))
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(raw))
    with pytest.raises(SpecError) as info:
        load_scene(path)
    message = str(info.value)
    assert "\n" not in message and str(path) in message
    assert "target_speed_range" in message and "0 < low <= high" in message
