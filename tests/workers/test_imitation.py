"""Imitation scenes on real simulators: reference state initialisation (MuJoCo planar and free
root, OpenSim), mirroring, the phase in the observation, the tracking terms, early end when the
pose drifts, and that a body put exactly in the reference earns the full tracking reward."""

from __future__ import annotations

import numpy as np
import pytest
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.rewards import TERMS
from gaitforge.workers.scenes import Scene, catalogue, load_scene
from gaitforge.workers.scenes.imitate import IMITATION_TERMS
from gaitforge.workers.sim.pose import pelvis_pitch_list

from tests.tolerance import assert_close
from tests.workers.scene_fields import scene_with


def _scene(name: str, **fields: object) -> Scene:
    """A catalogue imitation scene with clock and start fields replaced (``scene_with``)."""
    return scene_with(name, **fields)


def _scene_3d(**fields: object) -> Scene:
    """MyoLeg imitating the recorded 3-D walk."""
    return _scene("imitate-walk-3d", **fields)


CASES = [
    pytest.param(lambda **kw: _scene("imitate-walk-2d", **kw), "mujoco", id="walk-2d-mujoco"),
    pytest.param(lambda **kw: _scene("imitate-run-2d", **kw), "mujoco", id="run-2d-mujoco"),
    pytest.param(lambda **kw: _scene("imitate-walk-2d", **kw), "opensim", id="walk-2d-opensim"),
    pytest.param(_scene_3d, "mujoco", id="myoleg-mujoco"),
]


@pytest.mark.parametrize(("make", "backend"), CASES)
def test_reset_puts_the_body_in_the_reference(make, backend: str) -> None:
    env = MuscleEnv(make(noise=0.0), backend)
    for seed in (0, 1, 2):
        _, info = env.reset(seed=seed)
        ref = env.reference_state()
        assert ref is not None and info["imitation"]["phase"] == pytest.approx(ref.phase)
        state = env.sim.state()
        coords = env.sim.coordinates()
        for joint in env.imitation.joints:
            k = env.sim.dof_names.index(joint)
            assert coords[joint] == pytest.approx(ref.joints[joint], abs=1e-6), joint
            assert state.dof_vel[k] == pytest.approx(ref.joint_speeds[joint], abs=1e-3), joint
        assert info["imitation"]["pose_error_rad"] < 1e-6
        pitch, list_ = pelvis_pitch_list(state.pelvis_up, env.sim.up_axis, env.sim.forward_axis)
        assert pitch == pytest.approx(ref.pelvis_pitch, abs=1e-6)
        assert list_ == pytest.approx(ref.pelvis_list, abs=1e-6)
        height = state.pelvis_pos[env.sim.up_axis]
        assert ref.pelvis_height - 1e-6 <= height <= ref.pelvis_height + 0.01  # lifted <= 1 cm
        spheres = env.sim.contact_spheres()
        for s in spheres.values():  # no foot sphere starts inside the floor
            assert (s[:, env.sim.up_axis] - s[:, 3] >= -1e-6).all()


@pytest.mark.parametrize(("make", "backend"), CASES[:3])
def test_reset_noise_stays_within_its_bound(make, backend: str) -> None:
    env = MuscleEnv(make(noise=0.02), backend)
    _, info = env.reset(seed=4)
    assert 0.0 < info["imitation"]["pose_error_rad"] <= 0.02


def test_the_pelvis_starts_at_the_references_speed() -> None:
    env = MuscleEnv(_scene("imitate-walk-2d", noise=0.0), "opensim")
    env.reset(seed=3)
    ref = env.reference_state()
    state = env.sim.state()  # OpenSim: the pelvis origin's velocity
    assert state.pelvis_vel[0] == pytest.approx(ref.forward_speed, abs=1e-6)
    assert state.pelvis_vel[1] == pytest.approx(ref.pelvis_vertical_speed, abs=1e-6)
    mujoco = MuscleEnv(_scene("imitate-walk-2d", noise=0.0), "mujoco")
    mujoco.reset(seed=3)
    qvel = dict(zip(["tx", "ty", "tilt"], mujoco.sim.data.qvel[:3], strict=True))
    assert qvel["tx"] == pytest.approx(ref.forward_speed, abs=1e-6)
    assert qvel["tilt"] == pytest.approx(ref.pelvis_angular_speed[0], abs=1e-6)


