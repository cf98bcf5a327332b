"""The conversion measure on real OpenSim and MuJoCo: an imported model against its original
(arm26, gait10dof18musc), a deliberately wrong body, bad files, and the CLI command."""

from __future__ import annotations

import json
import math
from functools import cache
from pathlib import Path

import mujoco
import numpy as np
import pytest
import typer
from gaitforge.service.conversion_commands import compare
from gaitforge.workers.bodies.osim_import import import_osim
from gaitforge.workers.bodies.schema import Body
from gaitforge.workers.fidelity.conversion import measure_conversion
from gaitforge.workers.fidelity.conversion_plot import plot_conversion
from gaitforge.workers.fidelity.conversion_report import ConversionReport
from gaitforge.workers.fidelity.conversion_sides import MujocoSide, load_opensim_model
from gaitforge.workers.sim.mujoco.build import build_spec
from gaitforge.workers.sim.mujoco.lock import coupled_qpos
from gaitforge.workers.spec_io import SpecError
from typer.testing import CliRunner

MODELS = Path(__file__).resolve().parents[3] / "examples" / "models"
ARM26 = MODELS / "arm26.osim"
GAIT10 = MODELS / "gait10dof18musc.osim"
QUICK = {"poses": 5, "sweep_points": 9, "force_poses": 2, "drop_s": 0.2}


@cache
def _body(path: Path) -> Body:
    return import_osim(path).body


@cache
def _arm26_report() -> ConversionReport:
    return measure_conversion(ARM26, _body(ARM26), **QUICK)


def test_arm26_figures_are_computed_and_sane() -> None:
    report = _arm26_report()
    for row in report.masses:
        if row.opensim_kg > 0:  # arm26's massless base gets a token mass in the body
            assert row.mujoco_kg == pytest.approx(row.opensim_kg, abs=1e-9), row.segment
    assert report.kinematics.poses == 5 and report.kinematics.segments == 3
    assert report.kinematics.worst_mm < 0.1
    # six muscles; the three triceps heads and the biceps' long head span both joints
    assert len(report.pairs) == 9
    for pair in report.pairs:
        assert pair.q.shape == (9,)
        assert np.all(np.isfinite(pair.arm_mujoco)) and np.all(np.isfinite(pair.length_mujoco))
        assert 5.0 < pair.arm_peak_mm < 100.0, (pair.muscle, pair.coordinate)
        if pair.coordinate == "r_elbow_flex":  # no wrap crosses the elbow: exact paths
            assert pair.passed and pair.arm_rms_mm < 0.5, pair.muscle
    assert 0.0 < report.pass_share <= 1.0
    assert len(report.forces) == 2 * 2 * 6
    active = [r for r in report.forces if r.activation == 1.0]
    assert all(r.opensim_n > 0 and r.mujoco_n > 0 for r in active)
    assert report.drop is not None and set(report.drop.rms) == {"r_shoulder_elev", "r_elbow_flex"}
    assert all(math.isfinite(v) for v in report.drop.rms.values())


def test_report_renders_as_markdown_json_and_png(tmp_path: Path) -> None:
    report = _arm26_report()
    text = report.markdown()
    assert "| moment-arm pairs passing" in text and f"{report.pass_share:.1%}" in text
    assert text.count("| r_") >= 9  # every pair of the worst-10 table names its coordinate
    data = json.loads(json.dumps(report.to_json(), allow_nan=False))
    assert data["summary"]["pairs"] == 9
    assert len(data["worst_pair_curves"]["q"]) == 9
    png = tmp_path / "arm26.png"
    plot_conversion(report, png)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_moved_path_point_is_caught() -> None:
    """BRA spans the elbow only; its insertion moved 1 cm on the ulna fails its pair and no
    other."""
    body = _body(ARM26)
    raw = body.model_dump(mode="python")
    muscle = next(m for m in raw["muscles"] if m["name"] == "BRA")
    x, y, z = muscle["path"][-1]["location"]
    muscle["path"][-1]["location"] = (x + 0.01, y, z)
    wrong = Body.model_validate(raw)
    report = measure_conversion(ARM26, wrong, poses=2, sweep_points=9, force_poses=1, drop_s=0)
    verdicts = {(p.muscle, p.coordinate): p.passed for p in report.pairs}
    assert verdicts[("BRA", "r_elbow_flex")] is False
    right = {(p.muscle, p.coordinate): p.passed for p in _arm26_report().pairs}
    assert {k: v for k, v in verdicts.items() if k[0] != "BRA"} == {
        k: v for k, v in right.items() if k[0] != "BRA"
    }
    assert right[("BRA", "r_elbow_flex")] is True
    assert report.drop is None


