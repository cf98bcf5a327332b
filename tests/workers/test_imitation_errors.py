"""Bad clock and imitation settings in a scene file fail at load with one line naming the
file, the field and what is allowed."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from gaitforge.workers.motions import motion_file
from gaitforge.workers.scenes import load_scene, scene_fields
from gaitforge.workers.spec_io import SpecError


def _write(tmp_path: Path, base: str, edit) -> Path:
    raw = scene_fields(base)
    edit(raw)
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(raw))
    return path


def _fails(path: Path, *fragments: str) -> None:
    with pytest.raises(SpecError) as info:
        load_scene(path)
    message = str(info.value)
    assert "\n" not in message and str(path) in message, message
    for fragment in fragments:
        assert fragment in message, message


def _bad_motion_file(tmp_path: Path) -> Path:
    raw = yaml.safe_load(motion_file("gait2d", "walk").read_text())
    raw["joint_angles"]["elbow_flex"] = raw["joint_angles"].pop("ankle_angle_l")
    path = tmp_path / "elbow-walk.yaml"
    path.write_text(yaml.safe_dump(raw))
    return path


def test_an_unknown_motion_lists_the_available_ones(tmp_path: Path) -> None:
    path = _write(tmp_path, "imitate-walk-2d", lambda r: r["task"]["clock"].update(motion="hop"))
    _fails(path, "task.clock.motion", "'hop'", "run", "walk")


def test_a_motion_with_joints_the_body_lacks(tmp_path: Path) -> None:
    motion = _bad_motion_file(tmp_path)
    path = _write(
        tmp_path, "imitate-walk-2d", lambda r: r["task"]["clock"].update(motion=str(motion))
    )
    _fails(path, "task.clock.motion", "elbow_flex")


def test_a_motion_of_another_body(tmp_path: Path) -> None:
    other = str(motion_file("myoleg", "run"))
    path = _write(tmp_path, "imitate-walk-2d", lambda r: r["task"]["clock"].update(motion=other))
    _fails(path, "task.clock.motion", "'myoleg'", "'gait2d'")


def test_a_scene_that_keeps_none_of_the_motions_joints(tmp_path: Path) -> None:
    path = _write(
        tmp_path, "imitate-walk-2d", lambda r: r["keep"].update(joints=["lumbar_extension"])
    )
    _fails(path, "task.clock.motion", "keeps none", "keep.joints")


def test_a_clock_on_a_reach_task(tmp_path: Path) -> None:
    path = _write(tmp_path, "elbow-reach", lambda r: r["task"].update(clock={"motion": "walk"}))
    _fails(path, "task", "clock", "locomotion", "'reach'")


def test_a_clock_on_a_body_without_a_pelvis(tmp_path: Path) -> None:
    def edit(raw: dict) -> None:
        raw["task"] = {
            "kind": "locomotion",
            "min_pelvis_height": 0.5,
            "clock": {"motion": "walk"},
        }

    _fails(_write(tmp_path, "elbow-reach", edit), "task.clock", "no free pelvis", "myoelbow")


def test_imitation_on_a_backend_the_body_cannot_run_on(tmp_path: Path) -> None:
    def edit(raw: dict) -> None:
        raw["task"]["clock"] = {"motion": "run"}
        raw["backends"] = ["mujoco", "opensim"]

    _fails(_write(tmp_path, "walk-3d", edit), "backends", "MuJoCo only")


@pytest.mark.parametrize(
    ("edit", "fragments"),
    [
        (lambda i: i.update(max_pose_error_rad=0), ["task.imitate.max_pose_error_rad", "0"]),
        (lambda i: i["weights"].update(pose=-1), ["task.imitate.weights.pose"]),
        (lambda i: i["scales"].update(feet=0), ["task.imitate.scales.feet"]),
        (lambda i: i["starts"].update(noise=-0.1), ["task.imitate.starts.noise"]),
        (lambda i: i.update(speed=2), ["task.imitate.speed", "Extra inputs"]),
    ],
)
def test_bad_imitation_fields(tmp_path: Path, edit, fragments: list[str]) -> None:
    path = _write(tmp_path, "imitate-walk-2d", lambda r: edit(r["task"]["imitate"]))
    _fails(path, *fragments)
