"""The ``overspeed`` reward term: charges running faster than the target speed, never
slower (a start from standing is not charged, as ``target_speed`` charges it)."""

from __future__ import annotations

import numpy as np
import pytest
from gaitforge.workers.rewards import StepContext, reward_terms
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.scenes.spec import Scene
from gaitforge.workers.sim.base import SimState


def _state_at(x_m: float) -> SimState:
    """An upright body at rest with its pelvis ``x_m`` m along the forward axis (x)."""
    zeros = np.zeros(3)
    return SimState(
        time=0.0,
        dof_pos=np.zeros(2),
        dof_vel=np.zeros(2),
        pelvis_pos=np.array([x_m, 1.0, 0.0]),
        pelvis_up=np.array([0.0, 1.0, 0.0]),
        pelvis_forward=np.array([1.0, 0.0, 0.0]),
        pelvis_vel=zeros,
        pelvis_angvel=zeros,
        activations=np.zeros(4),
        foot_forces=np.zeros(2),
    )


def _terms(speed: float, target: float | None) -> dict[str, float]:
    """The terms of one 0.04-s control step at ``speed`` m/s against ``target`` m/s."""
    dt = 0.04
    ctx = StepContext(
        previous=_state_at(0.0),
        excitation=np.zeros(4),
        previous_excitation=np.zeros(4),
        dt=dt,
        forward_axis=0,
        up_axis=1,
        target_speed=target,
        reach_index=None,
        reach_target=0.0,
    )
    return reward_terms(_state_at(speed * dt), ctx)


def test_overspeed_charges_only_the_speed_above_the_target() -> None:
    assert _terms(3.5, 3.0)["overspeed"] == pytest.approx(-0.25)
    assert _terms(3.5, 3.0)["target_speed"] == pytest.approx(-0.25)
    assert _terms(1.0, 3.0)["overspeed"] == 0.0, "slower than the target: not charged"
    assert _terms(1.0, 3.0)["target_speed"] == pytest.approx(-4.0)
    assert _terms(5.0, None)["overspeed"] == 0.0


def test_overspeed_needs_a_target_speed() -> None:
    data = load_scene("stand-2d").model_dump()
    data["task"]["reward"]["overspeed"] = 1.0
    data["task"]["target_speed"] = None
    with pytest.raises(ValueError, match=r"overspeed 1\.0: the task has no target speed"):
        Scene.model_validate(data)
    data["task"]["target_speed"] = 1.2
    assert Scene.model_validate(data).task.reward.overspeed == 1.0
