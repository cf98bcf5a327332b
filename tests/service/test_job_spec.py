"""Submitted jobs are data only and validated as job files are: paths, ray_address, unknown
fields and scenes that do not load are refused naming the field; catalogue names and inline
scenes are accepted, written into the job's folder and load as the trainer loads them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml
from gaitforge.learner.job import load_job
from gaitforge.service.jobs.layout import JobLayout
from gaitforge.service.jobs.spec import SubmissionError, prepare_submission, write_job_files
from gaitforge.workers.scenes import scene_fields
from gaitforge.workers.spec_io import SpecError

EXAMPLE = Path(__file__).parents[2] / "examples" / "stand-2d.yaml"


def _stage(scene: object, **stage: object) -> dict:
    """A one-stage job on ``scene`` with more ``stage`` fields."""
    return {"name": "x", "stages": [{"scene": scene, "env_steps": 1000, **stage}]}


def _scene(name: str = "my-stand", base: str = "stand-2d", **changes: object) -> dict:
    scene = scene_fields(base)
    return {**scene, "name": name, **changes}


def _refused(spec: object) -> SubmissionError:
    with pytest.raises(SubmissionError) as info:
        prepare_submission(spec)
    assert "\n" not in str(info.value)
    assert isinstance(info.value, SpecError)
    return info.value


@pytest.mark.parametrize(
    "scene",
    ["stand-2d.yaml", "scenes/stand-2d", "../../etc/passwd", "/abs/scene", "C:\\x\\s.yml", "a.YML"],
)
def test_a_scene_path_is_refused(scene: str) -> None:
    error = _refused(_stage(scene))
    assert error.field == "stages.0.scene" and "file paths are not accepted" in str(error)


def test_ray_address_and_unknown_fields_are_refused_each_named() -> None:
    spec = {**_stage("stand-2d"), "workers": {"ray_address": "auto"}, "entrypoint": "rm -rf /"}
    error = _refused(spec)
    fields = [field for field, _ in error.errors]
    assert fields == ["workers.ray_address", "entrypoint"], error.errors
    assert str(error).startswith("job: workers.ray_address: not accepted")


@pytest.mark.parametrize(
    "changes,field",
    [
        ({"task": {"kind": "locomotion", "bogus": 1}}, "stages.0.scene.task.bogus"),
        ({"control_hz": -5}, "stages.0.scene.control_hz"),
        ({"body": "../../bodies/evil.yaml"}, "stages.0.scene.body"),
        ({"body": "nobody"}, "stages.0.scene.body"),
        ({"keep": {"joints": ["no_such_joint"]}}, "stages.0.scene.keep.joints.0"),
        ({"name": "Bad Name"}, "stages.0.scene.name"),
        ({"fault": {"hang_prob": 1.0}}, "stages.0.scene"),  # a test hook, not a field
    ],
)
def test_a_bad_inline_scene_is_refused_naming_its_field(changes: dict, field: str) -> None:
    error = _refused(_stage(_scene(**changes)))
    assert error.field == field, error.errors


def test_an_inline_motion_path_is_refused() -> None:
    scene = _scene("my-imitation", base="imitate-walk-2d")
    scene["task"]["clock"]["motion"] = "/data/walk.yaml"
    assert _refused(_stage(scene)).field == "stages.0.scene.task.clock.motion"
    scene = _scene("my-run", base="run-2d+clock")
    scene["task"]["clock"]["lead_in"]["motion"] = "/data/walk.yaml"
    assert _refused(_stage(scene)).field == "stages.0.scene.task.clock.lead_in.motion"


def test_an_evaluation_scene_is_a_catalogue_name_that_fits_the_stage() -> None:
    path = {"evaluate": {"scene": "../run-2d+clock.yaml"}}
    assert _refused(_stage("stand-2d", **path)).field == "stages.0.evaluate.scene"
    other_body = _refused(_stage("stand-2d", evaluate={"scene": "elbow-reach"}))
    assert other_body.field == "stages.0.evaluate.scene" and "other names" in str(other_body)


def test_scenes_are_checked_fully_at_submission() -> None:
    assert _refused(_stage("no-such-scene")).field == "stages.0.scene"
    two_bodies = _stage("stand-2d")
    two_bodies["stages"].append({"scene": "elbow-reach", "env_steps": 10})
    assert _refused(two_bodies).field == "stages.1"
    mirror = {**_stage("elbow-reach"), "ppo": {"mirror": True}}
    assert _refused(mirror).field == "ppo.mirror"
    twins = _stage(_scene("twin"))
    twins["stages"].append({"scene": _scene("twin", episode_s=3), "env_steps": 10})
    assert _refused(twins).field == "stages.1.scene.name"


@pytest.mark.parametrize(
    "text,problem",
    [
        ("- a list", "expected a mapping"),
        ("name: [unclosed", "not valid YAML"),
        ("a: &x [1, 2]\nb: *x\n", "aliases"),
        ("x" * 1_000_001, "at most 1000000"),
    ],
)
def test_text_that_is_not_a_job_mapping_is_refused(text: str, problem: str) -> None:
    error = _refused(text)
    assert error.field == "<root>" and problem in str(error)


def test_yaml_and_json_text_give_the_same_normalised_job() -> None:
    from_yaml = prepare_submission(EXAMPLE.read_text())
    from_json = prepare_submission(json.dumps(yaml.safe_load(EXAMPLE.read_text()), indent="\t"))
    assert from_yaml == from_json
    assert from_yaml["stages"][0]["scene"] == "stand-2d"
    assert from_yaml["stages"][0]["promote"][0]["metric"] == "survival"
    assert prepare_submission(from_yaml) == from_yaml  # normalised: a fixed point
    json.dumps(from_yaml, allow_nan=False)


def test_an_inline_scene_is_kept_written_and_loads(tmp_path: Path) -> None:
    spec = _stage(_scene("my-stand", episode_s=2.5))
    spec["stages"].append({"scene": "stand-2d", "env_steps": 500})
    normalised = prepare_submission(spec)
    assert normalised["stages"][0]["scene"]["name"] == "my-stand"
    assert prepare_submission(normalised) == normalised
    layout = JobLayout(tmp_path, "j-0123456789ab")
    job_file = write_job_files(layout, normalised)
    assert job_file == layout.job_file
    assert (layout.scenes_dir / "my-stand.yaml").is_file()
    assert yaml.safe_load(job_file.read_text())["stages"][0]["scene"] == "scenes/my-stand.yaml"
    job, scenes, _ = load_job(job_file)
    assert [s.name for s in scenes] == ["my-stand", "stand-2d"]
    assert scenes[0].episode_s == 2.5 and job.name == "x"


def test_a_stage_scene_set_is_checked_on_the_stage_backend_alone() -> None:
    """As a job file's stage is: a fidelity MuJoCo alone integrates (implicitfast) set on a
    scene that runs on both simulators passes for a MuJoCo stage and is refused for an
    OpenSim one."""
    fidelity = {"integrator": "implicitfast", "timestep": 0.01}
    mujoco = _stage("stand-2d", scene_set={"control_hz": 25, "fidelity": fidelity})
    assert prepare_submission(mujoco)["stages"][0]["scene_set"]["fidelity"] == fidelity
    opensim = {**mujoco, "backend": "opensim"}
    assert _refused(opensim).field.startswith("stages.0.scene_set")
