"""Neutral body files: the shipped ones load; broken ones fail naming file and field."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from gaitforge.workers.bodies import available_bodies, load_body
from gaitforge.workers.spec_io import SpecError

GAIT2D = Path(__file__).parents[3] / "workers" / "bodies" / "data" / "gait2d.yaml"


def test_gait2d_is_the_2017_model() -> None:
    body = load_body("gait2d")
    assert "gait2d" in available_bodies()
    assert len(body.muscles) == 18
    moving = [d for d in body.dof_names if d != "lumbar_extension"]
    assert moving == [
        "pelvis_tx",
        "pelvis_ty",
        "pelvis_tilt",
        "hip_flexion_r",
        "knee_angle_r",
        "ankle_angle_r",
        "hip_flexion_l",
        "knee_angle_l",
        "ankle_angle_l",
    ]
    per_leg = {m.name.rsplit("_", 1)[0] for m in body.muscles}
    assert per_leg == {
        "hamstrings",
        "bifemsh",
        "glut_max",
        "iliopsoas",
        "rect_fem",
        "vasti",
        "gastroc",
        "soleus",
        "tib_ant",
    }
    assert body.total_mass == pytest.approx(79.66, abs=0.05)
    assert sorted(c.name for c in body.contact_spheres if c.part == "foot") == [
        "l_heel",
        "l_toe",
        "r_heel",
        "r_toe",
    ]


def test_spans_follow_the_tree() -> None:
    body = load_body("gait2d")
    spans = {m.name: body.dofs_spanned(m) for m in body.muscles}
    assert spans["vasti_r"] == ["knee_angle_r"]
    assert spans["gastroc_l"] == ["knee_angle_l", "ankle_angle_l"]
    assert spans["hamstrings_r"] == ["hip_flexion_r", "knee_angle_r"]
    assert spans["soleus_r"] == ["ankle_angle_r"]


def _broken(tmp_path: Path, edit) -> Path:
    raw = yaml.safe_load(GAIT2D.read_text())
    edit(raw)
    path = tmp_path / "body.yaml"
    path.write_text(yaml.safe_dump(raw))
    return path


@pytest.mark.parametrize(
    ("edit", "fragments"),
    [
        (lambda r: r["segments"][0].update(mass=-1), ["segments.0.mass", "greater than 0"]),
        (lambda r: r["muscles"][0]["path"][0].update(segment="humerus"), ["humerus"]),
        (
            lambda r: r["muscles"][0].pop("max_isometric_force"),
            ["muscles.0.max_isometric_force", "Field required"],
        ),
        (lambda r: r["joints"][1]["dofs"][0].update(type="ball"), ["dofs.0.type", "'hinge'"]),
        (lambda r: r["joints"][1]["dofs"][0].update(range=[1, -1]), ["range must be increasing"]),
        (lambda r: r["muscles"].append(r["muscles"][0]), ["duplicate name"]),
    ],
)
def test_broken_body_file_fails_naming_file_and_field(tmp_path: Path, edit, fragments) -> None:
    path = _broken(tmp_path, edit)
    load_body.cache_clear()
    with pytest.raises(SpecError) as info:
        load_body(str(path))
    message = str(info.value)
    assert "\n" not in message and str(path) in message
    for fragment in fragments:
        assert fragment in message, message


def test_unknown_body_name_lists_the_shipped_ones() -> None:
    with pytest.raises(SpecError, match="gait2d"):
        load_body("gait3d")
