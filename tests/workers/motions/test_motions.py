"""The shipped reference motions load, close at the seam, interpolate and mirror correctly."""

from __future__ import annotations

import numpy as np
import pytest
from gaitforge.workers.bodies.topology import topology_for
from gaitforge.workers.motions import (
    available_motions,
    excitations_at,
    load_excitations,
    load_motion,
)
from gaitforge.workers.motions.model import PELVIS_SERIES, seam_problem

SHIPPED = [
    ("gait2d", "walk"),
    ("gait2d", "run"),
    ("myoleg", "walk"),
    ("myoleg", "run"),
    ("gait2354", "walk"),
    ("gait14dof22musc", "walk"),
]


def test_available() -> None:
    assert available_motions("gait2d") == ["run", "walk"]
    assert available_motions("myoleg") == ["run", "walk"]
    assert available_motions("gait2354") == ["walk"]
    assert available_motions("gait14dof22musc") == ["walk"]
    assert available_motions("myoelbow") == []


@pytest.mark.parametrize(("body", "name"), SHIPPED)
def test_shipped_motion_is_sound(body: str, name: str) -> None:
    motion = load_motion(body, name)
    topo = topology_for(body)
    assert motion.body == body and motion.name == name
    assert 50 <= motion.samples <= 100
    assert set(motion.joints) <= set(topo.dof_defaults)
    assert set(motion.feet) == set(topo.feet)
    assert motion.period_s > 0 and motion.speed_m_s > 0
    assert "speed" in motion.source and ".mot" in motion.source
    # plausible gait figures: stride period, speed, pelvis height, each foot on the ground
    # for part of the cycle, never both feet in the air during a walk
    assert 0.5 < motion.period_s < 1.5
    assert (0.8 < motion.speed_m_s < 1.6) if name == "walk" else (2.5 < motion.speed_m_s < 4.5)
    assert all(0.8 < h < 1.05 for h in motion.pelvis_height)
    stance = np.array([motion.stance[f] for f in motion.feet])
    assert all(0.1 < share < 0.8 for share in stance.mean(axis=1))
    if name == "walk":
        assert stance.any(axis=0).all()
    assert motion.stance["foot_right"][0], "phase 0 is a right heel strike"
    assert not motion.stance["foot_right"][motion.samples // 2 + 10]


@pytest.mark.parametrize(("body", "name"), SHIPPED)
def test_seam_closes(body: str, name: str) -> None:
    motion = load_motion(body, name)
    for joint, values in motion.joint_angles.items():
        assert seam_problem(np.asarray(values)) is None, joint
    for field in PELVIS_SERIES:
        values = getattr(motion, field)
        if values is not None:
            assert seam_problem(np.asarray(values)) is None, field
    before, after = motion.at(1 - 1e-9), motion.at(0.0)
    for joint in motion.joints:
        assert before.joints[joint] == pytest.approx(after.joints[joint], abs=1e-6)
        assert before.joint_speeds[joint] == pytest.approx(after.joint_speeds[joint], abs=1e-5)
    assert motion.at(1.25).joints == motion.at(0.25).joints  # exactly: 1.25 % 1 is 0.25
    assert motion.at(-0.75).joints == pytest.approx(motion.at(0.25).joints)


@pytest.mark.parametrize(("body", "name"), SHIPPED)
def test_at_matches_samples_and_speeds(body: str, name: str) -> None:
    motion = load_motion(body, name)
    n = motion.samples
    for k in (0, 7, n // 2, n - 1):
        state = motion.at(k / n)
        for joint in motion.joints:
            assert state.joints[joint] == pytest.approx(motion.joint_angles[joint][k], abs=1e-9)
        assert state.pelvis_height == pytest.approx(motion.pelvis_height[k])
        assert state.pelvis_pitch == pytest.approx(motion.pelvis_pitch[k])
        for foot in motion.feet:
            assert state.feet_rel_pelvis[foot] == pytest.approx(motion.feet_rel_pelvis[foot][k])
            assert state.stance[foot] == motion.stance[foot][k]
    # speeds: the angles' rate of change over one sample interval, wrapping at the seam
    dt = motion.period_s / n
    for k in (0, n // 3, n - 1):
        state = motion.at(k / n)
        for joint in motion.joints:
            angles = motion.joint_angles[joint]
            rate = (angles[(k + 1) % n] - angles[k - 1]) / (2 * dt)
            assert state.joint_speeds[joint] == pytest.approx(rate, abs=1e-9)
    mean_speed = np.mean([motion.at(k / n).forward_speed for k in range(n)])
    assert mean_speed == pytest.approx(motion.speed_m_s, abs=0.02)
    # the walk's hip flexion velocity reverses twice per cycle (flexion, then extension)
    hip = np.array(motion.joint_angles["hip_flexion_r"])
    assert np.ptp(hip) > 0.5


@pytest.mark.parametrize(("body", "name"), SHIPPED)
def test_mirrored_state_swaps(body: str, name: str) -> None:
    motion = load_motion(body, name)
    state = motion.at(0.3)
    half = motion.at(0.8)  # half a cycle later the other leg does what this one did
    mirrored = motion.mirrored_state(state)
    assert set(mirrored.joints) == set(state.joints)
    for joint in motion.joints:
        other = joint[:-2] + ("_l" if joint.endswith("_r") else "_r")
        assert mirrored.joints[other] == state.joints[joint]
        assert mirrored.joint_speeds[other] == state.joint_speeds[joint]
    assert mirrored.stance == {
        "foot_left": state.stance["foot_right"],
        "foot_right": state.stance["foot_left"],
    }
    lateral = 1 if body == "myoleg" else 2
    for a, b in (("foot_right", "foot_left"), ("foot_left", "foot_right")):
        assert mirrored.feet_rel_pelvis[b][lateral] == -state.feet_rel_pelvis[a][lateral]
        assert mirrored.feet_rel_pelvis[b][0] == state.feet_rel_pelvis[a][0]
    assert mirrored.pelvis_list == -state.pelvis_list
    assert mirrored.pelvis_rotation == -state.pelvis_rotation
    assert mirrored.pelvis_height == state.pelvis_height
    assert motion.mirrored_state(mirrored) == state
    # a mirrored state resembles the motion half a cycle on (symmetric gait): within 0.25 rad
    errors = [abs(mirrored.joints[j] - half.joints[j]) for j in motion.joints]
    assert float(np.sqrt(np.mean(np.square(errors)))) < 0.25
    # the right foot is on the right, by more than 1 cm: +Z for neutral bodies, -Y for MyoLeg
    # (gait14dof22musc's right foot is 3.0 cm right of its pelvis here, gait2354's 3.4)
    right = state.feet_rel_pelvis["foot_right"][lateral]
    assert right < -0.01 if body == "myoleg" else right > 0.01


def test_excitations() -> None:
    motion = load_motion("gait2d", "walk")
    exc = load_excitations("gait2d", "walk")
    assert list(exc) == topology_for("gait2d").muscles
    for values in exc.values():
        assert values.shape == (motion.samples,)
        assert values.min() >= 0.0 and values.max() <= 1.0
    at = excitations_at(exc, 5 / motion.samples)
    assert at == {m: pytest.approx(float(v[5])) for m, v in exc.items()}
    between = excitations_at(exc, 5.5 / motion.samples)
    for m, v in exc.items():
        assert between[m] == pytest.approx(0.5 * (v[5] + v[6]))
    # soleus and gastrocnemius fire in stance (push-off), tibialis anterior in swing too
    assert exc["soleus_r"][: motion.samples // 2].mean() > exc["soleus_r"][-15:].mean()
