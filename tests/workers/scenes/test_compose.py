"""Scenes composed from a base and options: the former catalogue's scenes rebuilt field for
field, the order and base rules of options, dotted overrides and their errors."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml
from gaitforge.learner.checkpoint_meta import read_meta
from gaitforge.workers.scenes import Scene, load_scene, option_names, parse_assignments
from gaitforge.workers.scenes.compose import base_names, load_option
from gaitforge.workers.scenes.migration import FORMER_NAMES, REMOVED_NAMES
from gaitforge.workers.spec_io import SpecError

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures"
FORMER = json.loads((FIXTURES / "former-catalogue-scenes.json").read_text())
"""every scene of the catalogue before it was composed, and the scene files of MuJoCo made
like OpenSim, as loaded then (names aside; in the older layout, backend options at the top)"""
SCENE_FILES = {
    "walk-2d-clock-floor-shell-fibre": "walk-2d+clock+opensim-like",
    "walk-2d-clock-recommended": "walk-2d+clock+opensim-recommended",
}
"""scene files that options now make"""
SHIPPED_WALKER = FIXTURES.parents[1] / "examples" / "policies" / "walk-2d"


def fields(scene_dump: dict) -> dict:
    return {k: v for k, v in scene_dump.items() if k not in ("name", "description")}


@pytest.mark.parametrize("former", sorted(set(FORMER) - set(REMOVED_NAMES)))
def test_each_former_scene_is_a_base_with_options(former: str) -> None:
    ref = SCENE_FILES.get(former) or FORMER_NAMES.get(former, former)
    assert ref.split("+")[0] in base_names()
    composed = load_scene(ref).model_dump(mode="json")
    former_fields = Scene.model_validate(FORMER[former]).model_dump(mode="json")  # as migrated
    assert fields(composed) == fields(former_fields)
    if former not in SCENE_FILES:  # a former catalogue name still loads, as its composition
        assert load_scene(former).name == ref


@pytest.mark.parametrize(
    ("ref", "what"),
    [
        ("walk-2d-clock-opensim-laws-half-ms", "MuJoCo on OpenSim's laws"),
        ("walk-2d+clock+opensim-laws", "MuJoCo on OpenSim's laws"),
        ("walk-3d-planar", "the planar option (keep.planar)"),
        ("walk-3d+planar", "the planar option (keep.planar)"),
    ],
)
def test_a_removed_scene_or_option_is_refused_naming_the_commit_that_has_it(
    ref: str, what: str
) -> None:
    with pytest.raises(SpecError, match=r"^scene ") as err:
        load_scene(ref)
    assert f"{what} was removed; commit a1888fe has its code" in str(err.value)


@pytest.mark.parametrize(
    ("former", "field"),
    [
        ("walk-2d-clock-opensim-laws-half-ms", "mujoco.contact_model"),
        ("walk-3d-planar", "keep.planar"),
    ],
)
def test_a_former_scene_of_a_removed_knob_is_refused_naming_it(former: str, field: str) -> None:
    with pytest.raises(ValueError, match=rf"{field}: retired \(.* commit a1888fe has its code"):
        Scene.model_validate(FORMER[former])  # as it was stored


def test_the_shipped_walkers_own_scene_is_walk_with_the_clock() -> None:
    stored = read_meta(SHIPPED_WALKER).scene_spec().model_dump(mode="json")
    composed = load_scene("walk-2d+clock").resolved().model_dump(mode="json")
    assert fields(composed) == fields(stored)


def test_every_option_describes_itself_and_composes_onto_a_base() -> None:
    for name in option_names():
        option = load_option(name)
        assert len(option.description.split()) >= 10, name
    assert set(option_names()) >= {"clock", "one-leg", "obstacles", "speed-range"}


def test_a_composed_scene_describes_its_parts() -> None:
    scene = load_scene("run-2d+clock+one-leg")
    assert scene.name == "run-2d+clock+one-leg"
    assert "run forward at 3 m/s" in scene.description
    assert "gait clock" in scene.description and "same leg" in scene.description


@pytest.mark.parametrize(
    ("ref", "message"),
    [
        ("run-2d+one-leg", "option 'one-leg' needs ['clock'] before it"),
        ("run-2d+clock+clock", "option 'clock' given twice"),
        ("stand-2d+clock", "option 'clock': not for base 'stand-2d'"),
        ("run-2d+wings", "scene option 'wings': unknown; options: ["),
        ("walk-5d", "scene 'walk-5d': unknown base; bases: ["),
        ("Walk 2d", "expected a catalogue name, base+option+..., or a .yaml path"),
    ],
)
def test_a_wrong_composition_says_what_is_allowed(ref: str, message: str) -> None:
    with pytest.raises(SpecError, match=r"^scene") as err:
        load_scene(ref)
    assert message in str(err.value)


def test_overrides_set_fields_by_dotted_path_and_merge_groups() -> None:
    overrides = parse_assignments(
        ["task.target_speed=2.5", "task.reward={forward: 4}", "obstacles.count=3"]
    )
    assert overrides == {
        "task.target_speed": 2.5,
        "task.reward": {"forward": 4},
        "obstacles.count": 3,
    }
    scene = load_scene("obstacles-2d+clock", overrides)
    assert scene.task.target_speed == 2.5 and scene.obstacles.count == 3
    assert scene.task.reward.forward == 4 and scene.task.reward.alive == 0.2  # merged


@pytest.mark.parametrize(
    ("assignment", "message"),
    [
        ("task.target_sped=2", "task.target_sped: Extra inputs are not permitted"),
        ("task.target_speed=fast", "task.target_speed: Input should be a valid number"),
        ("task.target_speed.x=1", "task.target_speed is a value, not a group of fields"),
    ],
)
def test_a_wrong_override_names_the_field(assignment: str, message: str) -> None:
    with pytest.raises(SpecError) as err:
        load_scene("walk-2d", parse_assignments([assignment]))
    assert message in str(err.value)


@pytest.mark.parametrize("text", ["task.target_speed", "=2", "a=[1"])
def test_a_malformed_assignment_is_refused(text: str) -> None:
    with pytest.raises(SpecError, match="--set"):
        parse_assignments([text])


def test_a_scene_file_may_compose_from_the_catalogue(tmp_path: Path) -> None:
    path = tmp_path / "slow-runner.yaml"
    spec = {
        "name": "slow-runner",
        "description": "run-2d's clock at 2.5 m/s",
        "base": "run-2d",
        "options": ["clock"],
        "set": {"task.target_speed": 2.5},
    }
    path.write_text(yaml.safe_dump(spec))
    scene = load_scene(path)
    assert scene.name == "slow-runner" and scene.task.target_speed == 2.5
    assert scene.task.clock is not None and scene.control_hz == 25
    path.write_text(yaml.safe_dump({**spec, "control_hz": 50}))
    with pytest.raises(SpecError, match="a composed scene file has base, options, set"):
        load_scene(path)