def test_a_mirrored_reset_swaps_the_legs() -> None:
    env = MuscleEnv(_scene("imitate-walk-2d", random_phase=False, noise=0.0))
    seen = {}
    for seed in range(20):
        obs, info = env.reset(seed=seed)
        seen[info["imitation"]["mirrored"]] = env.sim.coordinates()
        assert obs[env.obs_names.index("phase_mirror")] == (
            1.0 if info["imitation"]["mirrored"] else -1.0
        )
    assert set(seen) == {True, False}
    plain, mirrored = seen[False], seen[True]
    for joint in ("hip_flexion", "knee_angle", "ankle_angle"):
        assert mirrored[f"{joint}_r"] == pytest.approx(plain[f"{joint}_l"], abs=1e-9)
        assert mirrored[f"{joint}_l"] == pytest.approx(plain[f"{joint}_r"], abs=1e-9)
    assert plain["hip_flexion_r"] != pytest.approx(plain["hip_flexion_l"], abs=1e-3)


def test_the_phase_in_the_observation_advances_with_time() -> None:
    env = MuscleEnv("imitate-walk-2d")
    sin_i, cos_i = env.obs_names.index("phase_sin"), env.obs_names.index("phase_cos")
    assert env.obs_names[-3:] == ["phase_sin", "phase_cos", "phase_mirror"]
    obs, info = env.reset(seed=5)
    phase0 = info["imitation"]["phase"]
    assert obs[-1] == (1.0 if info["imitation"]["mirrored"] else -1.0)
    step = env.dt / env.clock.motion.period_s
    for k in range(1, 6):
        obs, *_, info = env.step(np.full(env.action_space.shape, 0.3, np.float32))
        expected = (phase0 + k * step) % 1.0
        assert info["imitation"]["phase"] == pytest.approx(expected, abs=1e-9)
        angle = 2 * np.pi * expected
        assert obs[sin_i] == pytest.approx(np.sin(angle), abs=1e-6)
        assert obs[cos_i] == pytest.approx(np.cos(angle), abs=1e-6)


def test_reward_terms_are_named_and_within_their_weights() -> None:
    env = MuscleEnv("imitate-walk-2d")
    weights = env.scene.task.imitate.weights
    env.reset(seed=6)
    rng = np.random.default_rng(0)
    for _ in range(10):
        _, reward, terminated, _, info = env.step(rng.uniform(0, 1, env.action_space.shape))
        terms = info["reward_terms"]
        assert tuple(terms) == TERMS + IMITATION_TERMS == env.reward_term_names
        for term in IMITATION_TERMS:
            assert 0.0 <= terms[term] <= getattr(weights, term.removeprefix("imitate_")) + 1e-12
        assert reward == pytest.approx(sum(terms.values()))
        if terminated:
            break


@pytest.mark.parametrize("backend", ["mujoco", "opensim"])
def test_a_limp_body_loses_the_gait_and_the_episode_ends(backend: str) -> None:
    env = MuscleEnv("imitate-walk-2d", backend)
    env.reset(seed=0)
    for _ in range(env.scene.steps_per_episode):
        _, _, terminated, truncated, info = env.step(np.zeros(env.action_space.shape))
        if terminated:
            break
    assert terminated and not truncated and info["health"] == "ok"
    assert info["lost_track"] and not info["imitation"]["kept"]
    assert info["imitation"]["pose_error_rad"] > env.scene.task.imitate.max_pose_error_rad
    assert info["sim_time"] < 3.0


@pytest.mark.parametrize(("make", "backend"), [CASES[0], CASES[2], CASES[3]])
def test_a_body_held_in_the_reference_earns_the_full_tracking_reward(make, backend) -> None:
    env = MuscleEnv(make(noise=0.0), backend)
    env.reset(seed=7)
    imitation = env.imitation
    previous = env.sim.state()
    for steps in range(1, 8):
        ref = env.clock.reference(steps)
        env.sim.set_pose(imitation.pose_of(ref))
        state = env.sim.state()
        kernels = imitation.track(state, previous, env.sim, steps).kernels
        for term in ("pose", "joint_speed", "feet", "pelvis_pitch"):
            assert kernels[f"imitate_{term}"] > 0.99, (term, kernels)
        assert kernels["imitate_pelvis_height"] > 0.99
        previous = state


def test_scenes_that_imitate_nothing_keep_their_layout_and_terms() -> None:
    for name in ("walk-2d", "stand-2d", "elbow-reach", "obstacles-2d"):
        env = MuscleEnv(name)
        assert env.imitation is None and env.reference_state() is None
        assert not any(n.startswith("phase_") for n in env.obs_names)
        _, info = env.reset(seed=0)
        assert "imitation" not in info
        _, _, _, _, info = env.step(np.zeros(env.action_space.shape))
        assert tuple(info["reward_terms"]) == TERMS and "imitation" not in info


