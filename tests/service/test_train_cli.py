"""``gaitforge train``: a real run through typer's runner, and one-line errors."""

from __future__ import annotations

import json
import logging
import shlex
import shutil
from pathlib import Path

import pytest
import typer
from gaitforge.learner.checkpoint import latest_checkpoint, load_checkpoint
from gaitforge.learner.job import Job
from gaitforge.learner.trainer import Trainer
from gaitforge.service.cli import app
from gaitforge.service.train_commands import TrainDisplay, resume_command
from rich.console import Console
from typer.testing import CliRunner

runner = CliRunner()
JOB = """name: tiny
ppo: {batch_env_steps: 256, minibatch_size: 128, epochs: 1}
stages:
  - scene: elbow-reach
    env_steps: 100000
"""


def _train_args(tmp_path: Path, *limit: str) -> list[str]:
    """``gaitforge train`` of the tiny job in-process into ``tmp_path/run``, with ``limit``."""
    job = tmp_path / "job.yaml"
    job.write_text(JOB)
    return [
        "train",
        str(job),
        "--workers",
        "0",
        "--run-dir",
        str(tmp_path / "run"),
        *limit,
        "--no-tensorboard",
    ]


def _newest_meta(tmp_path: Path):
    return load_checkpoint(latest_checkpoint(tmp_path / "run" / "checkpoints"))[1]


@pytest.fixture(scope="module")
def first_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """A run of 2 iterations (its folder, holding ``job.yaml`` and ``run``; and its output),
    made once for the tests that resume it (each resumes a copy)."""
    folder = tmp_path_factory.mktemp("first-run")
    result = runner.invoke(
        app, _train_args(folder, "--max-iterations", "2"), env={"COLUMNS": "200"}
    )
    assert result.exit_code == 0, result.output
    return folder, result.output


def _resumable(first_run: tuple[Path, str], tmp_path: Path) -> None:
    """A copy of ``first_run``'s run directory at ``tmp_path/run``."""
    shutil.copytree(first_run[0] / "run", tmp_path / "run")


def test_train_runs_a_job_and_resumes_from_its_run_dir(
    first_run: tuple[Path, str], tmp_path: Path
) -> None:
    assert "stage 0 elbow-reach" in first_run[1]
    meta = _newest_meta(first_run[0])
    assert meta.iteration == 2 and meta.stage.index == 0
    _resumable(first_run, tmp_path)
    args = _train_args(tmp_path, "--max-iterations", "2")
    again = runner.invoke(app, args, env={"COLUMNS": "200"})
    assert again.exit_code == 0, again.output
    assert _newest_meta(tmp_path).iteration == 4, "the second run went on from the first's"


