"""The ankle postural reflex (``action.balance``): its offsets on fixed states, the real
MuJoCo MyoLeg that it keeps standing where the plain reflex layer topples, and bad balances
refused at load naming the field."""

from __future__ import annotations

import numpy as np
import pytest
from gaitforge.workers.balance import AnkleBalance
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.scenes.action import Balance
from gaitforge.workers.sim.base import SimState
from gaitforge.workers.spec_io import SpecError

ANKLES = ["ankle_angle_r", "ankle_angle_l"]
BALANCE = {"dofs": ANKLES, "lean_gain": 2.0, "speed_gain": 0.3}
DOFS = ["hip_flexion_r", "ankle_angle_r", "hip_flexion_l", "ankle_angle_l"]


def state(pelvis: list[float], velocity: list[float]) -> SimState:
    zero = np.zeros(3)
    return SimState(
        time=0.0,
        dof_pos=np.zeros(4),
        dof_vel=np.zeros(4),
        pelvis_pos=np.array(pelvis),
        pelvis_up=np.array([0.0, 0.0, 1.0]),
        pelvis_vel=np.array(velocity),
        pelvis_angvel=zero,
        activations=np.zeros(2),
        foot_forces=np.zeros(2),
    )


FEET = [np.array([0.1, 0.1, 0.05]), np.array([-0.1, -0.1, 0.05])]


def test_a_body_ahead_of_its_feet_gets_its_ankles_extended_by_the_gain() -> None:
    balance = AnkleBalance(Balance(dofs=ANKLES, lean_gain=2.0), DOFS, 0, 2)
    ahead = balance.offsets(state([0.1, 0.0, 1.05], [0.0, 0.0, 0.0]), FEET, 0.0)
    assert balance.lean(state([0.1, 0.0, 1.05], [0.0, 0.0, 0.0]), FEET) == pytest.approx(0.1)
    np.testing.assert_allclose(ahead, [0.0, -0.2, 0.0, -0.2])
    behind = balance.offsets(state([-0.1, 0.3, 1.05], [0.0, 0.0, 0.0]), FEET, 0.0)
    np.testing.assert_allclose(behind, [0.0, 0.2, 0.0, 0.2])


def test_the_speed_term_reads_the_speed_over_the_target() -> None:
    balance = AnkleBalance(Balance(dofs=ANKLES, lean_gain=0.0, speed_gain=0.5), DOFS, 0, 2)
    standing = state([0.0, 0.0, 1.05], [1.0, 0.0, 0.0])
    np.testing.assert_allclose(balance.offsets(standing, FEET, 1.0), np.zeros(4))
    np.testing.assert_allclose(balance.offsets(standing, FEET, 0.0), [0.0, -0.5, 0.0, -0.5])
    np.testing.assert_allclose(balance.offsets(standing, FEET, 1.4), [0.0, 0.2, 0.0, 0.2])


def test_a_fallen_body_does_not_divide_by_its_height() -> None:
    balance = AnkleBalance(Balance(dofs=ANKLES, lean_gain=1.0), DOFS, 0, 2)
    assert balance.lean(state([0.3, 0.0, 0.06], [0.0, 0.0, 0.0]), FEET) == pytest.approx(1.0)


def standing_seconds(balance: dict | None, seconds: float) -> float:
    """MyoLeg on walk-3d at target speed 0, joint-target actions held at the standing pose,
    with ``balance``: how long it stands (s), up to ``seconds``."""
    overrides: dict = {
        "action.kind": "joint_targets",
        "control_hz": 25,
        "task.target_speed": 0.0,
        "action.balance": balance,
    }
    env = MuscleEnv(load_scene("walk-3d", overrides))
    env.reset(seed=0)
    for step in range(round(seconds * 25)):
        _, _, fell, _, info = env.step(np.full(env.action_space.shape, 0.5))
        assert info["health"] == "ok"
        if fell:
            return step / 25
    return seconds


def test_the_reflex_keeps_a_toppling_myoleg_standing() -> None:
    assert standing_seconds(None, 5.0) < 3.0
    assert standing_seconds(BALANCE, 5.0) == 5.0


@pytest.mark.parametrize(
    ("overrides", "named"),
    [
        ({"action.balance": BALANCE}, "joint_targets"),
        (
            {"action.kind": "joint_targets", "action.balance.dofs": ["ankle"]},
            "action.balance.dofs.0",
        ),
        ({"action.kind": "joint_targets", "action.balance.lean_gain": 1e6}, "lean_gain"),
        ({"action.kind": "joint_targets", "action.balance.tilt_gain": 1.0}, "tilt_gain"),
    ],
)
def test_bad_balances_are_refused_at_load_naming_the_field(overrides: dict, named: str) -> None:
    raw = {"action.balance": BALANCE} if "action.balance" not in overrides else {}
    with pytest.raises((SpecError, ValueError), match=named):
        load_scene("walk-3d", {**raw, **overrides})


def test_a_balance_needs_a_locomotion_task() -> None:
    with pytest.raises((SpecError, ValueError), match="locomotion"):
        load_scene(
            "elbow-reach",
            {"action.kind": "joint_targets", "action.balance": {**BALANCE, "dofs": ["elbow"]}},
        )