def test_mujoco_and_opensim_start_from_the_same_pose() -> None:
    """Also where the run's ankle passes the body's limit: both clip to the limit range."""
    scene = _scene("imitate-run-2d", noise=0.0)
    envs = [MuscleEnv(scene, backend) for backend in ("mujoco", "opensim")]
    for seed in (0, 1, 2, 21):  # seed 21: the left ankle starts clipped at its limit
        a, b = (env.reset(seed=seed)[1]["imitation"] for env in envs)
        # the phase and flags are drawn alike; the pose error is each backend's own, from
        # coordinates that agree to the 1e-6 rad below (1e-16 apart here, not 0)
        assert_close(a, b, abs_tol=1e-6)
        ca, cb = (env.sim.coordinates() for env in envs)
        assert ca.keys() == cb.keys()
        for name in ca:
            assert ca[name] == pytest.approx(cb[name], abs=1e-6), (seed, name)
        va, vb = (env.sim.state().dof_vel for env in envs)
        np.testing.assert_allclose(va, vb, atol=1e-3)


def test_catalogue_imitation_scenes_target_their_motions_speed() -> None:
    """Scenes that reward imitation target their motion's speed at its tempo, within 2 % (a
    scene with a clock alone keeps its own task's target; imitate-walk-2d+standing-starts
    observes walk-2d's 1.25 m/s for its 1.27), except imitate-run-2d+standing-starts, which
    observes run-2d's 3 m/s (the target its next stage, run-2d+clock, observes) while it
    imitates the run at 3.63."""
    from gaitforge.workers.motions import load_motion

    def rewards_imitation(name: str) -> bool:
        imitate = load_scene(name).task.imitate
        return imitate is not None and any(imitate.weights.model_dump().values())

    names = [n for n in catalogue() if rewards_imitation(n)]
    assert {"imitate-walk-2d", "imitate-run-2d", "imitate-walk-3d"} <= set(names)
    observes_next_stages_target = {"imitate-run-2d+standing-starts": load_scene("run-2d+clock")}
    for name in names:
        scene = load_scene(name)
        if name in observes_next_stages_target:
            assert scene.task.target_speed == observes_next_stages_target[name].task.target_speed
            continue
        motion = load_motion(scene.body, scene.task.clock.motion)
        pace = motion.speed_m_s * scene.task.clock.tempo
        assert scene.task.target_speed == pytest.approx(pace, rel=0.02), name


def test_myoleg_starts_with_the_pelvis_velocity_of_the_reference() -> None:
    env = MuscleEnv(_scene_3d(noise=0.0))
    for seed in (0, 1):
        env.reset(seed=seed)
        ref = env.reference_state()
        vel = env.sim.data.qvel[:3]  # the free root's origin is the pelvis's, world frame
        assert vel[env.sim.forward_axis] == pytest.approx(ref.forward_speed, abs=1e-4)
        assert vel[env.sim.up_axis] == pytest.approx(ref.pelvis_vertical_speed, abs=1e-4)
        assert abs(vel[1]) < 1e-4  # no sideways speed


@pytest.mark.parametrize("name", ["imitate-walk-2d", "imitate-run-2d", "imitate-walk-3d"])
def test_every_start_steps_healthily(name: str) -> None:
    env = MuscleEnv(name)
    for seed in range(30):
        env.reset(seed=seed)
        _, _, _, _, info = env.step(np.full(env.action_space.shape, 0.1, np.float32))
        assert info["health"] == "ok" and not info["fell"], (seed, info)


@pytest.mark.parametrize("turn", [0.5, -0.5])
def test_the_feet_term_compares_in_the_bodys_heading(turn: float) -> None:
    """A MyoLeg turned about the vertical still has its feet where the reference has them,
    relative to its pelvis and heading."""
    import dataclasses

    env = MuscleEnv(_scene_3d(noise=0.0))
    env.reset(seed=3)
    imitation = env.imitation
    ref = env.clock.reference(1)
    turned = dataclasses.replace(imitation.pose_of(ref), pelvis_rotation=ref.pelvis_rotation + turn)
    env.sim.set_pose(turned)
    state = env.sim.state()
    assert imitation.track(state, state, env.sim, 1).kernels["imitate_feet"] > 0.95
