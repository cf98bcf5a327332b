"""Shared fixtures."""

from __future__ import annotations

import mujoco
import pytest
from gaitforge.workers.sim.mujoco.mjcf_models import myoleg_spec


@pytest.fixture(scope="session")
def myoleg_model() -> mujoco.MjModel:
    """MyoLeg as shipped (compiled once; do not modify)."""
    return myoleg_spec().compile()
