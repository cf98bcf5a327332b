"""The operations layer as the REST service will call it: typed inputs and results, one-line
typed errors naming the field, nothing printed."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest
from gaitforge.learner.evaluation.evaluate import EvaluationError
from gaitforge.learner.job import Job, load_job
from gaitforge.service.ops import InputError, SpecError, validate_request
from gaitforge.service.ops import evaluate as evaluate_ops
from gaitforge.service.ops import fidelity as fidelity_ops
from gaitforge.service.ops import scenes as scene_ops
from gaitforge.service.ops import train as train_ops

EXAMPLES = Path(__file__).parents[2] / "examples"


def test_scenes_list_show_and_check_return_models(capsys: pytest.CaptureFixture) -> None:
    listed = {s.name: s for s in scene_ops.list_scenes()}
    assert listed["walk-2d"].target_speed_m_s == 1.25 and listed["walk-2d"].body == "gait2d"
    report = scene_ops.show_scene("walk-2d", "mujoco")
    assert report.scene == "walk-2d" and "lumbar_extension" in report.locked_dofs
    assert report.model_dump(mode="json")["profile"]["integrator"] == report.profile.integrator
    [check] = scene_ops.check_scenes("elbow-reach", "mujoco", seconds=0.2)
    assert check.steps > 0 and check.sim_s == pytest.approx(check.steps / 50)
    assert capsys.readouterr() == ("", ""), "operations print nothing"


@pytest.mark.parametrize(
    ("call", "field", "words"),
    [
        (lambda: scene_ops.show_scene("walk-3d", "opensim"), "backend", "runs on ['mujoco']"),
        (lambda: scene_ops.show_scene("walk-2d", "bullet"), "backend", "unknown 'bullet'"),
        (
            lambda: scene_ops.scenes_to_check("walk-2d", "mujoco", all_scenes=True),
            "name",
            "not both",
        ),
        (lambda: scene_ops.scenes_to_check(None, "mujoco"), "name", "neither"),
        (
            lambda: fidelity_ops.sweep(fidelity_ops.SweepRequest(scene="walk-2d", tolerance=0)),
            "tolerance",
            "must be > 0 rad",
        ),
        (
            lambda: fidelity_ops.stress(fidelity_ops.StressRequest(scene="walk-2d", seconds=0)),
            "seconds",
            "must be > 0 s",
        ),
        (lambda: evaluate_ops.parse_percentages("0,100"), "sweep_percent", "[0, 100)"),
        (lambda: evaluate_ops.parse_percentages("0,fast"), "sweep_percent", "percentages"),
        (lambda: validate_request(train_ops.TrainRequest), "request", "not both or neither"),
        (
            lambda: validate_request(train_ops.TrainRequest, job={}, budget_scale=0),
            "budget_scale",
            "greater than 0",
        ),
    ],
)
def test_bad_arguments_are_one_line_input_errors(call, field: str, words: str) -> None:
    with pytest.raises(InputError) as caught:
        call()
    assert caught.value.field == field and words in str(caught.value)
    assert "\n" not in str(caught.value) and str(caught.value).startswith(f"{field}: ")


def test_a_bad_scene_or_job_is_a_spec_error_naming_file_and_field(tmp_path: Path) -> None:
    with pytest.raises(SpecError, match=r"unknown base; bases: \[.*walk-2d"):
        scene_ops.show_scene("walk-9d")
    job = tmp_path / "job.yaml"
    job.write_text("name: x\nstages: [{scene: elbow-reach, env_steps: 0}]\n")
    with pytest.raises(SpecError, match=r"job.yaml: stages.0.env_steps"):
        train_ops.load_request(train_ops.TrainRequest(job_file=job))
    spec = {"name": "x", "stages": [{"scene": "walk-9d", "env_steps": 10}]}
    with pytest.raises(SpecError, match=r"^job: stages.0.scene: scene 'walk-9d': unknown"):
        train_ops.load_request(train_ops.TrainRequest(job=spec))


def test_budget_scaling_scales_every_stage_and_blend_ramp() -> None:
    path = EXAMPLES / "gait2d-curriculum.yaml"
    job = load_job(path).job

    def scaled(scale: float, **fields) -> Job:
        request = train_ops.TrainRequest(job_file=path, budget_scale=scale, **fields)
        return train_ops.load_request(request).job

    smoke = scaled(0.001)
    assert [s.env_steps for s in smoke.stages] == [round(s.env_steps / 1000) for s in job.stages]
    blends = [(s.blend, t.blend) for s, t in zip(job.stages, smoke.stages, strict=True)]
    assert all(b.ramp_env_steps == round(a.ramp_env_steps / 1000) for a, b in blends)
    assert all(s.env_steps >= 1 for s in scaled(1e-6).stages)
    overridden = scaled(1.0, workers=0, address="auto")
    assert overridden.workers.num_workers == 0 and overridden.workers.ray_address == "auto"


def test_a_job_spec_trains_and_reports_where_it_stands(tmp_path: Path) -> None:
    scene = tmp_path / "scenes" / "reach.yaml"
    scene.parent.mkdir()
    scene.write_text(
        (
            Path(scene_ops.__file__).parents[2]
            / "workers"
            / "scenes"
            / "catalogue"
            / "elbow-reach.yaml"
        ).read_text()
    )
    spec = {
        "name": "reach",
        "ppo": {"batch_env_steps": 128, "minibatch_size": 64, "epochs": 1},
        "workers": {"num_workers": 3, "envs_per_worker": 1, "fragment_length": 64},
        "stages": [{"scene": "scenes/reach.yaml", "env_steps": 10**6}],
    }
    request = train_ops.TrainRequest(
        job=spec, base_dir=tmp_path, run_dir=tmp_path / "run", workers=0, tensorboard=False
    )
    training = train_ops.prepare_training(request)
    assert training.job.workers.num_workers == 0 and not training.uses_ray
    assert not training.start_ray(), "in-process training starts no Ray"
    seen: list[dict] = []
    result = training.run(max_iterations=2, on_iteration=seen.append)
    assert result.iterations == result.iteration == 2 and len(seen) == 2
    assert not result.finished and not result.stopped
    assert result.checkpoint == train_ops.newest_checkpoint(tmp_path / "run")
    assert "stage 0 elbow-reach: iteration 2, 256 env steps" in train_ops.status_line(seen[-1])
    training.request_stop()
    again = training.run(max_iterations=5)
    assert again.iterations == 0 and again.stopped and again.checkpoint == result.checkpoint


def test_progress_log_at_most_once_per_period_and_at_stage_ends(
    caplog: pytest.LogCaptureFixture,
) -> None:
    metrics = {
        "stage": 0,
        "stage_name": "walk",
        "iteration": 1,
        "env_steps": 1000,
        "stage_env_steps": 1000,
        "steps_per_s": 500.0,
        "return": 1.5,
        "speed": 0.5,
        "fall_rate": 0.25,
        "verdict": None,
    }
    log = train_ops.ProgressLog(every_s=3600)
    with caplog.at_level(logging.INFO, logger=train_ops.logger.name):
        log(metrics)
        log({**metrics, "iteration": 2})
        log({**metrics, "iteration": 3, "verdict": "promoted"})
    lines = [r.getMessage() for r in caplog.records]
    assert lines == [
        "stage 0 walk: iteration 1, 1,000 env steps (1,000 in stage), 500 steps/s; return 1.5, "
        "speed 0.50 m/s, falls 25 %",
        "stage 0 walk (promoted): iteration 3, 1,000 env steps (1,000 in stage), 500 steps/s; "
        "return 1.5, speed 0.50 m/s, falls 25 %",
    ]


def test_the_status_line_gives_an_evaluation_and_its_confirmation_on_fresh_episodes() -> None:
    evaluated = {
        "stage": 3,
        "stage_name": "run",
        "iteration": 40,
        "env_steps": 8192,
        "stage_env_steps": 4096,
        "steps_per_s": 1000.0,
        "return": 300.0,
        "speed": 2.9,
        "fall_rate": 0.1,
        "verdict": None,
        "eval_return": 350.0,
        "eval_speed": 3.05,
        "eval_fall_rate": 0.08,
        "confirmation_eval_speed": 2.98,
        "confirmation_eval_fall_rate": 0.12,
    }
    assert train_ops.status_line(evaluated).endswith(
        "; evaluated: return 350.0, speed 3.05 m/s, falls 8 %; on fresh episodes: speed "
        "2.98 m/s, falls 12 %"
    )
    turned = {**evaluated, "eval_turned": 0.0}  # a planar body
    assert train_ops.status_line(turned) == train_ops.status_line(evaluated)
    turned["eval_turned"] = 41.6
    assert "falls 8 %, turned 42 deg; on fresh" in train_ops.status_line(turned)


def test_evaluation_errors_are_typed(tmp_path: Path) -> None:
    request = evaluate_ops.EvaluateRequest(checkpoint=tmp_path / "missing")
    with pytest.raises(EvaluationError, match="no such file"):
        evaluate_ops.evaluate(request)
    assert EvaluationError in evaluate_ops.user_errors()
