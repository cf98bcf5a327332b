"""The gaitforge CLI, run for real through typer's runner."""

from __future__ import annotations

import json
from pathlib import Path

from gaitforge.service.cli import app
from gaitforge.workers.scenes import load_scene
from typer.testing import CliRunner

runner = CliRunner()


def test_scenes_list_names_the_bases_and_the_options() -> None:
    result = runner.invoke(app, ["scenes", "list"], env={"COLUMNS": "200"})
    assert result.exit_code == 0, result.output
    for name in ("elbow-reach", "walk-2d", "walk-3d", "obstacles-2d", "clock", "one-leg"):
        assert f"│ {name} " in result.output, name


def test_set_overrides_a_scene_field_and_a_wrong_one_is_one_line() -> None:
    args = ["scenes", "show", "run-2d+clock+obstacles", "--json"]
    result = runner.invoke(app, [*args, "--set", "obstacles.count=3"])
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["obstacles"] == 3
    wrong = runner.invoke(app, [*args, "-o", "obstacles.cuont=3"])
    assert wrong.exit_code == 2 and "obstacles.cuont: Extra inputs" in wrong.stderr
    assert len(wrong.stderr.strip().splitlines()) == 1


def test_scenes_show_prints_the_compile_report() -> None:
    result = runner.invoke(app, ["scenes", "show", "walk-2d"], env={"COLUMNS": "200"})
    assert result.exit_code == 0, result.output
    assert "lumbar_extension" in result.output
    assert "contact_pairs" in result.output


def test_scenes_check_reports_speed_and_health() -> None:
    result = runner.invoke(
        app, ["scenes", "check", "elbow-reach", "--seconds", "0.5"], env={"COLUMNS": "200"}
    )
    assert result.exit_code == 0, result.output
    assert "steps/s" in result.output
    assert "elbow-reach" in result.output


def test_unknown_scene_is_one_clear_error() -> None:
    result = runner.invoke(app, ["scenes", "show", "walk-9d"], env={"COLUMNS": "200"})
    assert result.exit_code == 2
    assert "unknown" in result.output and "walk-2d" in result.output


def test_bad_seconds_is_rejected() -> None:
    result = runner.invoke(app, ["scenes", "check", "walk-2d", "--seconds", "-1"])
    assert result.exit_code != 0
    assert "seconds" in result.output


def test_unknown_backend_is_rejected_naming_the_choices() -> None:
    result = runner.invoke(app, ["scenes", "check", "walk-2d", "--backend", "bullet"])
    assert result.exit_code == 2
    assert "bullet" in result.output and "mujoco" in result.output


def test_a_backend_the_scene_does_not_name_is_one_line() -> None:
    result = runner.invoke(app, ["scenes", "show", "walk-3d", "--backend", "opensim"])
    assert result.exit_code == 2
    assert "runs on ['mujoco']" in result.output


def test_scenes_show_on_opensim() -> None:
    result = runner.invoke(
        app, ["scenes", "show", "walk-2d", "--backend", "opensim"], env={"COLUMNS": "200"}
    )
    assert result.exit_code == 0, result.output
    assert "rk-merson" in result.output and "lumbar_extension" in result.output


def test_name_and_all_together_is_an_error() -> None:
    result = runner.invoke(app, ["scenes", "check", "walk-2d", "--all"])
    assert result.exit_code == 2
    assert "not both" in result.output


def test_evaluate_sets_fields_of_the_checkpoints_own_scene() -> None:
    """``--set`` on ``evaluate`` changes the scene the checkpoint is judged on (here the
    shipped walker asked for 1.0 m/s); a wrong field is one line naming ``--set``."""
    walker = str(Path(__file__).resolve().parents[2] / "examples" / "policies" / "walk-2d")
    args = ["evaluate", walker, "--episodes", "1", "--json"]
    result = runner.invoke(app, [*args, "--set", "task.target_speed=1.0"])
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["results"]["deterministic"]["target_speed_m_s"] == 1.0
    wrong = runner.invoke(app, [*args, "-o", "task.target_sped=1.0"])
    assert wrong.exit_code == 2 and wrong.stderr.startswith("error: --set: ")
    assert "task.target_sped: Extra inputs" in wrong.stderr


def test_tune_searches_resumes_and_refuses_a_scene_without_the_controller(
    tmp_path: Path,
) -> None:
    """``gaitforge tune`` runs CMA-ES in-process, writes the tuned scene, and a second call
    with more generations goes on from the saved state; a scene without the reflex
    controller, or a population of one, is one line. The tuned scene of a MuJoCo search
    loads on OpenSim too (a search goes on there from it), and on MuJoCo it is the scene
    searched with the tuned parameters, field for field."""
    args = ["tune", "reflex-walk-3d", "--out", str(tmp_path), "--population", "2"]
    args += ["--episodes", "1", "--set", "episode_s=0.2"]
    first = runner.invoke(app, [*args, "--generations", "1"])
    assert first.exit_code == 0, first.output
    assert "generation 1:" in first.stdout and (tmp_path / "tuned.yaml").exists()
    on_mujoco = load_scene(tmp_path / "tuned.yaml", backend="mujoco").resolved()
    on_opensim = load_scene(tmp_path / "tuned.yaml", backend="opensim")
    assert on_opensim.action.parameters == on_mujoco.action.parameters
    searched = {"episode_s": 0.2, "action.parameters": on_mujoco.action.parameters}
    assert on_mujoco == load_scene("reflex-walk-3d", searched, backend="mujoco").resolved()
    second = runner.invoke(app, [*args, "--generations", "2"])
    assert second.exit_code == 0 and "generation 2:" in second.stdout, second.output
    with (tmp_path / "progress.csv").open() as f:
        assert len(f.read().splitlines()) == 3  # the header and one row a generation
    wrong = runner.invoke(app, ["tune", "walk-2d", "--out", str(tmp_path / "w")])
    assert wrong.exit_code != 0 and "not reflex_gait" in wrong.stderr
    small = runner.invoke(app, [*args, "--population", "1"])
    assert small.exit_code != 0 and "population" in small.stderr
    assert len(small.stderr.strip().splitlines()) == 1
