"""GAE against numbers worked by hand (gamma 0.9, lambda 0.5; rewards 1, 2, 3; values
0.5, 1, 1.5; V after the fragment 2)."""

from __future__ import annotations

import numpy as np
import pytest
from gaitforge.learner.gae import compute_gae

REWARD = np.array([[1.0], [2.0], [3.0]])
VALUE = np.array([[0.5], [1.0], [1.5]])
LAST = np.array([2.0])


def _gae(terminated=(0, 0, 0), truncated=(0, 0, 0), bootstrap=(0, 0, 0)):
    as_col = lambda x, dtype=float: np.array(x, dtype=dtype)[:, None]  # noqa: E731
    return compute_gae(
        REWARD,
        VALUE,
        as_col(terminated, bool),
        as_col(truncated, bool),
        as_col(bootstrap),
        LAST,
        gamma=0.9,
        lam=0.5,
    )


def test_no_episode_end_bootstraps_from_the_last_value() -> None:
    # delta2 = 3 + 0.9*2 - 1.5 = 3.3; delta1 = 2 + 0.9*1.5 - 1 = 2.35; delta0 = 1.4
    # A2 = 3.3; A1 = 2.35 + 0.45*3.3 = 3.835; A0 = 1.4 + 0.45*3.835 = 3.12575
    adv, ret = _gae()
    np.testing.assert_allclose(adv[:, 0], [3.12575, 3.835, 3.3], rtol=1e-6)
    np.testing.assert_allclose(ret[:, 0], [3.62575, 4.835, 4.8], rtol=1e-6)


def test_termination_cuts_the_future_to_zero() -> None:
    # step 1 ends by a fall: delta1 = 2 - 1 = 1, A1 = 1; A0 = 1.4 + 0.45*1 = 1.85; A2 = 3.3
    adv, _ = _gae(terminated=(0, 1, 0))
    np.testing.assert_allclose(adv[:, 0], [1.85, 1.0, 3.3], rtol=1e-6)


def test_truncation_bootstraps_from_the_final_observation() -> None:
    # step 1 times out with V(final obs) = 4: delta1 = 2 + 3.6 - 1 = 4.6; A0 = 1.4 + 2.07
    adv, _ = _gae(truncated=(0, 1, 0), bootstrap=(0, 4.0, 0))
    np.testing.assert_allclose(adv[:, 0], [3.47, 4.6, 3.3], rtol=1e-6)


@pytest.mark.parametrize("k", [1, 5])
def test_envs_are_independent(k: int) -> None:
    reward = np.tile(REWARD, (1, k))
    value = np.tile(VALUE, (1, k))
    flags = np.zeros((3, k), bool)
    adv, _ = compute_gae(reward, value, flags, flags, np.zeros((3, k)), np.full(k, 2.0), 0.9, 0.5)
    np.testing.assert_allclose(adv, np.tile([[3.12575], [3.835], [3.3]], (1, k)), rtol=1e-6)
