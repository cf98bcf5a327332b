"""How an imitation episode starts and paces itself, on real MuJoCo: ``imitate.tempo`` (the
motion played faster), ``init.standing_fraction`` (some episodes start standing at phase 0)
and ``init.ramp_s`` (joint targets blend from the standing pose into the motion's)."""

from __future__ import annotations

import numpy as np
import pytest
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.spec_io import SpecError, validate_model


def _imitate_walk(action: dict | None = None, tempo: float = 1.0, **init: object) -> Scene:
    raw = load_scene("imitate-walk-2d").model_dump()
    raw["backends"] = ["mujoco"]
    raw["task"]["imitate"]["tempo"] = tempo
    raw["task"]["imitate"]["init"].update(init)
    if action is not None:
        raw["action"] = action
    return Scene.model_validate(raw)


def test_a_faster_tempo_advances_the_phase_and_scales_the_speeds() -> None:
    plain = MuscleEnv(_imitate_walk(random_phase=False, mirror=False))
    fast = MuscleEnv(_imitate_walk(tempo=1.25, random_phase=False, mirror=False))
    plain.reset(seed=0)
    fast.reset(seed=0)
    assert fast.imitation.phase(4) == pytest.approx(plain.imitation.phase(5), abs=1e-12)
    slow_ref, fast_ref = plain.imitation.reference(5), fast.imitation.reference(4)
    assert fast_ref.joints == pytest.approx(slow_ref.joints)
    assert fast_ref.forward_speed == pytest.approx(1.25 * slow_ref.forward_speed)
    for joint, speed in slow_ref.joint_speeds.items():
        assert fast_ref.joint_speeds[joint] == pytest.approx(1.25 * speed)
    # the reset places the body at the faster reference's speeds
    fast_start = fast.sim.state()
    assert fast_start.pelvis_vel[fast.sim.forward_axis] == pytest.approx(
        fast.imitation.reference(0).forward_speed, rel=0.05
    )


def test_a_fraction_of_episodes_starts_standing_at_phase_zero() -> None:
    env = MuscleEnv(_imitate_walk(standing_fraction=0.5))
    standing = env._default_pose
    starts = []
    for seed in range(40):
        _, info = env.reset(seed=seed)
        q = env.sim.state().dof_pos
        at_rest = bool(np.allclose(q, standing, atol=env.scene.init_noise + 1e-9))
        assert at_rest == env.imitation.standing_start
        if at_rest:
            assert info["imitation"]["phase"] == 0.0
        starts.append(at_rest)
    assert 8 <= sum(starts) <= 32  # p = 0.5 over 40 draws (both bounds: p > 0.998)
    env = MuscleEnv(_imitate_walk(standing_fraction=1.0))
    for seed in range(5):
        env.reset(seed=seed)
        assert env.imitation.standing_start


def test_the_fraction_is_refused_with_a_standing_start() -> None:
    raw = load_scene("walk-2d+clock").model_dump()
    raw["task"]["imitate"]["init"]["standing_fraction"] = 0.3
    with pytest.raises(SpecError, match=r"standing_fraction: only with start: motion"):
        validate_model(raw, Scene, "scene")


def test_the_targets_ramp_from_standing_into_the_motion() -> None:
    """With ``ramp_s`` 0.4 s at 25 Hz the base pose is 1/10 of the way into the motion after
    one step and all the way after ten; with no ramp it is the motion's pose at once."""
    targets = {"kind": "joint_targets"}
    env = MuscleEnv(_imitate_walk(targets, standing_fraction=1.0, ramp_s=0.4))
    _, info = env.reset(seed=0)
    assert info["imitation"]["pose_error_rad"] < 0.02  # compared with the standing pose
    standing = env._default_pose
    neutral = np.full(env.action_space.shape, 0.5, np.float32)
    for step in range(1, 13):
        env.step(neutral)
        ref = env.imitation.reference(step)
        names = env.sim.dof_names
        motion = np.array([ref.joints.get(d, b) for d, b in zip(names, standing, strict=True)])
        blend = min(1.0, step / 10)
        assert env.imitation.ramp(step) == pytest.approx(blend)
        np.testing.assert_allclose(env.reflex._targets, standing + blend * (motion - standing))
    assert not np.allclose(motion, standing, atol=0.05)  # the ramp had somewhere to go
    no_ramp = MuscleEnv(_imitate_walk(targets, standing_fraction=1.0))
    _, info = no_ramp.reset(seed=0)
    assert no_ramp.imitation.ramp(0) == 1.0
    assert info["imitation"]["pose_error_rad"] > 0.1  # compared with the motion's pose
    moving = MuscleEnv(_imitate_walk(targets, ramp_s=0.4))  # a start in the motion: no ramp
    moving.reset(seed=0)
    assert moving.imitation.ramp(0) == 1.0
