"""Values a job file (and the scenes it names) accepts are values a run can use: seeds in
[0, 2**32), numbers strict (no "1000" or true for an int) and finite, names and lists
bounded, and every error short, naming the field and what is allowed."""

from __future__ import annotations

import typing
from pathlib import Path

import pytest
import yaml
from gaitforge.learner.job import Job, Stage, load_job
from gaitforge.workers.scenes import Scene, load_scene
from gaitforge.workers.spec_io import MAX_PROBLEMS, SpecError
from gaitforge.workers.spec_types import SEED_LIMIT
from pydantic import BaseModel

STAGE = {"scene": "stand-2d", "env_steps": 1000}
ERROR_CHARS = 2000
"""an error about one field is a line, whatever was written there"""


def _job_file(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "job.yaml"
    path.write_text(text)
    return path


def _job_error(tmp_path: Path, most: int = ERROR_CHARS, **fields: object) -> str:
    """The error of loading a stand-2d job file with ``fields`` (YAML-dumped): one line of
    fewer than ``most`` characters."""
    job = {"name": "values", "stages": [STAGE], **fields}
    with pytest.raises(SpecError) as caught:
        load_job(_job_file(tmp_path, yaml.safe_dump(job)))
    message = str(caught.value)
    assert "\n" not in message, message[:300]
    assert len(message) < most, message[:300]
    return message


@pytest.mark.parametrize("seed", [-1, SEED_LIMIT, 2**70])
def test_a_seed_outside_0_to_2_pow_32_is_refused_naming_the_field(
    tmp_path: Path, seed: int
) -> None:
    message = _job_error(tmp_path, seed=seed)
    assert ": seed: " in message
    assert ("greater than or equal to 0" in message) == (seed < 0)
    assert ("less than 4294967296" in message) == (seed >= 0)


def test_seeds_at_the_ends_of_the_range_load(tmp_path: Path) -> None:
    for seed in (0, SEED_LIMIT - 1):
        text = f"name: values\nseed: {seed}\nstages: [{{scene: stand-2d, env_steps: 1000}}]\n"
        job, _, _ = load_job(_job_file(tmp_path, text))
        assert job.seed == seed


@pytest.mark.parametrize(
    ("text", "field"),
    [
        ('seed: "7"', "seed"),
        ("seed: true", "seed"),
        ('stages: [{scene: stand-2d, env_steps: "1000"}]', "stages.0.env_steps"),
        ("stages: [{scene: stand-2d, env_steps: true}]", "stages.0.env_steps"),
        ("stages: [{scene: stand-2d, env_steps: 1000.0}]", "stages.0.env_steps"),
        ('workers: {num_workers: "2"}', "workers.num_workers"),
        ('ppo: {lr: "0.001"}', "ppo.lr"),
        ("ppo: {epochs: true}", "ppo.epochs"),
        ('checkpoint: {every_iters: "5"}', "checkpoint.every_iters"),
    ],
)
def test_numbers_are_strict(tmp_path: Path, text: str, field: str) -> None:
    """A string or a bool where a number is expected is refused, never coerced."""
    stages = "" if text.startswith("stages") else "stages: [{scene: stand-2d, env_steps: 1000}]"
    path = _job_file(tmp_path, f"name: values\n{text}\n{stages}\n")
    with pytest.raises(SpecError, match=rf": {field}: Input should be a valid"):
        load_job(path)


def test_yaml_numbers_load_and_a_float_field_takes_an_int(tmp_path: Path) -> None:
    text = """
name: values
seed: 3
ppo: {lr: 1, gamma: 0.98, epochs: 4}
workers: {timeout_s: 30, num_workers: 2}
stages:
  - {scene: stand-2d, env_steps: 1000, scene_set: {control_hz: 50}, promote: "survival >= 1 over 5"}
"""
    job, scenes, _ = load_job(_job_file(tmp_path, text))
    assert job.ppo.lr == 1.0 and isinstance(job.ppo.lr, float)
    assert job.workers.timeout_s == 30.0
    rule = job.stages[0].promote[0]
    assert (rule.value, rule.window) == (1.0, 5)
    assert scenes[0].control_hz == 50.0


@pytest.mark.parametrize(
    ("text", "field"),
    [
        ("workers: {timeout_s: .inf}", "workers.timeout_s"),
        ("ppo: {max_grad_norm: .inf}", "ppo.max_grad_norm"),
        ("ppo: {target_kl: .nan}", "ppo.target_kl"),
        ("workers: {actor_failure_window_s: .inf}", "workers.actor_failure_window_s"),
    ],
)
def test_floats_are_finite(tmp_path: Path, text: str, field: str) -> None:
    path = _job_file(tmp_path, f"name: values\n{text}\nstages: [{{scene: stand-2d, env_steps: 9}}]")
    with pytest.raises(SpecError, match=rf": {field}: Input should be a finite number"):
        load_job(path)


def test_a_rule_of_an_infinite_value_is_refused() -> None:
    with pytest.raises(ValueError, match="finite number"):
        Stage.model_validate({**STAGE, "promote": "return >= 1e999"})


def test_a_scene_file_is_strict_and_finite_too(tmp_path: Path) -> None:
    """A scene YAML: a string or inf where a number goes is refused; its ranges, lists in
    YAML, still load."""
    base = yaml.safe_load(yaml.safe_dump(load_scene("obstacles-2d").model_dump(mode="json")))
    path = tmp_path / "scene.yaml"
    path.write_text(yaml.safe_dump(base))
    assert load_scene(str(path)).obstacles.x_range == tuple(base["obstacles"]["x_range"])
    for change, field in [
        ({"episode_s": "10"}, "episode_s"),
        ({"control_hz": float("inf")}, "control_hz"),
        ({"obstacles": {**base["obstacles"], "count": True}}, "obstacles.count"),
        ({"obstacles": {**base["obstacles"], "x_range": [1, float("nan")]}}, "obstacles.x_range"),
    ]:
        path.write_text(yaml.safe_dump({**base, **change}))
        with pytest.raises(SpecError, match=rf": {field}"):
            load_scene(str(path))


def _spec_models(root: type[BaseModel]) -> set[type[BaseModel]]:
    """``root`` and every model its fields hold, however nested in unions and containers."""
    found: set[type[BaseModel]] = set()
    pending: list[object] = [root]
    while pending:
        kind = pending.pop()
        if isinstance(kind, type) and issubclass(kind, BaseModel):
            if kind not in found:
                found.add(kind)
                pending.extend(f.annotation for f in kind.model_fields.values())
        else:
            pending.extend(typing.get_args(kind))
    return found


@pytest.mark.parametrize("root", [Job, Scene])
def test_every_spec_model_is_strict_and_finite(root: type[BaseModel]) -> None:
    """A model added to a job or a scene later takes the same rules."""
    models = _spec_models(root)
    assert len(models) > 5
    for model in models:
        config = model.model_config
        assert config.get("strict") is True, f"{model.__name__} is not strict"
        assert config.get("allow_inf_nan") is False, f"{model.__name__} allows inf and NaN"


def test_a_long_name_is_refused_in_a_short_error(tmp_path: Path) -> None:
    message = _job_error(tmp_path, name="w" * 900_000)
    assert ": name: String should have at most 128 characters" in message


def test_names_and_references_are_bounded() -> None:
    for stage, field in [
        ({**STAGE, "name": "s" * 129}, "name"),
        ({**STAGE, "name": "../up"}, "name"),
        ({**STAGE, "scene": "x" * 1025}, "scene"),
        ({**STAGE, "promote": ["survival >= 1"] * 17}, "promote"),
    ]:
        with pytest.raises(ValueError, match=rf"(?m)^{field}\b"):
            Stage.model_validate(stage)


def test_too_many_workers_are_refused(tmp_path: Path) -> None:
    message = _job_error(tmp_path, workers={"num_workers": 4096})
    assert ": workers.num_workers: Input should be less than or equal to 1024" in message


def test_many_unknown_fields_give_a_short_error(tmp_path: Path) -> None:
    """Thousands of unknown keys with long values: the first problems are listed, the others
    counted, each value quoted only in part."""
    unknown = {f"key{i}": "v" * 500 for i in range(2000)}
    each = len(str(tmp_path / "job.yaml")) + 200  # the file, the field, the problem
    message = _job_error(tmp_path, most=(MAX_PROBLEMS + 1) * each, **unknown)
    assert message.count("Extra inputs are not permitted") == MAX_PROBLEMS
    assert f"{2000 - MAX_PROBLEMS} more problems not listed" in message
    assert "(502 characters)" in message  # the value's repr, quotes included


def test_an_integer_of_5000_digits_is_an_error_not_a_crash(tmp_path: Path) -> None:
    path = _job_file(tmp_path, "name: values\nseed: " + "9" * 5000 + "\nstages: []\n")
    with pytest.raises(SpecError, match="not valid YAML: Exceeds the limit"):
        load_job(path)
