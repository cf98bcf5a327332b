"""Recipes without copies: a job file extends another (``extends``), picks its stages by
name, merges fields over it and sets single fields (``set``); the shipped recipes are parts
of the curriculum, field for field."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from gaitforge.learner.job import load_job, read_job_fields
from gaitforge.workers.spec_io import SpecError

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def test_the_recipes_are_stages_of_the_curriculum() -> None:
    curriculum, _, _ = load_job(EXAMPLES / "learn-to-run.yaml")
    for recipe, names in [
        ("learn-to-walk", ["imitate-walk", "walk"]),
        ("learn-to-run-2d", ["imitate-run", "run"]),
        ("obstacles-2d", ["obstacles"]),
        ("obstacles-2d-speeds", ["speeds"]),
    ]:
        job, _, _ = load_job(EXAMPLES / f"{recipe}.yaml")
        by_name = {stage.name: i for i, stage in enumerate(curriculum.stages)}
        assert [stage.name for stage in job.stages] == names
        for i, name in enumerate(names):
            whole = curriculum.stages[by_name[name]]
            assert job.stage_ppo(i) == curriculum.stage_ppo(by_name[name]), (recipe, name)
            assert job.stages[i] == whole, "a picked stage is the stage as written there"
        assert job.network == curriculum.network and job.workers == curriculum.workers


def test_the_3d_walk_is_the_walk_recipe_on_myolegs_scenes_at_less_noise() -> None:
    """learn-to-walk.yaml on MyoLeg's scenes, with a third of its starting noise and no mirror
    images in the walk stage."""
    planar, _, _ = load_job(EXAMPLES / "learn-to-walk.yaml")
    myoleg, scenes, _ = load_job(EXAMPLES / "learn-to-walk-3d.yaml")
    assert [s.name for s in scenes] == ["imitate-walk-3d+standing-starts", "walk-3d+clock"]
    assert all(s.body == "myoleg" and s.action.kind == "joint_targets" for s in scenes)
    assert planar.stage_ppo(1).mirror and not myoleg.stage_ppo(1).mirror
    assert myoleg.stage_ppo(0) == planar.stage_ppo(0)
    walk = myoleg.stages[1].model_copy(update={"ppo": planar.stages[1].ppo})
    for mine, theirs in zip([myoleg.stages[0], walk], planar.stages, strict=True):
        assert mine.model_copy(update={"scene": theirs.scene}) == theirs
    assert myoleg.network.init_std == pytest.approx(planar.network.init_std / 3)
    network = myoleg.network.model_copy(update={"init_std": planar.network.init_std})
    same = {"name": planar.name, "stages": planar.stages, "network": network}
    assert myoleg.model_copy(update=same) == planar


def test_the_curriculum_promotes_each_task_stage_on_its_evaluation_or_ends() -> None:
    """Imitation stages run their budgets; every task stage is judged on 100 deterministic
    episodes, promoted at its target and ends the job if it misses it; the walk, run and
    obstacle targets are those its README names."""
    curriculum, _, _ = load_job(EXAMPLES / "learn-to-run.yaml")
    rules = {
        stage.name: sorted(str(rule) for rule in stage.promote)
        for stage in curriculum.stages
        if stage.if_not_promoted == "fail"
    }
    assert list(rules) == ["walk", "run", "obstacles", "speeds"]
    judged_stages = [s for s in curriculum.stages if s.if_not_promoted == "fail"]
    assert all(s.evaluate and s.evaluate.episodes == 100 for s in judged_stages)
    judged = "on the stage's evaluation"
    assert rules["walk"] == [f"eval.fall_rate <= 0.1 {judged}", f"eval.speed >= 1 {judged}"]
    assert rules["run"] == [f"eval.fall_rate <= 0.1 {judged}", f"eval.speed >= 3 {judged}"]
    assert rules["obstacles"] == [f"eval.fall_rate <= 0.07 {judged}", f"eval.speed >= 2 {judged}"]


def test_set_changes_one_field_of_the_job_it_extends() -> None:
    plain, _, _ = load_job(EXAMPLES / "imitate-walk-2d.yaml")
    targets, scenes, _ = load_job(EXAMPLES / "imitate-walk-2d-targets.yaml")
    assert targets.name == "imitate-walk-2d-targets"
    assert targets.stages[0].scene_set["action"] == {"kind": "joint_targets"}
    assert scenes[0].action.kind == "joint_targets"
    assert targets.stages[0].model_copy(update={"scene_set": {}}) == plain.stages[0]


def write(path: Path, fields: dict) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump(fields))
    return path


def test_an_extended_jobs_paths_stay_its_own(tmp_path: Path) -> None:
    """A scene file named by the job extended is found from that job's folder."""
    scene = {"base": "walk-2d", "options": ["clock"], "set": {"task.target_speed": 1.0}}
    write(tmp_path / "recipes" / "scenes" / "slow.yaml", scene)
    stage = {"name": "slow", "scene": "scenes/slow.yaml", "env_steps": 1000}
    write(tmp_path / "recipes" / "base.yaml", {"name": "base", "stages": [stage]})
    mine = write(tmp_path / "mine" / "job.yaml", {"extends": "../recipes/base.yaml", "name": "m"})
    job, scenes, _ = load_job(mine, {"ppo.lr": 1.0e-4})
    assert scenes[0].task.target_speed == 1.0 and job.ppo.lr == 1.0e-4
    assert read_job_fields(mine)["stages"][0]["scene"] == "../recipes/scenes/slow.yaml"


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"extends": "job.yaml"}, "extends: 'job.yaml' makes a cycle"),
        ({"extends": "other.yaml", "stages": ["run"]}, "stages: ['run'] not in the job it extends"),
        ({"extends": "learn-to-run"}, "extends: a job file's path (.yaml)"),
        ({"extends": "other.yaml", "set": ["ppo.lr"]}, "set: a mapping of dotted field paths"),
        ({"extends": "other.yaml", "set": {"stages.4.env_steps": 1}}, "an index into a list of 1"),
    ],
)
def test_a_wrong_recipe_is_one_line_naming_the_field(
    tmp_path: Path, fields: dict, message: str
) -> None:
    write(tmp_path / "other.yaml", {"name": "o", "stages": [{"scene": "walk-2d", "env_steps": 1}]})
    with pytest.raises(SpecError) as err:
        load_job(write(tmp_path / "job.yaml", {"name": "j", **fields}))
    assert message in str(err.value) and "\n" not in str(err.value)
