"""The reflex gait controller (``workers.gait_reflex``) on the imported 2019 challenge body:
it runs on MuJoCo and OpenSim from the same sensors, its wiring and parameters are checked
early, and a candidate's score is made of the parts it reports."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.gait_measure import GaitMeasure, score_candidate
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.scenes.reflex_parameters import DEFAULTS, NAMES
from gaitforge.workers.spec_io import SpecError

SHORT = {"episode_s": 0.5}


def test_the_sensors_agree_between_mujoco_and_opensim() -> None:
    """At the same start pose both simulators sense nearly the same fibre lengths (their
    muscles are fitted to the same model; 0.05 of optimal length allows MuJoCo's rigid
    tendon against OpenSim's compliant one), and the controller runs on both. (Its first
    excitations may differ: which foot touches the floor first at the start differs.)"""
    envs = [MuscleEnv(load_scene("reflex-walk-3d", SHORT), b) for b in ("mujoco", "opensim")]
    for env in envs:
        env.reset(seed=3)
    lengths = [env.sim.muscle_sensors()[0] for env in envs]
    np.testing.assert_allclose(lengths[0], lengths[1], atol=0.05)
    first = [env.gait(env.sim.state()) for env in envs]
    for excitation in first:
        assert excitation.shape == (22,) and 0.0 <= excitation.min() <= excitation.max() <= 1.0


def test_a_loaded_foot_is_in_stance_and_a_lifted_one_swings() -> None:
    """Mid-stride (the right foot on the ground, the left knee bent and its foot in the
    air) the right leg starts in stance and the left in swing with its knee flexing."""
    mid_stride = {
        **SHORT,
        "action.start_speed": 1.5,
        "action.parameters": {
            "pose.lead_hip": 0.35,
            "pose.trail_hip": -0.26,
            "pose.trail_knee": 0.7,
            "pose.lean": 0.17,
        },
    }
    env = MuscleEnv(load_scene("reflex-walk-3d", mid_stride))
    env.reset(seed=0)
    right, left = env.gait._phases
    assert right.stance and not right.swing
    assert left.swing and left.flex_knee and not left.stance


def test_the_trunk_and_pelvis_are_sensed_along_the_heading() -> None:
    """A body turned about the vertical senses the same lean, list and speeds as one facing
    ahead: they are read in the pelvis's heading frame (to 1e-9: only rotations are
    summed)."""
    env = MuscleEnv(load_scene("reflex-walk-3d", {**SHORT, "action.start_speed": 1.5}))
    env.reset(seed=0)
    state = env.sim.state()
    up, forward = np.eye(3)[env.sim.up_axis], np.eye(3)[env.sim.forward_axis]
    right = np.cross(forward, up)
    state.pelvis_up = state.pelvis_up + 0.05 * forward - 0.03 * right
    state.pelvis_up /= np.linalg.norm(state.pelvis_up)
    state.pelvis_vel = state.pelvis_vel + 0.2 * right
    angle, (x, y, z) = 0.8, up
    across = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])  # up x (.)
    turn = np.eye(3) + np.sin(angle) * across + (1 - np.cos(angle)) * across @ across
    turned = copy.copy(state)
    for name in ("pelvis_up", "pelvis_forward", "pelvis_vel"):
        setattr(turned, name, turn @ getattr(state, name))
    ahead, aside = env.gait._read(state), env.gait._read(turned)
    for name in ("lean", "list_right", "forward_speed", "right_speed"):
        assert getattr(aside, name) == pytest.approx(getattr(ahead, name), abs=1e-9), name
    assert abs(ahead.list_right) > 0.01 and abs(ahead.right_speed) > 0.1  # not trivially 0


def test_placement_follows_the_pelvis_over_the_stance_foot() -> None:
    """Song and Geyer's position terms: with ``swing.position_gain`` g a leg aims g rad
    further forward per rad the pelvis is ahead of the other foot, and with
    ``swing.lateral_position_gain`` its hip aims that much more adducted per rad the other
    foot is under the body; at 0 (the default) the aims are the 2019 baseline's."""
    mid_stride = {**SHORT, "action.start_speed": 1.5, "action.parameters": {"pose.lead_hip": 0.3}}
    plain = MuscleEnv(load_scene("reflex-walk-3d", mid_stride))
    plain.reset(seed=0)
    gains = {"swing.position_gain": 0.5, "swing.lateral_position_gain": -0.4}
    tuned = load_scene(
        "reflex-walk-3d", {**mid_stride, "action.parameters": {"pose.lead_hip": 0.3, **gains}}
    )
    env = MuscleEnv(tuned)
    env.reset(seed=0)
    s = env.gait._read(env.sim.state())
    (aim, adduction), (aim0, adduction0) = env.gait.aims(s), plain.gait.aims(s)
    ahead = s.lean - s.leg  # rad the pelvis is ahead of each foot
    toward = np.array([1.0, -1.0]) * s.list_right  # the list toward each leg
    under = s.adduction[::-1] - toward  # the other foot's frontal angle toward each side
    np.testing.assert_allclose(aim - aim0, 0.5 * ahead[::-1], atol=1e-12)
    np.testing.assert_allclose(adduction - adduction0, -0.4 * under, atol=1e-12)
    assert ahead[0] < -0.05  # the right foot leads: the left leg aims further back


