"""Joint targets through the reflex layer (``action.kind: joint_targets``) on real MuJoCo:
the action's names and size, targets that move joints where they point, the reference pose
as the base in imitation scenes, mirror maps, fault injection, and the scene and job checks."""

from __future__ import annotations

import numpy as np
import pytest
from gaitforge.learner.job import load_job
from gaitforge.learner.symmetry import MirrorMap
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.reflex import ReflexLayer
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.scenes.action import ActionSpec
from gaitforge.workers.scenes.io_names import action_names, lateral_axis
from gaitforge.workers.sim.faults import FaultInjection
from gaitforge.workers.spec_io import SpecError
from pydantic import ValidationError


def _targets(name: str, **action: object) -> Scene:
    """Catalogue scene ``name`` on MuJoCo with joint-target actions (``action`` fields)."""
    raw = load_scene(name).model_dump()
    raw["backends"] = ["mujoco"]
    raw["action"] = {"kind": "joint_targets", **action}
    return Scene.model_validate(raw)


def _run(env: MuscleEnv, action: np.ndarray, steps: int, seed: int = 0) -> list[dict]:
    env.reset(seed=seed)
    infos = []
    for _ in range(steps):
        _, _, terminated, truncated, info = env.step(action)
        infos.append(info)
        if terminated or truncated:
            break
    return infos


def test_the_action_is_one_target_per_kept_dof() -> None:
    scene = _targets("walk-2d")
    env = MuscleEnv(scene)
    assert env.act_names == [f"target:{d}" for d in env.sim.dof_names]
    assert env.action_space.shape == (len(env.sim.dof_names),)
    assert action_names(scene) == env.act_names
    obs, _ = env.reset(seed=0)
    obs, reward, *_ = env.step(np.full(env.action_space.shape, 0.5))
    assert np.isfinite(obs).all() and np.isfinite(reward)
    mirror = MirrorMap.from_names(env.obs_names, env.act_names, lateral_axis(scene.body))
    swapped = [env.act_names[i] for i in mirror.act_perm.tolist()]
    assert swapped[env.act_names.index("target:hip_flexion_r")] == "target:hip_flexion_l"


def test_a_target_moves_its_joint_toward_it() -> None:
    """The elbow (one dof, six muscles) driven to the top and the bottom of its target span
    ends near each, from the same start; with the gains at zero it is not driven at all."""
    env = MuscleEnv(_targets("elbow-reach", range_rad=0.6))
    base = env._default_pose[0]
    ends = {}
    for a in (0.0, 1.0):
        _run(env, np.array([a]), steps=50)
        ends[a] = env.sim.coordinates()["r_elbow_flex"]
    assert ends[1.0] - ends[0.0] > 0.6  # of the 1.2 rad between the two targets
    assert abs(ends[1.0] - (base + 0.6)) < 0.3
    limp = MuscleEnv(_targets("elbow-reach", kp=0.0, kd=0.0))
    infos = _run(limp, np.array([1.0]), steps=10)
    assert limp.sim.state().activations.max() < 1e-3
    assert all(i["health"] == "ok" for i in infos)


def test_the_reflex_excites_only_muscles_that_pull_toward_the_target() -> None:
    env = MuscleEnv(_targets("elbow-reach"))
    env.reset(seed=0)
    layer = ReflexLayer(env.scene.action, env.sim)
    q = np.array([env._default_pose[0]])
    layer.set_targets(np.array([1.0]), q, np.zeros(1))  # flex: target above q
    arms = env.sim.moment_arms()[:, 0]
    excitation = layer(q, np.zeros(1))
    assert (excitation[arms > 0] > 0).all()
    assert (excitation[arms < 0] == 0).all()


