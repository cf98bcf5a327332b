"""The rollout worker in-process (no Ray): fragment layout, seeding, bootstrapping, health."""

from __future__ import annotations

import dataclasses
import functools
import pickle

import numpy as np
import pytest
import torch
from gaitforge.workers.fragment import Fragment
from gaitforge.workers.policy_api import UniformExcitationPolicy
from gaitforge.workers.rollout import RolloutWorker
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.sim.faults import FaultInjection

ELBOW_MUSCLES = 6
MUSCLES = {"elbow-reach": ELBOW_MUSCLES, "walk-2d": 18}


def _worker(scene_name: str = "elbow-reach", **kwargs) -> RolloutWorker:
    scene = (kwargs.pop("scene", None) or load_scene(scene_name)).resolved()
    policy = functools.partial(UniformExcitationPolicy, MUSCLES[scene_name])
    return RolloutWorker(scene, policy, **kwargs)


def test_an_unresolved_scene_is_refused() -> None:
    """A worker may run on a node without the driver's saved profiles: it takes only scenes
    resolved where they were loaded."""
    policy = functools.partial(UniformExcitationPolicy, ELBOW_MUSCLES)
    with pytest.raises(
        ValueError,
        match=r"^RolloutWorker: scene 'elbow-reach' has fidelity 'default', not resolved",
    ):
        RolloutWorker(load_scene("elbow-reach"), policy)
    worker = _worker(num_envs=1, fragment_length=2)
    with pytest.raises(ValueError, match="not resolved"):
        worker.set_scene(load_scene("elbow-reach"))


def test_fragment_has_the_documented_layout() -> None:
    worker = _worker(num_envs=3, fragment_length=120)
    frag = worker.sample()
    t, k = 120, 3
    assert frag.obs.shape == (t, k, worker.envs[0].observation_space.shape[0])
    assert frag.action.shape == (t, k, ELBOW_MUSCLES)
    for key in ("logp", "value", "reward", "terminated", "truncated", "unhealthy"):
        assert getattr(frag, key).shape == (t, k), key
    assert frag.last_obs.shape == (k, frag.obs.shape[2])
    assert np.isfinite(frag.obs).all() and np.isfinite(frag.reward).all()
    assert frag.steps == t * k
    # elbow-reach episodes are 100 steps: each env truncated once, episode stats recorded
    assert frag.truncated.sum() == k
    assert len(frag.episode_return) == k
    assert (frag.episode_length == 100).all()
    assert np.allclose(frag.episode_return, frag.reward[:100].sum(axis=0), atol=1e-3)
    assert (frag.length, frag.num_envs, frag.episodes) == (t, k, k)


def test_fragment_dtypes_pickling_and_shape_check() -> None:
    frag = _worker(num_envs=2, fragment_length=110).sample()
    floats = (
        "obs",
        "action",
        "logp",
        "value",
        "reward",
        "bootstrap_value",
        "last_obs",
        "last_value",
    )
    assert all(getattr(frag, n).dtype == np.float32 for n in floats)
    assert all(getattr(frag, n).dtype == bool for n in ("terminated", "truncated", "unhealthy"))
    assert frag.episode_length.dtype == np.int64 and frag.episode_fell.dtype == bool
    assert frag.episode_return.dtype == frag.episode_distance.dtype == np.float64
    again = pickle.loads(pickle.dumps(frag))  # what crossing Ray does
    assert isinstance(again, Fragment) and again.steps == frag.steps == 220
    np.testing.assert_array_equal(again.obs, frag.obs)
    with pytest.raises(ValueError, match=r"\['reward'\] do not fit"):
        dataclasses.replace(frag, reward=frag.reward[:-1])


def test_same_seed_same_fragment() -> None:
    torch.manual_seed(0)
    a = _worker(num_envs=2, fragment_length=30, seed=5).sample()
    b = _worker(num_envs=2, fragment_length=30, seed=5).sample()
    # exactly: determinism is what is tested, both samples in this process on this machine
    np.testing.assert_array_equal(a.obs, b.obs)
    np.testing.assert_array_equal(a.action, b.action)


def test_new_weights_change_the_actions_and_set_the_version() -> None:
    worker = _worker(num_envs=2, fragment_length=20)
    policy = UniformExcitationPolicy(ELBOW_MUSCLES, spread=0.5)
    with torch.no_grad():
        policy.centre.fill_(0.9)
    frag = worker.sample(policy.state_dict(), version=3)
    assert frag.policy_version == 3
    assert frag.action.mean() > 0.7


def test_unhealthy_steps_are_flagged_and_counted_and_never_nan(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    for name, value in FaultInjection(nan_prob=0.1).as_environment().items():
        monkeypatch.setenv(name, value)
    worker = _worker("walk-2d", num_envs=2, fragment_length=100)
    frag = worker.sample()
    assert frag.unhealthy.any()
    assert sum(frag.health.values()) == frag.unhealthy.sum()
    assert np.isfinite(frag.obs).all() and np.isfinite(frag.reward).all()
    assert (frag.terminated[frag.unhealthy]).all()


def test_set_scene_switches_the_envs() -> None:
    worker = _worker(num_envs=2, fragment_length=5)
    worker.set_scene(load_scene("elbow-reach").resolved().model_copy(update={"episode_s": 0.1}))
    frag = worker.sample()
    assert frag.truncated.sum() == 2  # 5-step episodes now
