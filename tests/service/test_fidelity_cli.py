"""``gaitforge fidelity``: a quick sweep end to end, its saved profile used by a scene, and
one-line errors for bad arguments."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml
from gaitforge.service.cli import app
from gaitforge.workers.fidelity.sweep import remeasure
from gaitforge.workers.scenes import load_scene, scene_fields
from gaitforge.workers.scenes.saved_profiles import ENV_DIR
from gaitforge.workers.spec_io import SpecError
from typer.testing import CliRunner

runner = CliRunner()
ENV = {"COLUMNS": "200"}


def _one_line_error(output: str) -> str:
    lines = [line for line in output.strip().splitlines() if line.strip()]
    assert len(lines) == 1, output
    assert lines[0].startswith("error:"), output
    return lines[0]


def test_quick_sweep_recommends_a_profile_within_tolerance_when_measured_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(ENV_DIR, str(tmp_path / "profiles"))
    out = tmp_path / "out"
    tolerance = 0.01
    result = runner.invoke(
        app,
        [
            "fidelity",
            "sweep",
            "walk-2d",
            "--quick",
            "--tolerance",
            str(tolerance),
            "--out",
            str(out),
        ],
        env={**ENV, ENV_DIR: str(tmp_path / "profiles")},
    )
    assert result.exit_code == 0, result.output
    assert "converged" in result.output and "NOT converged" not in result.output
    table = json.loads((out / "walk-2d-mujoco.json").read_text())
    assert (out / "walk-2d-mujoco.csv").read_text().count("\n") == len(table["rows"]) + 1
    assert (out / "walk-2d-mujoco.png").read_bytes()[:4] == b"\x89PNG"
    assert table["reference"]["margin"] >= 10
    rec = table["recommended"]
    assert rec is not None and rec["within"] and rec["error"] <= tolerance
    assert rec["error"] == max(rec["err_short"], rec["err_long"])
    faster = [r for r in table["rows"] if r["steps_per_s"] > rec["steps_per_s"]]
    assert all(not r["within"] for r in faster)  # nothing faster was within tolerance

    # a scene asks for it with fidelity: auto, or by name
    raw = scene_fields("walk-2d")
    raw.update(backends=["mujoco"], fidelity="auto", fidelity_tolerance=tolerance)
    path = tmp_path / "auto.yaml"
    path.write_text(yaml.safe_dump(raw))
    scene = load_scene(path)
    profile = scene.profile("mujoco")
    assert profile.integrator == rec["integrator"]
    assert profile.timestep == pytest.approx(rec["timestep_ms"] / 1e3)
    raw.update(fidelity="walk-2d-mujoco-tol0.01", fidelity_tolerance=None)
    path.write_text(yaml.safe_dump(raw))
    assert load_scene(path).profile("mujoco") == profile
    # measured again, it is still within tolerance
    assert remeasure(scene, "mujoco", profile, 0.1, 0.5) <= tolerance

    # asking for a tighter tolerance than any saved profile is a one-line error
    raw.update(fidelity="auto", fidelity_tolerance=tolerance / 100)
    path.write_text(yaml.safe_dump(raw))
    with pytest.raises(SpecError, match="no saved profile") as err:
        load_scene(path)
    assert "\n" not in str(err.value)


def test_unknown_scene_is_a_one_line_error() -> None:
    result = runner.invoke(app, ["fidelity", "sweep", "walk-9d", "--quick"], env=ENV)
    assert result.exit_code == 2
    assert "unknown" in _one_line_error(result.output)


@pytest.mark.parametrize("tolerance", ["0", "-0.01"])
def test_non_positive_tolerance_is_a_one_line_error(tolerance: str) -> None:
    result = runner.invoke(
        app, ["fidelity", "sweep", "walk-2d", "--quick", f"--tolerance={tolerance}"], env=ENV
    )
    assert result.exit_code == 2
    assert "--tolerance" in _one_line_error(result.output)


def test_empty_grid_is_a_one_line_error() -> None:
    result = runner.invoke(
        app, ["fidelity", "sweep", "walk-2d", "--quick", "--integrators", "leapfrog"], env=ENV
    )
    assert result.exit_code == 2
    assert "no profile" in _one_line_error(result.output)


def test_backend_the_scene_lacks_is_a_one_line_error() -> None:
    result = runner.invoke(
        app, ["fidelity", "stress", "walk-3d", "--backend", "opensim", "--quick"], env=ENV
    )
    assert result.exit_code == 2
    assert "runs on" in _one_line_error(result.output)


def test_quick_stress_prints_a_stability_map_and_a_limit() -> None:
    args = ["fidelity", "stress", "walk-3d", "--quick", "--seconds", "0.3"]
    result = runner.invoke(app, args, env=ENV)
    assert result.exit_code == 0, result.output
    assert "stability map" in result.output
    assert "euler 20ms" in result.output and "diverged" in result.output
    assert "largest stable step" in result.output
    as_json = runner.invoke(app, [*args, "--no-bisect", "--json"], env=ENV)
    assert as_json.exit_code == 0, as_json.output
    outcome = json.loads(as_json.stdout)
    assert outcome["scene"] == "walk-3d" and outcome["limits"] == []
    euler = next(row for row in outcome["rows"] if row["profile"] == "euler 20ms")
    assert any(cause.startswith("diverged") for cause in euler.values())


def test_a_task_tolerance_no_profile_meets_leaves_nothing_recommended(tmp_path: Path) -> None:
    """Every profile's mean distance differs from the reference's by more than 1e-12 m."""
    args = ["fidelity", "sweep", "walk-2d", "--quick", "--task-tolerance", "1e-12"]
    result = runner.invoke(app, [*args, "--no-save", "--out", str(tmp_path), "--json"], env=ENV)
    assert result.exit_code == 0, result.output
    printed = json.loads(result.stdout)
    assert printed["result"]["recommended"] is None and printed["saved"] is None
    table = json.loads((tmp_path / "walk-2d-mujoco.json").read_text())
    assert table["recommended"] is None and not any(r["within"] for r in table["rows"])
    assert all(abs(r["task"]["distance_vs_ref"]) > 1e-12 for r in table["rows"])
