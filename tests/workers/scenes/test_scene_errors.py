"""Bad scene files fail at load with one line naming the file, the field and what is allowed."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from gaitforge.workers.scenes import load_scene, scene_fields
from gaitforge.workers.spec_io import SpecError


def _write(tmp_path: Path, edit) -> Path:
    raw = scene_fields("walk-2d")
    edit(raw)
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(raw))
    return path


def _assert_one_line(exc: SpecError, path: Path, *fragments: str) -> None:
    message = str(exc)
    assert "\n" not in message
    assert str(path) in message
    for fragment in fragments:
        assert fragment in message, message


@pytest.mark.parametrize(
    ("edit", "fragments"),
    [
        (
            lambda r: r["keep"].update(muscles=["vasti_r", "biceps_x"]),
            ["keep.muscles.1", "biceps_x"],
        ),
        (lambda r: r["keep"].update(joints=["hip_flexion_r", "elbow"]), ["keep.joints.1", "elbow"]),
        (
            lambda r: r.update(fidelity={"integrator": "rk4", "timestep": -0.001}),
            ["fidelity", "timestep", "greater than 0"],
        ),
        (lambda r: r.update(backends=["bullet"]), ["backends.0", "'mujoco'", "'opensim'"]),
        (lambda r: r.pop("task"), ["task", "Field required"]),
        (lambda r: r.update(control_hz="fast"), ["control_hz", "number"]),
        (
            lambda r: r.update(fidelity={"integrator": "verlet", "timestep": 0.002}),
            ["fidelity.integrator", "verlet", "implicitfast"],
        ),
        (
            lambda r: r.update(fidelity={"integrator": "rk4", "timestep": 0.003}),
            ["timestep", "control period"],
        ),
        (lambda r: r.update(colour="blue"), ["colour", "Extra inputs"]),
    ],
)
def test_bad_scene_file_fails_with_one_line(tmp_path: Path, edit, fragments: list[str]) -> None:
    path = _write(tmp_path, edit)
    with pytest.raises(SpecError) as info:
        load_scene(path)
    _assert_one_line(info.value, path, *fragments)


def test_unknown_scene_name_lists_the_catalogue() -> None:
    with pytest.raises(SpecError, match="walk-2d"):
        load_scene("walk-4d")


def test_not_yaml(tmp_path: Path) -> None:
    path = tmp_path / "x.yaml"
    path.write_text("name: [unclosed")
    with pytest.raises(SpecError, match="not valid YAML"):
        load_scene(path)