def test_a_resume_with_another_job_names_what_changed(
    first_run: tuple[Path, str], tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """The checkpoint records the job it trained: a resume given another seed and override
    says which fields changed, old and new, and goes on with the job given."""
    _resumable(first_run, tmp_path)
    args = _train_args(tmp_path, "--max-iterations", "1")
    caplog.set_level(logging.WARNING, logger="gaitforge.learner.run_state")
    changed = [*args[:-1], "--seed", "7", "--set", "ppo.epochs=2", "--no-tensorboard"]
    again = runner.invoke(app, changed, env={"COLUMNS": "200"})
    assert again.exit_code == 0, again.output
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1 and "differs from the one it trained" in warnings[0]
    assert "ppo.epochs: 1 -> 2" in warnings[0] and "seed: 0 -> 7" in warnings[0]
    meta = _newest_meta(tmp_path)
    assert meta.iteration == 3 and meta.job["seed"] == 7, "the run went on with the job given"


def test_a_resume_with_the_same_job_warns_of_nothing(
    first_run: tuple[Path, str], tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    _resumable(first_run, tmp_path)
    args = _train_args(tmp_path, "--max-iterations", "1")
    caplog.set_level(logging.WARNING, logger="gaitforge.learner.run_state")
    assert runner.invoke(app, args, env={"COLUMNS": "200"}).exit_code == 0
    assert not [r for r in caplog.records if "differs" in r.getMessage()]
    assert _newest_meta(tmp_path).iteration == 3, "it resumed"


def test_max_minutes_stops_training_with_a_checkpoint(tmp_path: Path) -> None:
    """The wall-clock limit is checked between updates: a limit shorter than one update ends
    the run after its first, checkpointed, long before the stage's budget."""
    result = runner.invoke(
        app, _train_args(tmp_path, "--max-minutes", "0.001"), env={"COLUMNS": "200"}
    )
    assert result.exit_code == 0, result.output
    meta = _newest_meta(tmp_path)
    assert meta.iteration == 1 and meta.env_steps < 100_000


@pytest.mark.parametrize(
    ("job", "message"),
    [
        (JOB.replace("epochs: 1", "epochs: 0"), "ppo.epochs: Input should be greater than"),
        (
            JOB.replace("epochs: 1}", "epochs: 1, mirror: true}"),
            "ppo.mirror: stages.0 (elbow-reach): mirror: the body has no left and right muscles",
        ),
    ],
)
def test_a_bad_job_is_one_line(tmp_path: Path, job: str, message: str) -> None:
    path = tmp_path / "job.yaml"
    path.write_text(job)
    result = runner.invoke(
        app, ["train", str(path), "--run-dir", str(tmp_path / "run")], env={"COLUMNS": "300"}
    )
    assert result.exit_code == 2
    assert message in result.output and len(result.output.strip().splitlines()) == 1


def test_seed_and_set_override_the_job_file(tmp_path: Path) -> None:
    """``--seed`` and ``--set`` (dotted paths, values as YAML) change the job that runs, as
    its checkpoint records it; the stage's ``scene_set`` reaches the scene it trains on."""
    overrides = ["--set", "ppo.epochs=2", "-o", "stages.0.scene_set={episode_s: 1.5}"]
    args = _train_args(tmp_path, "--max-iterations", "1", "--seed", "7", *overrides, "--json")
    result = runner.invoke(app, args, env={"COLUMNS": "200"})
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)  # --json: the run's summary, and nothing else
    assert summary["iteration"] == 1 and summary["checkpoint"] and not summary["finished"]
    meta = _newest_meta(tmp_path)
    assert meta.job["seed"] == 7 and meta.job["ppo"]["epochs"] == 2
    assert meta.scene["episode_s"] == 1.5


def test_the_resume_hint_repeats_the_options_that_change_the_job(tmp_path: Path) -> None:
    """The command printed at a stop, parsed by ``gaitforge train``'s own parser, gives the
    job, run directory, seed, budget scale and overrides it stopped with."""
    job, run_dir = tmp_path / "my jobs" / "job.yaml", tmp_path / "run"
    overrides = ["ppo.epochs=2", "stages.0.scene_set={episode_s: 1.5}"]
    hint = resume_command(job, run_dir, 7, 0.5, overrides)
    words = shlex.split(hint)
    assert words[:2] == ["gaitforge", "train"]
    group = typer.main.get_command(app)
    train = group.get_command(group.make_context("gaitforge", ["train", "--help"]), "train")
    params = train.make_context("train", words[2:]).params
    assert (params["job_file"], params["run_dir"]) == (job, run_dir)
    assert (params["seed"], params["budget_scale"], params["set_fields"]) == (7, 0.5, overrides)
    plain = shlex.split(resume_command(job, run_dir, None, 1.0, None))
    assert plain == ["gaitforge", "train", str(job), "--run-dir", str(run_dir)]


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--set", "ppo.epochs"], "--set"),
        (["--set", "ppo.epoch=2"], "ppo.epoch: Extra inputs are not permitted"),
        (["--set", "stages.3.env_steps=1"], "stages.3: an index into a list of 1"),
        (["--seed", "-1"], "--seed"),
    ],
)
def test_a_bad_override_is_one_line_naming_it(
    tmp_path: Path, extra: list[str], message: str
) -> None:
    result = runner.invoke(app, _train_args(tmp_path, *extra), env={"COLUMNS": "300"})
    assert result.exit_code == 2, result.output
    assert message in result.output and "Traceback" not in result.output


def test_a_mirrored_run_reports_the_kl_of_its_images_apart(tmp_path: Path) -> None:
    """With ``ppo.mirror`` an iteration's metrics (TensorBoard's ``train/*``) carry the KL of
    the sampled actions and of their mirror images apart, and the live table shows both."""
    job = Job.model_validate(
        {
            "name": "mirrored",
            "ppo": {"batch_env_steps": 256, "minibatch_size": 128, "epochs": 1, "mirror": True},
            "workers": {"num_workers": 0},
            "stages": [{"scene": "stand-2d", "env_steps": 10_000}],
        }
    )
    trainer = Trainer(job, tmp_path, tensorboard=False)
    trainer.run(max_iterations=1)
    metrics = trainer.history[-1]
    assert metrics["approx_kl_sampled"] >= 0 and metrics["approx_kl_mirrored"] >= 0
    display = TrainDisplay(job, [0])
    display.update(metrics)
    console = Console(record=True, width=200)
    console.print(display)
    shown = console.export_text()
    assert f"mirrored {metrics['approx_kl_mirrored']:.4g}" in shown, shown
