"""``--json`` on every list, show and evaluate command parses as JSON; at 80 columns nothing a
user needs is cut (no "…")."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from gaitforge.service.cli import app
from gaitforge.service.ops.train import TrainRequest, prepare_training
from gaitforge.workers.scenes import catalogue, option_names
from typer.testing import CliRunner

runner = CliRunner()
NARROW = {"COLUMNS": "80"}
POLICIES = Path(__file__).resolve().parents[2] / "examples" / "policies"


def test_scenes_list_json_is_the_catalogue() -> None:
    result = runner.invoke(app, ["scenes", "list", "--json"], env=NARROW)
    assert result.exit_code == 0, result.output
    listing = json.loads(result.stdout)
    scenes, options = listing["scenes"], listing["options"]
    assert [s["name"] for s in scenes] == catalogue()
    assert [o["name"] for o in options] == option_names()
    walk = next(s for s in scenes if s["name"] == "walk-2d")
    assert walk["backends"] == ["mujoco", "opensim"] and walk["target_speed_m_s"] == 1.25
    assert walk["description"] and walk["control_hz"] == 100
    clock = next(o for o in options if o["name"] == "clock")
    assert clock["bases"] == ["obstacles-2d", "run-2d", "walk-2d", "walk-3d"]
    assert clock["description"]


def test_scenes_list_at_80_columns_cuts_nothing() -> None:
    result = runner.invoke(app, ["scenes", "list"], env=NARROW)
    assert result.exit_code == 0, result.output
    assert "…" not in result.output
    assert max(map(len, result.output.splitlines())) <= 80
    for name in catalogue() + option_names():
        assert f"│ {name} " in result.output, name  # whole, in the table
        assert f"{name}: " in result.output, name  # and its description below it


def test_scenes_show_json_is_the_compile_report() -> None:
    result = runner.invoke(app, ["scenes", "show", "walk-3d", "--json"], env=NARROW)
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["scene"] == "walk-3d" and report["backend"] == "mujoco"
    assert report["profile"]["integrator"] and report["profile"]["timestep"] > 0
    assert "subtalar_angle_r" in report["locked_dofs"]
    assert report["saved"]["contact_pairs"] == (
        report["size_full"]["contact_pairs"] - report["size"]["contact_pairs"]
    )


def test_scenes_show_at_80_columns_cuts_nothing() -> None:
    result = runner.invoke(app, ["scenes", "show", "walk-3d"], env=NARROW)
    assert result.exit_code == 0, result.output
    assert "…" not in result.output and "contact_pairs" in result.output
    assert "hip_adduction_r" in result.output and "bofoot_col2_l" in result.output


def test_scenes_check_json() -> None:
    result = runner.invoke(
        app, ["scenes", "check", "elbow-reach", "--seconds", "0.2", "--json"], env=NARROW
    )
    assert result.exit_code == 0, result.output
    [check] = json.loads(result.stdout)
    assert check["scene"] == "elbow-reach" and check["backend"] == "mujoco"
    assert check["steps"] > 0 and check["steps_per_s"] > 0 and check["health"] == {}


def test_scenes_check_at_80_columns_cuts_nothing() -> None:
    result = runner.invoke(
        app, ["scenes", "check", "imitate-walk-3d", "--seconds", "0.2"], env=NARROW
    )
    assert result.exit_code == 0, result.output
    assert "…" not in result.output and "│ imitate-walk-3d │" in result.output
    assert "episodes" in result.output and "steps/s" in result.output


def test_an_error_with_json_is_still_one_line_on_stderr() -> None:
    result = runner.invoke(app, ["scenes", "show", "walk-9d", "--json"], env=NARROW)
    assert result.exit_code == 2 and result.stdout == ""
    assert result.stderr.startswith("error: ") and len(result.stderr.splitlines()) == 1


@pytest.fixture(scope="module")
def walk_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A walk-2d run of one PPO update (in-process), through the train operation."""
    run_dir = tmp_path_factory.mktemp("walk") / "run"
    job = {
        "name": "walk",
        "ppo": {"batch_env_steps": 128, "minibatch_size": 64, "epochs": 1},
        "workers": {"num_workers": 0, "envs_per_worker": 1, "fragment_length": 64},
        "stages": [{"scene": "walk-2d", "env_steps": 100000}],
    }
    training = prepare_training(TrainRequest(job=job, run_dir=run_dir, tensorboard=False))
    result = training.run(max_iterations=1)
    assert result.iterations == 1 and result.checkpoint is not None
    return run_dir


