"""bench/start_offsets.py and bench/start_distil.py: offsets in time follow the leading leg,
reach a real MuJoCo episode as clipped corrections to the policy's actions, and the DAgger
labels are the teacher's action there (real simulator, the shipped runner, short scenes)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from gaitforge.workers.episode import Observer

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "bench"))
import start_distil  # noqa: E402
import start_offsets  # noqa: E402
from start_offsets import (  # noqa: E402
    MIRROR_OBS,
    StartOffsets,
    distance_by,
    mirrored_order,
    open_runner,
    summary,
    with_offsets,
)

NAMES = ["target:hip_flexion_r", "target:knee_angle_r", "target:hip_flexion_l",
         "target:knee_angle_l", "clock_rate"]  # fmt: skip


class Actions(Observer):
    """The actions the env was given and whether the episode was mirrored."""

    def on_reset(self, env: Any, obs: np.ndarray, info: dict[str, Any]) -> None:
        self.actions: list[np.ndarray] = []
        self.mirrored = obs[env.obs_names.index(MIRROR_OBS)] > 0

    def on_step(self, env: Any, action: np.ndarray, obs: np.ndarray, reward: float,
                terminated: bool, truncated: bool, info: dict[str, Any]) -> None:  # fmt: skip
        self.actions.append(np.array(action))


def test_mirrored_order_swaps_the_legs_and_keeps_the_rest():
    assert mirrored_order(NAMES) == [2, 3, 0, 1, 4]


def test_offsets_are_linear_between_knots_zero_after_the_last_and_swapped_when_mirrored():
    values = np.array([[0.1, 0.2, 0.3, 0.4, 0.0], [0.3, 0.0, -0.1, 0.0, 0.2]])
    offsets = StartOffsets((0.0, 0.4, 1.0), values, mirrored_order(NAMES))
    np.testing.assert_allclose(offsets.at(0.0, False), values[0])
    np.testing.assert_allclose(offsets.at(0.2, False), (values[0] + values[1]) / 2)
    np.testing.assert_allclose(offsets.at(0.7, False), values[1] / 2)
    np.testing.assert_allclose(offsets.at(1.0, False), 0.0)
    np.testing.assert_allclose(offsets.at(3.0, False), 0.0)
    np.testing.assert_allclose(offsets.at(0.0, True), [0.3, 0.4, 0.1, 0.2, 0.0])
    with pytest.raises(ValueError, match=r"expected \(2, 5\)"):
        StartOffsets((0.0, 0.4, 1.0), values[:, :4], mirrored_order(NAMES))


def test_summary_counts_falls_and_speeds_as_evaluate_does():
    hz = 25.0
    stood = [0.1 * k for k in range(251)]  # 10 s at 2.5 m/s
    fell = [0.1 * k for k in range(51)]  # 2 s at 2.5 m/s, then down
    s = summary([(stood, False), (fell, True)], hz, 10.0)
    assert s["fall_rate"] == 0.5
    assert s["mean_speed"] == pytest.approx(2.5)  # each over its own length
    assert s["survivor_speed"] == pytest.approx(2.5)
    assert distance_by(fell, 4.0, hz) == pytest.approx(5.0)  # its last, after the fall
    assert s["distance_4s"] == pytest.approx((10.0 + 5.0) / 2)


@pytest.fixture(scope="module")
def runner_and_policy():
    policy, runner, _ = open_runner(REPO / "examples/policies/run-2d", "run-2d+clock")
    yield runner, policy
    runner.close()


def test_offsets_reach_the_episode_clipped_and_follow_the_leading_leg(runner_and_policy):
    runner, _ = runner_and_policy
    n_act = len(runner.act_names)
    values = np.zeros((2, n_act))
    values[0, 0], values[0, 1] = 0.3, 0.7  # hip_r up, knee_r past the top (clipped)
    offsets = StartOffsets((0.0, 0.2, 0.4), values, mirrored_order(runner.act_names))
    seen = {}
    for seed in range(8):
        log = Actions()
        runner.run(with_offsets(lambda obs: np.full(n_act, 0.5), offsets, runner), seed, [log], 12)
        seen[bool(log.mirrored)] = log.actions
    assert set(seen) == {False, True}, "8 seeds should give both sides"
    right = runner.act_names.index("target:hip_flexion_r")
    left = runner.act_names.index("target:hip_flexion_l")
    plain, mirrored = seen[False], seen[True]
    assert plain[0][right] == pytest.approx(0.8) and plain[0][right + 1] == 1.0  # clipped
    assert plain[0][left] == pytest.approx(0.5)
    assert mirrored[0][left] == pytest.approx(0.8) and mirrored[0][right] == pytest.approx(0.5)
    assert plain[1][right] == pytest.approx(0.5 + 0.3 * (1 - 0.04 / 0.2))  # step 1 at 0.04 s
    for step in range(10, 12):  # from 0.4 s on: the policy's own actions
        np.testing.assert_allclose(plain[step], 0.5)


def test_distil_labels_are_the_teachers_actions_with_the_offsets(runner_and_policy):
    runner, policy = runner_and_policy
    n_act = len(runner.act_names)
    values = np.full((1, n_act), 0.05)
    offsets = StartOffsets((0.0, 0.4), values, mirrored_order(runner.act_names))
    obs, labels = start_distil.collect(runner, policy, policy, offsets, range(1), True)
    assert obs.shape[0] == labels.shape[0] > 10 and labels.shape[1] == n_act
    first = start_distil.mean_action(policy, obs[0])
    np.testing.assert_allclose(labels[0], np.clip(first + 0.05, 0, 1), atol=1e-6)
    np.testing.assert_allclose(labels[10], start_distil.mean_action(policy, obs[10]), atol=1e-6)
    assert np.all((labels >= 0) & (labels <= 1))


def test_a_wider_target_span_leaves_the_policy_alone_as_it_was():
    """``--range-rad``: the policy's actions rescaled to the wider span give the same targets,
    so the same episode."""
    distances = {}
    for range_rad in (None, 1.2):
        runner_ckpt = str(REPO / "examples/policies/run-2d")
        start_offsets.open_worker(runner_ckpt, "run-2d+clock", (0.0, 0.4), range_rad)
        assert start_offsets._worker["runner"].scene.action.range_rad == (range_rad or 0.6)
        distances[range_rad], _ = start_offsets.worker_episode(None, 3, 1.0)
        start_offsets._worker["runner"].close()
    assert len(distances[None]) == 26
    np.testing.assert_allclose(distances[1.2], distances[None], atol=1e-9)
