"""Bad motion files fail at load with one line naming the file, the field and what is allowed."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import yaml
from gaitforge.workers.motions import MotionError, load_motion, load_motion_file, motion_file
from gaitforge.workers.spec_io import SpecError


def _write(tmp_path: Path, edit: Callable[[dict], None]) -> Path:
    raw = yaml.safe_load(motion_file("gait2d", "walk").read_text())
    edit(raw)
    path = tmp_path / "bad-motion.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


def _open_cycle(raw: dict) -> None:
    """The knee over 80 % of a cycle stretched onto the whole: the last sample is far from
    the first."""
    n = len(raw["pelvis_height"])
    knee = np.array(raw["joint_angles"]["knee_angle_r"])
    stretched = np.interp(np.arange(n) * 0.8, np.arange(n), knee)
    raw["joint_angles"]["knee_angle_r"] = stretched.tolist()


def _kinked_cycle(raw: dict) -> None:
    """Angles continuous at the seam but their speed reverses there (half a sine wave)."""
    n = len(raw["pelvis_height"])
    raw["joint_angles"]["hip_flexion_r"] = (0.5 * np.sin(np.pi * np.arange(n) / n)).tolist()


@pytest.mark.parametrize(
    ("edit", "fragments"),
    [
        (_open_cycle, ["joint_angles.knee_angle_r", "does not close"]),
        (_kinked_cycle, ["joint_angles.hip_flexion_r", "speed does not close"]),
        (lambda r: r.update(period_s=0), ["period_s", "greater than 0"]),
        (lambda r: r.update(period_s=-1.2), ["period_s", "greater than 0"]),
        (lambda r: r.update(speed_m_s=0.0), ["speed_m_s", "greater than 0"]),
        (lambda r: r.update(speed_m_s=-1), ["speed_m_s", "greater than 0"]),
        (
            lambda r: r["joint_angles"].update(hip_adduction_r=r["joint_angles"]["hip_flexion_r"]),
            ["joint_angles.hip_adduction_r", "no such joint", "knee_angle_r"],
        ),
        (lambda r: r.update(feet=["foot_right", "hoof"]), ["feet.1", "hoof", "foot_left"]),
        (
            lambda r: r["joint_angles"]["ankle_angle_l"].pop(),
            ["joint_angles.ankle_angle_l", "59 samples, expected 60"],
        ),
        (lambda r: r["stance"].pop("foot_left"), ["stance", "exactly the feet"]),
        (lambda r: r.update(body="quadruped"), ["body", "quadruped"]),
        (lambda r: r.pop("period_s"), ["period_s", "Field required"]),
        (lambda r: r.update(cadence=1.0), ["cadence", "Extra inputs"]),
    ],
)
def test_bad_motion_file(
    tmp_path: Path, edit: Callable[[dict], None], fragments: list[str]
) -> None:
    path = _write(tmp_path, edit)
    with pytest.raises(MotionError) as info:
        load_motion_file(path, "gait2d")
    message = str(info.value)
    assert isinstance(info.value, SpecError)
    assert "\n" not in message
    assert message.startswith(f"{path}: ")
    for fragment in fragments:
        assert fragment in message, message
    with pytest.raises(MotionError):  # the same through load_motion with a path
        load_motion("gait2d", str(path))


def test_a_good_copy_loads(tmp_path: Path) -> None:
    path = _write(tmp_path, lambda r: None)
    assert load_motion_file(path, "gait2d").joints == load_motion("gait2d", "walk").joints


def test_unknown_motion_names_the_available_ones() -> None:
    with pytest.raises(MotionError) as info:
        load_motion("gait2d", "moonwalk")
    message = str(info.value)
    assert "\n" not in message
    assert "gait2d-moonwalk.yaml" in message and "'moonwalk'" in message
    assert "available: run, walk" in message
    with pytest.raises(MotionError, match="no such motion"):
        load_motion("gait2d", "walk-excitations")


def test_motion_for_another_body(tmp_path: Path) -> None:
    path = _write(tmp_path, lambda r: None)
    with pytest.raises(MotionError, match=r"body: the motion is for 'gait2d', not for 'myoleg'"):
        load_motion_file(path, "myoleg")
    myoleg_walk = yaml.safe_load(motion_file("myoleg", "walk").read_text())
    myoleg_walk["body"] = "gait2d"  # MyoLeg's hip_adduction_r is no gait2d joint
    other = tmp_path / "other.yaml"
    other.write_text(yaml.safe_dump(myoleg_walk, sort_keys=False))
    with pytest.raises(MotionError, match=r"joint_angles.hip_adduction_r: body 'gait2d' has no"):
        load_motion_file(other, "gait2d")


def test_unreadable_files(tmp_path: Path) -> None:
    missing = tmp_path / "missing.yaml"
    with pytest.raises(MotionError, match=f"{missing}: cannot read"):
        load_motion_file(missing)
    broken = tmp_path / "broken.yaml"
    broken.write_text("name: [walk\n")
    with pytest.raises(MotionError, match=f"{broken}: not valid YAML"):
        load_motion_file(broken)
    scalar = tmp_path / "scalar.yaml"
    scalar.write_text("3\n")
    with pytest.raises(MotionError, match="<root>: expected a mapping"):
        load_motion_file(scalar)