def test_evaluate_json_on_stdout_and_to_a_file(walk_run: Path, tmp_path: Path) -> None:
    out = tmp_path / "eval.json"
    args = [
        "evaluate",
        str(walk_run),
        "--episodes",
        "1",
        "--mode",
        "both",
        "--sweep",
        "--sweep-percent",
        "0,50",
        "--json",
        "--json-out",
        str(out),
    ]
    result = runner.invoke(app, args, env=NARROW)
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert set(data["results"]) == {"deterministic", "stochastic"}
    assert [p["target_speed_m_s"] for p in data["sweep"]] == pytest.approx([1.25, 0.625])
    assert json.loads(out.read_text()) == data


def test_evaluate_at_80_columns_cuts_nothing(walk_run: Path) -> None:
    args = [
        "evaluate",
        str(walk_run),
        "--episodes",
        "2",
        "--mode",
        "both",
        "--sweep",
        "--sweep-percent",
        "0,10,20,30",
        "--per-episode",
    ]
    result = runner.invoke(app, args, env=NARROW)
    assert result.exit_code == 0, result.output
    text = result.output
    assert "…" not in text and max(map(len, text.splitlines())) <= 80
    for needed in (
        "deterministic",
        "stochastic",
        "health failures",
        "fall rate",
        "survival",
        "30 %",
        "Speed against safety",
        "distance",
        "return",
        "effort",
    ):
        assert needed in text, needed


ONE_PROCESS = """
import json, sys
from gaitforge.service.cli import app
for args in json.loads(sys.argv[1]):
    try:
        app(args, prog_name="gaitforge")
    except SystemExit as done:
        if done.code not in (None, 0):
            raise
    sys.stdout.write(SEPARATOR)
    sys.stdout.flush()
"""
SEPARATOR = "\f\n"
"""written to stdout after each command (no command writes a form feed)"""


def piped(*commands: list[str]) -> list[str]:
    """The stdout of each ``gaitforge COMMAND``, run one after another in a real process
    whose stdout is a pipe (as ``| cat``), with no ``COLUMNS`` in its environment: what a
    script reading the output sees. One process for them all: each start-up imports
    torch and Ray (seconds)."""
    env = {k: v for k, v in os.environ.items() if k not in ("COLUMNS", "LINES")}
    script = f"SEPARATOR = {SEPARATOR!r}\n{ONE_PROCESS}"
    result = subprocess.run(
        [sys.executable, "-c", script, json.dumps(commands)],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
        stdin=subprocess.DEVNULL,
    )
    assert result.returncode == 0, result.stderr
    outputs = result.stdout.split(SEPARATOR)
    assert len(outputs) == len(commands) + 1 and outputs[-1] == "", result.stdout
    return outputs[:-1]


def test_off_a_terminal_a_table_row_is_one_line() -> None:
    """No row wraps into a second line (where a word or a number would be split)."""
    listing, report = piped(
        ["scenes", "list"], ["evaluate", str(POLICIES / "walk-2d"), "--episodes", "1"]
    )
    rows = [line for line in listing.splitlines() if line.startswith("│")]
    assert [row.split("│")[1].strip() for row in rows] == catalogue() + option_names()
    rows = [line for line in report.splitlines() if line.startswith("│")]
    assert len(rows) == 1 and rows[0].startswith("│ deterministic ")
