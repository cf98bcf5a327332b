"""A clock the policy paces (``task.imitate.clock_rate_span``): the action's last entry,
``clock_rate``, plays the imitation clock faster or slower each step, on real MuJoCo."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.scenes.io_names import CLOCK_RATE_ACTION, action_names

from tests.workers.test_imitation_errors import _fails, _write


def _paced(tmp_path: Path, span: object = 0.5) -> Path:
    def edit(raw: dict) -> None:
        raw["name"] = "run-2d-clock-paced"
        raw["task"]["imitate"]["clock_rate_span"] = span

    return _write(tmp_path, "run-2d+clock", edit)


@pytest.mark.parametrize("span", [0.0, 0.95, "fast"])
def test_a_span_outside_its_range_names_the_field(tmp_path: Path, span: object) -> None:
    _fails(_paced(tmp_path, span), "clock_rate_span")


def test_the_clock_rate_is_the_last_action_entry(tmp_path: Path) -> None:
    scene = load_scene(_paced(tmp_path))
    env = MuscleEnv(scene)
    plain = MuscleEnv("run-2d+clock")
    assert env.act_names == [*plain.act_names, CLOCK_RATE_ACTION]
    assert action_names(scene) == env.act_names
    assert env.action_space.shape == (len(plain.act_names) + 1,)
    assert env.obs_names == plain.obs_names


def test_at_one_half_the_clock_runs_with_the_envs_time(tmp_path: Path) -> None:
    """a = 0.5 is rate 1: the same episode, observation for observation, as without pacing."""
    paced, plain = MuscleEnv(load_scene(_paced(tmp_path))), MuscleEnv("run-2d+clock")
    obs_paced, _ = paced.reset(seed=3)
    obs_plain, _ = plain.reset(seed=3)
    rng = np.random.default_rng(0)
    for _ in range(30):
        targets = rng.uniform(0.3, 0.7, len(plain.act_names))
        obs_paced, reward_paced, *_ = paced.step(np.append(targets, 0.5))
        obs_plain, reward_plain, *_ = plain.step(targets)
        assert np.array_equal(obs_paced, obs_plain)
        assert reward_paced == reward_plain
    assert paced.imitation is not None and paced.imitation.clock_rate(30) == 1.0


def test_a_faster_clock_plays_the_lead_in_and_its_speeds_faster(tmp_path: Path) -> None:
    """At a = 1 (rate 1.5 with span 0.5) 10 steps play what 15 play at the env's time: the same
    phase and standing ramp; the reference's speeds are 1.5 times as fast; the target speed
    the clock sets keeps the env's time (the task does not bend to the pace)."""
    paced, plain = MuscleEnv(load_scene(_paced(tmp_path))), MuscleEnv("run-2d+clock")
    paced.reset(seed=0)
    plain.reset(seed=0)
    targets = np.full(len(plain.act_names), 0.5)
    for _ in range(10):
        *_, info_paced = paced.step(np.append(targets, 1.0))
    for _ in range(15):
        *_, info_plain = plain.step(targets)
    assert info_paced["imitation"]["phase"] == pytest.approx(info_plain["imitation"]["phase"])
    fast, slow = paced.imitation, plain.imitation
    assert fast is not None and slow is not None
    assert fast.clock_rate(10) == pytest.approx(1.5)
    assert fast.ramp(10) == pytest.approx(slow.ramp(15)) and fast.ramp(10) < 1.0
    ref_fast, ref_slow = fast.reference(10), slow.reference(15)
    assert ref_fast.joints == pytest.approx(ref_slow.joints)
    assert ref_fast.forward_speed == pytest.approx(1.5 * ref_slow.forward_speed)
    for joint, speed in ref_slow.joint_speeds.items():
        assert ref_fast.joint_speeds[joint] == pytest.approx(1.5 * speed)
    assert plain.target_speed() > 0.0
    plain.reset(seed=0)
    for _ in range(10):
        plain.step(targets)
    assert paced.target_speed() == plain.target_speed() < ref_fast.forward_speed


def test_a_slower_clock_holds_the_standing_ramp_longer(tmp_path: Path) -> None:
    """a = 0 (rate 0.5): after 20 steps (0.8 s, the ramp's length) the clock has played 0.4 s,
    half the ramp; an out-of-range or NaN pace is clipped (NaN: 0.5, the clock's own rate)."""
    env = MuscleEnv(load_scene(_paced(tmp_path)))
    env.reset(seed=1)
    targets = np.full(len(env.act_names) - 1, 0.5)
    for pace in [0.0] * 18 + [-3.0, np.nan]:
        env.step(np.append(targets, pace))
    assert env.imitation is not None
    assert env.imitation.ramp(20) == pytest.approx((19 * 0.5 + 1.0) * env.dt / 0.8)
    assert env.imitation.clock_rate(19) == 0.5 and env.imitation.clock_rate(20) == 1.0


def test_an_unpaced_clock_refuses_a_pace() -> None:
    env = MuscleEnv("run-2d+clock")
    env.reset(seed=0)
    assert env.imitation is not None and not env.imitation.paced
    with pytest.raises(RuntimeError, match="env's time"):
        env.imitation.advance(0.8)
