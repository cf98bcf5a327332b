"""A lead-in (``task.clock.lead_in``): after a standing start the walk plays first and
cross-fades into the run (``workers.motions.playback``), on real MuJoCo; and the
``target_speed`` term's target follows that clock (``speed_target_from_clock``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.motions import load_motion
from gaitforge.workers.motions.playback import CrossFade, faster

from tests.workers.test_imitation_errors import _fails, _write


def _walk_into_run(hold_s: float = 1.0, crossfade_s: float = 1.0) -> CrossFade:
    return CrossFade(
        lead=load_motion("gait2d", "walk"),
        lead_tempo=1.25,
        main=load_motion("gait2d", "run"),
        main_tempo=1.0,
        hold_s=hold_s,
        crossfade_s=crossfade_s,
    )


def test_the_phase_rate_fades_from_the_walks_to_the_runs_without_a_jump() -> None:
    fade = _walk_into_run()
    walk_rate, run_rate = 1.25 / fade.lead.period_s, 1.0 / fade.main.period_s
    assert run_rate > walk_rate
    h = 1e-6
    for t, weight in [(0.3, 0.0), (1.0, 0.0), (1.25, 0.25), (1.5, 0.5), (2.0, 1.0), (4.0, 1.0)]:
        rate = (fade.cycles(t + h) - fade.cycles(t - h)) / (2 * h)
        assert fade.weight(t) == pytest.approx(weight)
        assert rate == pytest.approx((1 - weight) * walk_rate + weight * run_rate, rel=1e-5)
    # continuous at the fade's ends, and the run's rate after it
    for t in (1.0, 2.0):
        assert fade.cycles(t + h) - fade.cycles(t - h) < 2 * h * run_rate * 1.001
    assert fade.cycles(5.0) - fade.cycles(3.0) == pytest.approx(2.0 * run_rate)


def test_the_state_is_the_walk_then_a_blend_then_the_run() -> None:
    fade = _walk_into_run()
    for t, pick in [(0.5, "walk"), (3.0, "run")]:
        phase = fade.cycles(t) % 1.0
        expected = faster(fade.lead.at(phase), 1.25) if pick == "walk" else fade.main.at(phase)
        assert fade.at(t) == expected
    t = 1.5  # half way
    phase = fade.cycles(t) % 1.0
    walk, run = faster(fade.lead.at(phase), 1.25), fade.main.at(phase)
    state = fade.at(t)
    for joint, angle in state.joints.items():
        assert angle == pytest.approx((walk.joints[joint] + run.joints[joint]) / 2)
    assert state.forward_speed == pytest.approx((walk.forward_speed + run.forward_speed) / 2)
    assert state.pelvis_height == pytest.approx((walk.pelvis_height + run.pelvis_height) / 2)


def test_run_2d_clock_starts_walking_and_its_targets_and_clock_follow_the_fade() -> None:
    env = MuscleEnv("run-2d+clock")
    obs, _ = env.reset(seed=0)
    clock = env.clock
    assert clock.standing_start and clock.crossfade is not None
    fade = clock.crossfade
    names = env.obs_names
    sin, cos = names.index("phase_sin"), names.index("phase_cos")
    standing = env._default_pose
    neutral = np.full(env.action_space.shape, 0.5, np.float32)
    for step in range(1, 61):
        obs, _, terminated, truncated, info = env.step(neutral)
        t = step * env.dt
        phase = fade.cycles(t) % 1.0
        assert obs[sin] == pytest.approx(np.sin(2 * np.pi * phase), abs=1e-6)
        assert obs[cos] == pytest.approx(np.cos(2 * np.pi * phase), abs=1e-6)
        ref = clock.reference(step)
        if not clock.mirrored:
            assert ref == fade.at(t)
        angles = np.array(
            [ref.joints.get(d, q) for d, q in zip(env.sim.dof_names, standing, strict=True)]
        )
        ramp = min(1.0, t / 0.8)
        np.testing.assert_allclose(env.reflex._targets, standing + ramp * (angles - standing))
        # the target_speed term asks for the clock's speed (ramped), at most run-2d's 3 m/s
        target = min(3.0, ref.forward_speed * ramp)
        speed = info["reward_terms"]["forward"] / 10.0 / env.dt
        assert info["reward_terms"]["target_speed"] == pytest.approx(-((speed - target) ** 2))
        assert obs[names.index("target_speed")] == pytest.approx(3.0)
        if terminated or truncated:
            break
    assert step > 10
    assert clock.target_speed(0, 3.0) == 0.0
    assert clock.target_speed(100, 3.0) == 3.0  # the run is faster than 3 m/s


def test_each_start_plays_its_clock_standing_part_way_along_the_lead_in_or_in_the_run() -> None:
    env = MuscleEnv("imitate-run-2d+standing-starts")  # 35 % standing, 35 % along the lead-in
    ramp_s, noise = env.scene.task.clock.ramp_s, env.scene.task.imitate.starts.noise
    kinds = []
    for seed in range(40):
        _, info = env.reset(seed=seed)
        clock, fade = env.clock, env.clock.crossfade
        run_phase = (clock.phase0 + 10 * env.dt / clock.motion.period_s) % 1.0
        if clock.standing_start:
            kinds.append("standing")
            assert clock.start_s == 0.0 and clock.ramp(0) == 0.0
            assert clock.phase(10) == pytest.approx(fade.cycles(10 * env.dt))
        elif clock.start_s > 0.0:
            kinds.append("lead-in")
            start_s = clock.start_s
            assert ramp_s <= start_s <= fade.hold_s + fade.crossfade_s
            assert clock.phase0 == 0.0 and clock.ramp(0) == 1.0
            # the body starts in the faded reference there, and the clock goes on from it
            expected = fade.at(start_s)
            if clock.mirrored:
                expected = clock.motion.mirrored_state(expected)
            assert clock.reference(0) == expected
            assert 0.0 < info["imitation"]["pose_error_rad"] <= noise
            assert info["imitation"]["phase"] == pytest.approx(fade.cycles(start_s) % 1.0)
            assert clock.phase(10) == pytest.approx(fade.cycles(start_s + 10 * env.dt) % 1)
        else:
            kinds.append("run")
            assert clock.phase(10) == pytest.approx(run_phase)
        # no speed_target_from_clock here: the task's target speed throughout
        assert clock.target_speed(0, 3.0) == 3.0
    # p = 0.35, 0.35, 0.3 over 40 draws: each within [4, 24] with p > 0.999
    assert all(4 <= kinds.count(kind) <= 24 for kind in ("standing", "lead-in", "run")), kinds


@pytest.mark.parametrize(
    ("base", "edit", "fragments"),
    [
        (
            "imitate-run-2d",
            lambda t: t["clock"].update(lead_in={"motion": "walk", "hold_s": 1, "crossfade_s": 1}),
            ["task.clock.lead_in", "plays from a standing start", "starts.standing"],
        ),
        (
            "run-2d+clock",
            lambda t: t["clock"]["lead_in"].update(motion="skip"),
            ["task.clock.lead_in.motion", "no such motion", "available: run, walk"],
        ),
        (
            "run-2d+clock",
            lambda t: t["clock"]["lead_in"].update(crossfade_s=0),
            ["task.clock.lead_in.crossfade_s", "greater than 0"],
        ),
        (
            "run-2d+clock",
            lambda t: t["clock"]["lead_in"].pop("hold_s"),
            ["task.clock.lead_in.hold_s", "required"],
        ),
        (
            "imitate-run-2d",
            lambda t: t["imitate"]["starts"].update(lead_in=0.3),
            ["task.imitate.starts.lead_in", "only with a task.clock.lead_in"],
        ),
        (
            "imitate-run-2d+standing-starts",
            lambda t: t["imitate"]["starts"].update(standing=0.5, lead_in=0.6),
            ["task.imitate.starts.lead_in", "1.1", "at most 1"],
        ),
    ],
)
def test_bad_lead_ins_name_the_field(tmp_path: Path, base: str, edit, fragments) -> None:
    _fails(_write(tmp_path, base, lambda raw: edit(raw["task"])), *fragments)
