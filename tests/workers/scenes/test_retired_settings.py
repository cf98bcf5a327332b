"""Retired scene settings (``workers.scenes.migration.RETIRED_SETTINGS``): older scene files and
checkpoints that hold one at its former default load without it; any other value is refused
with one line naming the field."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest
import yaml
from gaitforge.workers.scenes import load_scene
from gaitforge.workers.scenes.migration import RETIRED_SETTINGS
from gaitforge.workers.scenes.spec import Scene
from gaitforge.workers.spec_io import SpecError

POLICIES = Path(__file__).parents[3] / "examples" / "policies"
OLDER = json.loads(
    (Path(__file__).parents[2] / "fixtures" / "older-layout-obstacle-scene.json").read_text()
)
"""An obstacle runner's scene as its checkpoint stored it (the obstacle runner shipped
until the curriculum's replaced it): the older layout (the clock inside ``task.imitate``),
every retired setting it knew at its former default."""


def with_setting(fields: dict, dotted: str, value: object) -> dict:
    """``fields`` with ``dotted`` (a path of mappings, created where missing) set to
    ``value``."""
    *path, name = dotted.split(".")
    parent = fields
    for key in path:
        parent = parent.setdefault(key, {})
    parent[name] = value
    return fields


def without_setting(fields: dict, dotted: str) -> dict:
    """A copy of ``fields`` without ``dotted`` (where it is)."""
    fields = copy.deepcopy(fields)
    *path, name = dotted.split(".")
    parent = fields
    for key in path:
        parent = parent.get(key, {})
    parent.pop(name, None)
    return fields


def test_each_retired_setting_at_its_former_default_is_dropped_on_load() -> None:
    fields = copy.deepcopy(OLDER)
    without = copy.deepcopy(OLDER)
    for dotted, default, _ in RETIRED_SETTINGS:
        fields = with_setting(fields, dotted, default)
        without = without_setting(without, dotted)
    expected = Scene.model_validate(without).model_dump(mode="json")
    migrated = Scene.model_validate(fields)
    assert migrated.model_dump(mode="json") == expected
    assert fields["task"]["imitate"]["clock_rate_span"] is None  # the input left as it was


@pytest.mark.parametrize(
    ("dotted", "value"),
    [
        ("task.imitate.clock_rate_span", 0.5),
        ("task.imitate.weights.pelvis_position", 0.2),
        ("task.imitate.weights.pelvis_lag", 0.3),
        ("task.imitate.scales.pelvis_lag", 1.0),
        ("task.imitate.tempo_speed_exponent", 0.0),
        ("obstacles.observe_behind", 2),
        ("task.reward.obstacle_touch", 1.0),
        ("observe_muscles", False),
        ("observe_heading", True),
        ("observe_heading", 0),  # not the boolean it was
        ("task.imitate.weights.pelvis_heading", 0.1),
        ("mujoco.contact_model", "hunt-crossley"),
        ("mujoco.joint_limits", "opensim"),
        ("task.assist", {"upright_kp": 400.0, "upright_kd": 40.0}),
    ],
)
def test_a_retired_setting_at_another_value_is_refused_naming_it(
    tmp_path: Path, dotted: str, value: object
) -> None:
    path = tmp_path / "older.yaml"
    path.write_text(yaml.safe_dump(with_setting(copy.deepcopy(OLDER), dotted, value)))
    with pytest.raises(SpecError) as info:
        load_scene(path)
    message = str(info.value)
    assert "\n" not in message and str(path) in message
    assert f"{dotted}: retired (" in message and "remove it" in message


@pytest.mark.parametrize("name", ["muscle_curves", "muscle_passive"])
def test_a_removed_value_is_refused_naming_the_commit_that_has_it(name: str) -> None:
    with pytest.raises(ValueError, match=rf"mujoco.{name} 'opensim': MuJoCo on OpenSim's laws"):
        Scene.model_validate({**OLDER, name: "opensim"})  # at the top, in the older layout


def test_the_shipped_policies_stored_scenes_load_without_the_retired_settings() -> None:
    metas = sorted(POLICIES.glob("*/meta.json"))
    assert len(metas) == 6
    retired = {dotted.split(".")[-1] for dotted, _, _ in RETIRED_SETTINGS}
    for meta in metas:
        stored = json.loads(meta.read_text())["scene"]
        dumped = json.dumps(Scene.model_validate(stored).model_dump(mode="json"))
        assert not [name for name in retired if f'"{name}"' in dumped], meta
