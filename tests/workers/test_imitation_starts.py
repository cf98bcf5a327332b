"""How an imitation episode starts and paces itself, on real MuJoCo: ``clock.tempo`` (the
motion played faster), ``imitate.starts.standing`` (some episodes start standing at phase
0) and ``clock.ramp_s`` (joint targets blend from the standing pose into the motion's)."""

from __future__ import annotations

import numpy as np
import pytest
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.spec_io import SpecError

from tests.workers.scene_fields import scene_with


def _imitate_walk(action: dict | None = None, **fields: object) -> Scene:
    """imitate-walk-2d on MuJoCo with clock and start fields (``scene_with``) and ``action``."""
    overrides = {"backends": ["mujoco"], **({"action": action} if action else {})}
    return scene_with("imitate-walk-2d", overrides, **fields)


def test_a_faster_tempo_advances_the_phase_and_scales_the_speeds() -> None:
    plain = MuscleEnv(_imitate_walk(random_phase=False, mirror=False))
    fast = MuscleEnv(_imitate_walk(tempo=1.25, random_phase=False, mirror=False))
    plain.reset(seed=0)
    fast.reset(seed=0)
    assert fast.clock.phase(4) == pytest.approx(plain.clock.phase(5), abs=1e-12)
    slow_ref, fast_ref = plain.clock.reference(5), fast.clock.reference(4)
    assert fast_ref.joints == pytest.approx(slow_ref.joints)
    assert fast_ref.forward_speed == pytest.approx(1.25 * slow_ref.forward_speed)
    for joint, speed in slow_ref.joint_speeds.items():
        assert fast_ref.joint_speeds[joint] == pytest.approx(1.25 * speed)
    # the reset places the body at the faster reference's speeds
    fast_start = fast.sim.state()
    assert fast_start.pelvis_vel[fast.sim.forward_axis] == pytest.approx(
        fast.clock.reference(0).forward_speed, rel=0.05
    )


def test_a_fraction_of_episodes_starts_standing_at_phase_zero() -> None:
    env = MuscleEnv(_imitate_walk(standing=0.5))
    standing = env._default_pose
    starts = []
    for seed in range(40):
        _, info = env.reset(seed=seed)
        q = env.sim.state().dof_pos
        at_rest = bool(np.allclose(q, standing, atol=env.scene.init_noise + 1e-9))
        assert at_rest == env.clock.standing_start
        if at_rest:
            assert info["imitation"]["phase"] == 0.0
        starts.append(at_rest)
    assert 8 <= sum(starts) <= 32  # p = 0.5 over 40 draws (both bounds: p > 0.998)
    env = MuscleEnv(_imitate_walk(standing=1.0))
    for seed in range(5):
        env.reset(seed=seed)
        assert env.clock.standing_start


def test_imitation_without_a_clock_is_refused() -> None:
    with pytest.raises(SpecError, match=r"task.imitate: imitation tracks .* set task.clock"):
        load_scene("walk-2d", {"task.imitate.starts.standing": 0.3})


def test_the_targets_ramp_from_standing_into_the_motion() -> None:
    """With ``ramp_s`` 0.4 s at 25 Hz the base pose is 1/10 of the way into the motion after
    one step and all the way after ten; with no ramp it is the motion's pose at once."""
    targets = {"kind": "joint_targets"}
    env = MuscleEnv(_imitate_walk(targets, standing=1.0, ramp_s=0.4))
    _, info = env.reset(seed=0)
    assert info["imitation"]["pose_error_rad"] < 0.02  # compared with the standing pose
    standing = env._default_pose
    neutral = np.full(env.action_space.shape, 0.5, np.float32)
    for step in range(1, 13):
        env.step(neutral)
        ref = env.clock.reference(step)
        names = env.sim.dof_names
        motion = np.array([ref.joints.get(d, b) for d, b in zip(names, standing, strict=True)])
        blend = min(1.0, step / 10)
        assert env.clock.ramp(step) == pytest.approx(blend)
        np.testing.assert_allclose(env.reflex._targets, standing + blend * (motion - standing))
    assert not np.allclose(motion, standing, atol=0.05)  # the ramp had somewhere to go
    no_ramp = MuscleEnv(_imitate_walk(targets, standing=1.0))
    _, info = no_ramp.reset(seed=0)
    assert no_ramp.clock.ramp(0) == 1.0
    assert info["imitation"]["pose_error_rad"] > 0.1  # compared with the motion's pose
    moving = MuscleEnv(_imitate_walk(targets, ramp_s=0.4))  # a start in the motion: no ramp
    moving.reset(seed=0)
    assert moving.clock.ramp(0) == 1.0


def test_an_older_imitation_that_started_standing_tracks_from_standing() -> None:
    """The older layout's ``init.start: standing`` with tracking weights becomes every
    episode starting standing (``starts.standing`` 1) at the clock's random phase; with
    every weight 0 and no early end it was a clock alone and leaves no ``task.imitate``."""
    older = load_scene("imitate-walk-2d").model_dump(mode="json")
    clock, imitate = older["task"].pop("clock"), older["task"].pop("imitate")
    imitate.pop("starts")
    init = {"start": "standing", "random_phase": True, "mirror": clock["mirror"], "noise": 0.02}
    older["task"]["imitate"] = {**imitate, "motion": clock["motion"], "init": init}
    scene = Scene.model_validate(older)
    assert scene.task.imitate is not None and scene.task.imitate.starts.standing == 1.0
    env = MuscleEnv(scene)
    phases = [env.reset(seed=seed)[1]["imitation"]["phase"] for seed in range(4)]
    assert env.clock.standing_start and len(set(phases)) == 4
    older["task"]["imitate"]["weights"] = dict.fromkeys(imitate["weights"], 0.0)
    older["task"]["imitate"]["max_pose_error_rad"] = None
    clock_alone = Scene.model_validate(older).task
    assert clock_alone.imitate is None and clock_alone.clock.motion == "walk"