def test_gait10_couplings_and_masses() -> None:
    """gait10dof18musc's knees move their shank through splines of the knee angle (coupled
    dofs in the body): centres of mass and the moment arms of muscles crossing the knee come
    out through the couplings."""
    report = measure_conversion(
        GAIT10, _body(GAIT10), poses=5, sweep_points=9, force_poses=1, drop_s=0
    )
    assert report.summary()["total_mass_mujoco_kg"] == pytest.approx(
        report.summary()["total_mass_opensim_kg"], abs=1e-9
    )
    assert report.kinematics.worst_mm < 1.0  # a spline's quartic fit: well under a millimetre
    pairs = {(p.muscle, p.coordinate): p for p in report.pairs}
    assert pairs[("bifemsh_r", "knee_angle_r")].passed
    assert pairs[("soleus_r", "ankle_angle_r")].passed
    assert ("hamstrings_r", "hip_flexion_r") in pairs and ("hamstrings_r", "knee_angle_r") in pairs


def test_mujoco_moment_arm_is_minus_the_total_derivative_of_length() -> None:
    """The chain through coupled joints: ``-dL/dq_knee`` by central differences with every
    coupled joint following the knee."""
    model = build_spec(_body(GAIT10)).compile()
    assert model.neq > 0  # the knee's coupled translations
    side = MujocoSide(model)
    knee, step = "knee_angle_r", 1e-6
    tendon = side.tendons["bifemsh_r"]
    for angle in (-1.5, -0.7, -0.1):
        side.set_pose({knee: angle})
        arm = side.moment_arms(knee)[tendon]
        lengths = []
        for q in (angle + step, angle - step):
            qpos = model.qpos0.copy()
            qpos[model.jnt_qposadr[side.joints[knee]]] = q
            data = mujoco.MjData(model)
            data.qpos[:] = coupled_qpos(model, qpos)
            mujoco.mj_fwdPosition(model, data)
            lengths.append(data.ten_length[tendon])
        assert arm == pytest.approx(-(lengths[0] - lengths[1]) / (2 * step), abs=1e-6)


@pytest.mark.parametrize(
    ("content", "expected"),
    [
        (None, "file not found"),
        (
            "<OpenSimDocument><Model",
            "line 1, column 17: not well-formed XML: unclosed token (the file ends there: "
            "truncated); OpenSim cannot load it",
        ),
        ("<gait/>", "not an OpenSim model (no <OpenSimDocument><Model>); refused"),
    ],
)
def test_bad_model_files_fail_in_one_line(
    tmp_path: Path, content: str | None, expected: str
) -> None:
    path = tmp_path / "model.osim"
    if content is not None:
        path.write_text(content)
    with pytest.raises(SpecError) as caught:
        load_opensim_model(path)
    assert str(caught.value) == f"{path}: {expected}"


def _cli() -> typer.Typer:
    app = typer.Typer()
    app.command("compare")(compare)
    app.command("other")(lambda: None)  # two commands: typer keeps ``compare`` as a name
    return app


def test_cli_missing_model_is_one_line(tmp_path: Path) -> None:
    missing = tmp_path / "nowhere.osim"
    result = CliRunner().invoke(_cli(), ["compare", str(missing)])
    assert result.exit_code == 2
    assert result.exception is None or isinstance(result.exception, SystemExit)
    assert "Traceback" not in result.output
    assert f"{missing}: file not found" in result.output


def test_cli_missing_body_is_one_line(tmp_path: Path) -> None:
    missing = tmp_path / "body.yaml"
    result = CliRunner().invoke(_cli(), ["compare", str(ARM26), "--body", str(missing)])
    assert result.exit_code == 2 and f"{missing}: file not found" in result.output


def test_cli_imports_the_model_and_writes_json_and_png(tmp_path: Path) -> None:
    png = tmp_path / "arm26.png"
    result = CliRunner().invoke(_cli(), ["compare", str(ARM26), "--png", str(png), "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["model"] == "arm26" and data["summary"]["pairs"] == 9
    assert png.stat().st_size > 10_000