@pytest.mark.parametrize(("backend", "seeds"), [("mujoco", 4), ("opensim", 2)])
def test_imitation_targets_start_from_the_motion(backend: str, seeds: int) -> None:
    """At a = 0.5 the targets are the reference pose: the body tracks the walk more closely
    over its first 0.4 s than with no excitation at all, in every episode, on both
    backends."""
    raw = load_scene("imitate-walk-2d").model_dump()
    raw["action"] = {"kind": "joint_targets"}
    env, limp = MuscleEnv(Scene.model_validate(raw), backend), MuscleEnv("imitate-walk-2d", backend)
    for seed in range(seeds):
        tracked = _run(env, np.full(6, 0.5), steps=10, seed=seed)
        dropped = _run(limp, np.zeros(18), steps=10, seed=seed)
        err = np.mean([i["imitation"]["pose_error_rad"] for i in tracked])
        err_limp = np.mean([i["imitation"]["pose_error_rad"] for i in dropped])
        assert err < 0.7 * err_limp, (seed, err, err_limp)


def test_moment_arms_agree_between_backends() -> None:
    """The same pose gives moment arms of the same sign and size on MuJoCo and OpenSim
    (the reflex layer acts alike on both)."""
    scene = load_scene("walk-2d")
    arms = {}
    for backend in ("mujoco", "opensim"):
        env = MuscleEnv(scene, backend)
        env.reset(seed=0)
        arms[backend] = env.sim.moment_arms()
    big = np.abs(arms["opensim"]) > 0.01
    assert big.sum() >= 20
    assert (np.sign(arms["mujoco"][big]) == np.sign(arms["opensim"][big])).all()
    np.testing.assert_allclose(arms["mujoco"][big], arms["opensim"][big], rtol=0.5)


def test_a_simulator_failure_ends_the_step_with_its_cause(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    for name, value in FaultInjection(nan_prob=1.0).as_environment().items():
        monkeypatch.setenv(name, value)
    env = MuscleEnv(_targets("walk-2d"))
    obs, _ = env.reset(seed=0)
    after, reward, terminated, _, info = env.step(np.full(6, 0.5))
    assert terminated and reward == 0.0 and info["health"] != "ok"
    assert np.isfinite(after).all() and np.array_equal(after, obs)


def test_scene_checks_name_the_field() -> None:
    raw = load_scene("walk-2d").model_dump()
    raw["action"] = {"kind": "joint_targets", "reflex_hz": 130.0}
    with pytest.raises(ValidationError, match=r"reflex_hz 130\.0 must be a whole multiple"):
        Scene.model_validate(raw)
    with pytest.raises(ValidationError, match="kind"):
        ActionSpec.model_validate({"kind": "torques"})


def test_a_stage_can_switch_to_joint_targets(tmp_path) -> None:
    job = tmp_path / "job.yaml"
    job.write_text(
        "name: t\nbackend: mujoco\nstages:\n"
        "  - scene: imitate-walk-2d\n"
        "    scene_set: {action: {kind: joint_targets, kp: 4.0}}\n"
        "    env_steps: 1000\n"
    )
    _, scenes, _ = load_job(job)
    scene = scenes[0]
    assert scene.action.targets and scene.action.kp == 4.0 and scene.backends == ["mujoco"]
    older = job.read_text().replace("    scene_set: {action:", "    action:").replace("}}", "}")
    job.write_text(older)  # as older job files wrote it: named with where it goes now
    with pytest.raises(SpecError, match=r"stages\.0: action: .*\(scene_set: \{action: \{"):
        load_job(job)


def test_the_clock_scene_starts_standing_and_rewards_no_imitation() -> None:
    """walk-2d+clock: the reset pose is walk-2d's (no reference state), the phase starts at
    0, there are no imitation terms and a drifting pose does not end the episode; the clock
    is reported in ``info["clock"]``, and imitation's ``info["imitation"]`` is absent."""
    clock, plain = MuscleEnv("walk-2d+clock"), MuscleEnv("walk-2d")
    for seed in range(3):
        clock.reset(seed=seed)
        plain.reset(seed=seed)
        np.testing.assert_allclose(clock.sim.state().dof_pos, plain.sim.state().dof_pos)
        assert clock.clock.phase(0) == 0.0 and clock.imitation is None
    infos = _run(clock, np.zeros(6), steps=250)  # every target at the bottom of its span
    assert not any("lost_track" in i or "imitation" in i for i in infos)
    assert [i["clock"]["phase"] for i in infos[:3]] == [clock.clock.phase(k) for k in (1, 2, 3)]
    assert clock.reward_term_names == plain.reward_term_names