def test_the_policy_adds_a_residual_to_the_controller() -> None:
    """An action of 0.5 adds nothing; 1.0 adds ``action.residual`` to every excitation."""
    excitations = []
    for action in (0.5, 1.0):
        env = MuscleEnv(load_scene("reflex-walk-3d", SHORT))
        env.reset(seed=0)
        controller = env.gait(env.sim.state())
        env.gait.reset(env.sim.state())  # the controller's first step again
        env.step(np.full(22, action, dtype=np.float32))
        excitations.append((controller, env.excitation.copy()))
    (plain, neutral), (_, pushed) = excitations
    np.testing.assert_allclose(neutral, plain, atol=1e-12)
    np.testing.assert_allclose(pushed, np.minimum(plain + 0.2, 1.0), atol=1e-12)


def test_parameters_are_checked_by_name_and_bound() -> None:
    with pytest.raises(SpecError, match=r"action.*unknown"):
        load_scene("reflex-walk-3d", {"action.parameters": {"trunk.nope": 1.0}})
    with pytest.raises(SpecError, match=r"ankle.ta_kp.*outside \[0.0, 6.0\]"):
        load_scene("reflex-walk-3d", {"action.parameters": {"ankle.ta_kp": 9.0}})


def test_a_wiring_that_names_what_the_body_lacks_is_refused_at_load(tmp_path: Path) -> None:
    shipped = Path(__file__).resolve().parents[2] / "workers/bodies/data/reflex"
    text = (shipped / "gait14dof22musc.yaml").read_text()
    cases = {
        "muscle": (text.replace("soleus_r", "soleus_x"), r"right\.groups\.SOL: .* 'soleus_x'"),
        "dof": (text.replace("knee_angle_l", "knee_x"), r"left\.knee: .* no dof 'knee_x'"),
        "body": (text.replace("body: gait14dof22musc", "body: gait2d"), "wires body 'gait2d'"),
    }
    for name, (changed, message) in cases.items():
        wiring = tmp_path / f"{name}.yaml"
        wiring.write_text(changed)
        with pytest.raises(SpecError, match=message):
            load_scene("reflex-walk-3d", {**SHORT, "action.wiring": str(wiring)})


def test_a_wiring_that_names_what_the_scene_does_not_keep_is_refused() -> None:
    env = MuscleEnv(load_scene("reflex-walk-3d", SHORT))
    muscles = [m for m in env.sim.muscle_names if m != "soleus_r"]
    scene = load_scene("reflex-walk-3d", {**SHORT, "keep.muscles": muscles})
    with pytest.raises(ValueError, match=r"no \['muscle soleus_r'\]"):
        MuscleEnv(scene)


def test_a_candidates_cost_is_made_of_its_parts() -> None:
    env = MuscleEnv(load_scene("reflex-walk-3d", SHORT))
    measure = GaitMeasure(min_speed=1.0, fall=2.0, speed=3.0, effort=0.5)
    score = score_candidate(env, DEFAULTS, [0, 1], measure)
    assert score.episodes == 2 and 0 < score.env_steps <= 2 * env.scene.steps_per_episode
    assert 0.0 <= score.alive <= 1.0 and 0.0 <= score.falls <= 1.0
    # one episode each: the parts' mean recombines into the mean cost (speed < min_speed)
    singles = [score_candidate(env, DEFAULTS, [seed], measure) for seed in (0, 1)]
    for single in singles:
        expected = (
            2.0 * (1.0 - single.alive)
            + 3.0 * max(1.0 - single.speed, 0.0)
            + 0.5 * single.excitation_sq
        )
        assert single.cost == pytest.approx(expected, rel=1e-9)
    assert score.cost == pytest.approx(np.mean([s.cost for s in singles]), rel=1e-9)
    assert len(NAMES) == len(DEFAULTS)


@pytest.mark.parametrize("scene", ["walk-2d", "walk-3d"])
def test_the_shipped_wirings_drive_their_bodies(scene: str) -> None:
    """gait2d (planar: no frontal circuits) and MyoLeg (80 muscles in eleven groups) take the
    same controller from their shipped wiring: a few steps give excitations in [0, 1]."""
    env = MuscleEnv(load_scene(scene, {"action.kind": "reflex_gait", "episode_s": 0.1}))
    env.reset(seed=0)
    for _ in range(5):
        env.step(np.full(env.action_space.shape, 0.5, dtype=np.float32))
        assert 0.0 <= env.excitation.min() <= env.excitation.max() <= 1.0
    assert env.excitation.max() > 0.01  # the feedback acts, not only the floor
