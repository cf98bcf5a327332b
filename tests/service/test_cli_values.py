"""Bad values on the command line and in the job files it reads are one clear error, never a
traceback: seeds outside [0, 2**32), more workers than allowed or than the machine's Ray has
CPUs, rollout actors that keep dying (real runs through typer's runner)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from gaitforge.learner.job import MAX_NUM_WORKERS
from gaitforge.service.cli import app
from gaitforge.workers.sim.faults import FaultInjection
from gaitforge.workers.spec_types import SEED_LIMIT
from typer.testing import CliRunner

runner = CliRunner()
EXAMPLES = Path(__file__).parents[2] / "examples"
JOB = """name: tiny
seed: {seed}
workers: {{num_workers: {workers}}}
ppo: {{batch_env_steps: 256, minibatch_size: 128, epochs: 1}}
stages:
  - scene: elbow-reach
    env_steps: 100000
"""


def _invoke(*args: str):
    return runner.invoke(app, list(args), env={"COLUMNS": "200"})


@pytest.mark.parametrize(
    ("command", "seed", "problem"),
    [
        (["evaluate", str(EXAMPLES / "policies" / "walk-2d")], -1, "greater than or equal to 0"),
        (["evaluate", str(EXAMPLES / "policies" / "walk-2d")], SEED_LIMIT, "less than or equal"),
        (["scenes", "check", "elbow-reach"], -1, "greater than or equal to 0"),
        (["scenes", "check", "elbow-reach"], 2**70, "less than or equal to 4294967295"),
    ],
)
def test_a_seed_outside_the_range_is_a_usage_error(
    command: list[str], seed: int, problem: str
) -> None:
    result = _invoke(*command, "--seed", str(seed))
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    assert "Invalid value for '--seed'" in result.output and problem in result.output


def test_too_many_workers_on_the_command_line_is_a_usage_error(tmp_path: Path) -> None:
    job = tmp_path / "job.yaml"
    job.write_text(JOB.format(seed=0, workers=0))
    result = _invoke("train", str(job), "--workers", str(MAX_NUM_WORKERS + 1))
    assert result.exit_code == 2, result.output
    assert "Invalid value for '--workers'" in result.output
    assert f"less than or equal to {MAX_NUM_WORKERS}" in result.output


@pytest.mark.parametrize(
    ("seed", "problem"),
    [
        ("-1", "seed: Input should be greater than or equal to 0 (got -1)"),
        (
            "1180591620717411303424",
            "seed: Input should be less than 4294967296 (got 1180591620717411303424)",
        ),
        ('"7"', "seed: Input should be a valid integer (got '7')"),
    ],
)
def test_a_bad_seed_in_a_job_file_is_one_line(tmp_path: Path, seed: str, problem: str) -> None:
    job = tmp_path / "job.yaml"
    job.write_text(JOB.format(seed=seed, workers=0))
    result = _invoke("train", str(job), "--run-dir", str(tmp_path / "run"))
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    assert result.output.strip() == f"error: {job}: {problem}"


@pytest.mark.skipif(
    (os.cpu_count() or 1) >= MAX_NUM_WORKERS, reason="this machine has as many CPUs as allowed"
)
def test_more_workers_than_the_local_ray_has_cpus_is_one_line(tmp_path: Path) -> None:
    """``gaitforge train`` starts a Ray of its own with this machine's CPUs: a job asking for
    more actors is refused once Ray is up, before any actor waits for a CPU forever."""
    workers = (os.cpu_count() or 1) + 1
    job = tmp_path / "job.yaml"
    job.write_text(JOB.format(seed=0, workers=workers))
    result = _invoke("train", str(job), "--run-dir", str(tmp_path / "run"), "--no-tensorboard")
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    lines = [line for line in result.output.splitlines() if line.startswith("error: ")]
    assert len(lines) == 1, result.output
    assert lines[0].startswith(
        f"error: workers.num_workers: {workers} rollout actors need {workers} CPUs (one each); "
        "this machine's Ray has "
    )


def test_actors_that_keep_dying_end_a_training_run_with_their_error(tmp_path: Path) -> None:
    """Every actor's simulator aborts its process (SIGABRT) on its first step: after
    ``workers.max_actor_failures`` the run ends, exit status 1, with the actors' error.
    One failure allowed (the least): the second ends the run, so that the error names a
    first and a last actor with two actor start-ups (each takes seconds) rather than more."""
    job = tmp_path / "job.yaml"
    job.write_text(JOB.format(seed=0, workers="1, max_actor_failures: 1"))
    args = ["train", str(job), "--run-dir", str(tmp_path / "run"), "--no-tensorboard"]
    aborting = FaultInjection(abort_prob=1.0).as_environment()
    result = runner.invoke(app, args, env={"COLUMNS": "200", **aborting})
    assert result.exit_code == 1, result.output
    assert "Traceback" not in result.output
    lines = [line for line in result.output.splitlines() if line.startswith("error: ")]
    assert len(lines) == 1, result.output
    assert lines[0].startswith(
        "error: rollout actors failed 2 times in 300 s (more than workers.max_actor_failures "
        "1); first: actor 0 died: "
    )
    assert "; last: actor 1 died: " in lines[0], lines[0]


@pytest.mark.parametrize(
    "command",
    [
        ["scenes", "check", "elbow-reach", "--seconds", "inf"],
        ["fidelity", "stress", "elbow-reach", "--seconds", "inf"],
    ],
)
def test_an_endless_duration_is_a_usage_error(command: list[str]) -> None:
    """Infinite seconds would run the check for ever."""
    result = _invoke(*command)
    assert result.exit_code == 2, result.output
    assert "Invalid value for '--seconds'" in result.output
    assert "less than or equal to" in result.output
