"""Importing OpenSim models as neutral bodies: the six example models, what the import keeps
(checked against OpenSim on the original file), and bad input (real ``opensim``)."""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import numpy as np
import opensim
import pytest
import yaml
from gaitforge.service.cli import app
from gaitforge.workers.bodies import load_body
from gaitforge.workers.bodies.functions import evaluate
from gaitforge.workers.bodies.osim_import import import_osim
from gaitforge.workers.bodies.schema import Body, PathPoint
from gaitforge.workers.fidelity.conversion import measure_conversion
from gaitforge.workers.fidelity.conversion_report import ConversionReport
from gaitforge.workers.scenes.prune import PrunePlan
from gaitforge.workers.sim.mujoco.build import build_spec
from gaitforge.workers.sim.mujoco.couplings import set_coupled_qpos
from gaitforge.workers.sim.opensim.build import build_model
from gaitforge.workers.spec_io import SpecError
from numpy.polynomial.polynomial import polyval
from typer.testing import CliRunner

from tests.workers.converted import converted

pytestmark = pytest.mark.xdist_group("converted")  # one worker converts each model once

MODELS = Path(__file__).resolve().parents[3] / "examples" / "models"
EXPECTED = {  # model: (free dofs, coupled dofs, muscles)
    "gait10dof18musc": (10, 4, 18),
    "leg6dof9musc": (6, 8, 9),
    "arm26": (2, 0, 6),
    "gait2354_simbody": (23, 4, 54),
    "gait2392_millard2012muscle": (23, 4, 92),
    "Rajagopal2016": (37, 14, 80),
}
runner = CliRunner()


@pytest.mark.parametrize("model", sorted(EXPECTED))
def test_every_example_model_imports_quickly_and_whole(model: str) -> None:
    result = import_osim(MODELS / f"{model}.osim")
    free, coupled, muscles = EXPECTED[model]
    body = result.body
    assert result.report.seconds < 30
    assert len(body.dof_names) - len(body.coupled_dofs) == free
    assert len(body.coupled_dofs) == coupled
    assert len(body.muscles) == muscles
    reference = opensim.Model(str(MODELS / f"{model}.osim"))
    bodies = reference.getBodySet()
    masses = {bodies.get(i).getName(): bodies.get(i).getMass() for i in range(bodies.getSize())}
    for segment in body.segments:
        assert segment.mass == pytest.approx(max(masses[segment.name], 1e-3))


@pytest.mark.parametrize("model", sorted(EXPECTED))
def test_every_imported_body_builds_on_both_simulators(model: str) -> None:
    """With MuJoCo's stand-ins fitted (``convert``, what ``bodies import`` writes; once per
    session, ``tests.workers.converted``)."""
    body = converted(model).body
    mujoco_model = build_spec(body).compile()
    assert mujoco_model.ntendon == len(body.muscles)
    plan = PrunePlan(
        kept_dofs=body.dof_names,
        locked_dofs={},
        kept_muscles=[m.name for m in body.muscles],
        removed_muscles={},
        contact_geoms=[s.name for s in body.contact_spheres],
        obstacles=0,
    )
    built = build_model(body, plan).model
    built.initSystem()
    assert built.getMuscles().getSize() == len(body.muscles)


def test_the_knee_translation_follows_opensims_spline() -> None:
    """gait2392's knee: the tibia's offset from the femur over the knee's range, read from
    OpenSim's own kinematics, equals the imported coupled dofs' functions."""
    body = import_osim(MODELS / "gait2392_millard2012muscle.osim").body
    model = opensim.Model(str(MODELS / "gait2392_millard2012muscle.osim"))
    state = model.initSystem()
    knee = model.getCoordinateSet().get("knee_angle_r")
    femur, tibia = model.getBodySet().get("femur_r"), model.getBodySet().get("tibia_r")
    slides = [d for d in body.joint_of_dof("knee_angle_r").dofs if d.type == "slide"]
    assert [d.coupled.coordinate for d in slides] == ["knee_angle_r", "knee_angle_r"]
    for angle in np.linspace(-2.0, 0.1, 8):
        knee.setValue(state, float(angle))
        model.realizePosition(state)
        offset = tibia.findStationLocationInAnotherFrame(state, opensim.Vec3(0, 0, 0), femur)
        expected = np.zeros(3)
        for dof in slides:
            expected += np.asarray(dof.axis) * float(evaluate(dof.coupled.function, angle))
        parent = np.asarray(body.joint_of_dof("knee_angle_r").location_in_parent)
        got = np.array([offset.get(i) for i in range(3)])
        np.testing.assert_allclose(got, parent + expected, atol=1e-9)


def test_a_coordinate_coupler_becomes_dofs_coupled_to_the_independent_coordinate() -> None:
    result = import_osim(MODELS / "Rajagopal2016.osim")
    patella = result.body.joint_of("patella_r")
    assert patella.dofs and all(d.coupled for d in patella.dofs)
    assert {d.coupled.coordinate for d in patella.dofs} == {"knee_angle_r"}
    assert "knee_angle_r_beta" not in result.body.dof_names
    assert any("knee_angle_r_beta" in note for note in result.report.notes)


def test_a_wrap_goes_where_opensim_wraps_the_path() -> None:
    """Rajagopal2016's vastus lateralis: in the default pose its path passes closest to the
    femur's knee-extensor cylinder between its two patella points, but OpenSim wraps it
    between the femur and the patella once the knee bends past about 90 degrees; the import
    puts the wrap there."""
    vaslat = next(
        m for m in import_osim(MODELS / "Rajagopal2016.osim").body.muscles if m.name == "vaslat_r"
    )
    wrap_at = next(i for i, e in enumerate(vaslat.path) if getattr(e, "wrap", None))
    before, after = vaslat.path[wrap_at - 1], vaslat.path[wrap_at + 1]
    assert vaslat.path[wrap_at].wrap == "KnExt_at_fem_r"
    assert (before.segment, after.segment) == ("femur_r", "patella_r")
    model = opensim.Model(str(MODELS / "Rajagopal2016.osim"))
    state = model.initSystem()
    model.getCoordinateSet().get("knee_angle_r").setValue(state, np.radians(110), True)
    model.realizePosition(state)
    path = model.getMuscles().get("vaslat_r").getGeometryPath().getCurrentPath(state)
    names = [path.get(i).getName() for i in range(path.getSize())]
    assert names[names.index("vaslat_r-P2") + 1] != "vaslat_r-P3"  # wrap points between them


def test_conditional_and_moving_points_and_ellipsoids_are_kept() -> None:
    gait = import_osim(MODELS / "gait10dof18musc.osim").body
    vasti = next(m for m in gait.muscles if m.name == "vasti_r")
    conditional = [p for p in vasti.points if p.active_when]
    moving = [p for p in vasti.points if p.moves_with]
    assert conditional[0].active_when.coordinate == "knee_angle_r"
    assert conditional[0].active_when.range == pytest.approx((-2.61799, -1.42))
    assert moving[0].moves_with.coordinate == "knee_angle_r"
    arm = import_osim(MODELS / "arm26.osim")
    assert {w.type for w in arm.body.wrap_objects} == {"cylinder", "ellipsoid"}


def test_the_cli_writes_a_body_file_that_loads_back_and_its_report(tmp_path: Path) -> None:
    args = ["bodies", "import", str(MODELS / "leg6dof9musc.osim"), "--out", str(tmp_path)]
    result = runner.invoke(app, [*args, "--json", "--no-fit"])
    assert result.exit_code == 0, result.output
    outcome = json.loads(result.stdout)
    body = load_body(outcome["body_file"])
    # exactly: written and imported again in this process, so the file must lose nothing
    assert body == import_osim(MODELS / "leg6dof9musc.osim").body
    fitted = runner.invoke(app, [*args, "--json", "--overwrite"])
    assert fitted.exit_code == 0, fitted.output
    assert any("wrap cylinder" in line for line in json.loads(fitted.stdout)["approximated"])
    report = Path(outcome["report_file"]).read_text()
    assert "## Approximated" in report and "toes_r" in report  # its zero inertia raised
    again = runner.invoke(app, args)
    assert again.exit_code == 2 and "--overwrite" in again.stderr
    assert len(again.stderr.strip().splitlines()) == 1


def test_foot_contacts_follow_the_rule_and_a_contacts_file_replaces_them(tmp_path: Path) -> None:
    body = import_osim(MODELS / "gait2392_millard2012muscle.osim").body
    feet = {s.name: (s.segment, s.foot) for s in body.contact_spheres}
    assert feet == {
        "r_heel": ("calcn_r", "foot_right"),
        "r_toe_lateral": ("toes_r", "foot_right"),
        "r_toe_medial": ("toes_r", "foot_right"),
        "l_heel": ("calcn_l", "foot_left"),
        "l_toe_lateral": ("toes_l", "foot_left"),
        "l_toe_medial": ("toes_l", "foot_left"),
    }
    lateral = {s.name: s.location[2] for s in body.contact_spheres if "lateral" in s.name}
    assert lateral["r_toe_lateral"] > 0 > lateral["l_toe_lateral"]  # Z is to the right
    contacts = tmp_path / "contacts.yaml"
    sphere = {"name": "r_ball", "segment": "calcn_r", "location": [0.15, 0, 0], "radius": 0.02}
    contacts.write_text(yaml.safe_dump([sphere]))
    replaced = import_osim(MODELS / "gait2392_millard2012muscle.osim", contacts=contacts).body
    assert [s.name for s in replaced.contact_spheres] == ["r_ball"]
    contacts.write_text(yaml.safe_dump([{**sphere, "radius": -1}]))
    with pytest.raises(SpecError, match=r"contacts.yaml: 0.radius"):
        import_osim(MODELS / "gait2392_millard2012muscle.osim", contacts=contacts)


def _cli_error(*args: str) -> str:
    result = runner.invoke(app, ["bodies", "import", *args])
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, lines
    return lines[0]


def test_bad_models_are_refused_in_one_line_naming_the_element(tmp_path: Path) -> None:
    out = str(tmp_path / "out")
    text = (MODELS / "arm26.osim").read_text()
    assert "cannot read the model" in _cli_error(str(tmp_path / "missing.osim"), "--out", out)
    truncated = tmp_path / "truncated.osim"
    truncated.write_text(text[: len(text) // 2])
    problem = _cli_error(str(truncated), "--out", out)
    assert "line" in problem and "not well-formed XML" in problem
    assert "(the file ends there: truncated)" in problem and "OpenSim cannot load it" in problem
    unknown = tmp_path / "unknown.osim"
    unknown.write_text(text.replace("<WeldJoint", '<Bogus name="strange" /><WeldJoint', 1))
    assert '<Bogus name="strange">: an unknown component' in _cli_error(str(unknown), "--out", out)
    other = tmp_path / "other.osim"
    other.write_text("<?xml version='1.0'?><Storage />")
    assert "not an OpenSim model" in _cli_error(str(other), "--out", out)
    assert "ending in .osim" in _cli_error(str(truncated.with_suffix(".txt")), "--out", out)


def test_an_unsupported_joint_names_its_path(tmp_path: Path) -> None:
    model = opensim.Model()
    model.setName("one_ellipsoid")
    bone = opensim.Body("bone", 1.0, opensim.Vec3(0), opensim.Inertia(0.1, 0.1, 0.1))
    model.addBody(bone)
    joint = opensim.EllipsoidJoint(
        "shoulder",
        model.getGround(),
        opensim.Vec3(0),
        opensim.Vec3(0),
        bone,
        opensim.Vec3(0),
        opensim.Vec3(0),
        opensim.Vec3(0.1, 0.2, 0.3),
    )
    model.addJoint(joint)
    model.finalizeConnections()
    path = tmp_path / "one_ellipsoid.osim"
    model.printToXML(str(path))
    with pytest.raises(SpecError, match=r"/jointset/shoulder: joint type EllipsoidJoint"):
        import_osim(path)


def _without_stand_ins(body: Body, *, carriers_only: bool = False) -> Body:
    """``body`` with its points' stand-ins (or only its moving points' carriers) replaced by
    the default rule (a conditional point kept iff active at the default pose, a moving one
    fixed where it is then)."""

    def cleared(e: PathPoint) -> bool:
        return e.stand_in is not None and (not carriers_only or e.stand_in.follow is not None)

    muscles = [
        m.model_copy(
            update={
                "path": [
                    e.model_copy(update={"stand_in": None})
                    if isinstance(e, PathPoint) and cleared(e)
                    else e
                    for e in m.path
                ]
            }
        )
        for m in body.muscles
    ]
    return body.model_copy(update={"muscles": muscles})


def test_fitted_stand_ins_keep_moment_arms_better_than_the_default_rule() -> None:
    """gait10dof18musc's knee muscles have conditional and moving points; MuJoCo stands in
    for them with fixed points the import fits. Measured against OpenSim's own moment arms
    on the original file, the fitted stand-ins cut the mean error of the default rule (a
    point kept iff active at the default pose, a moving one fixed where it is then) from 5.9
    to 3.3 mm; asserted with a margin."""
    model = MODELS / "gait10dof18musc.osim"
    body = import_osim(model).body
    assert any(p.stand_in for m in body.muscles for p in m.points)
    options = {"poses": 2, "force_poses": 1, "drop_s": 0.01}
    fitted = measure_conversion(model, body, **options)
    default = measure_conversion(model, _without_stand_ins(body), **options)

    def mean_error(report: ConversionReport) -> float:
        return float(np.mean([p.arm_rms_mm for p in report.pairs]))

    assert mean_error(fitted) < 0.75 * mean_error(default)


def test_another_function_is_resampled_and_reported(tmp_path: Path) -> None:
    """A custom-joint axis driven through a function the body has no type for (here OpenSim's
    PiecewiseLinearFunction) becomes a spline through its values, and the report says so."""
    model = opensim.Model(str(MODELS / "gait10dof18musc.osim"))
    knee = opensim.CustomJoint.safeDownCast(model.getJointSet().get("knee_r"))
    piecewise = opensim.PiecewiseLinearFunction()
    for x, y in [(-2.1, -0.003), (-1.0, 0.004), (0.0, -0.005), (2.1, -0.005)]:
        piecewise.addPoint(x, y)
    knee.updSpatialTransform().updTransformAxis(3).set_function(piecewise)
    model.finalizeConnections()
    path = tmp_path / "piecewise.osim"
    model.printToXML(str(path))
    result = import_osim(path)
    assert any("PiecewiseLinearFunction resampled" in a for a in result.report.approximated)
    slide = next(d for d in result.body.joint_of_dof("knee_angle_r").dofs if d.coupled)
    values = evaluate(slide.coupled.function, [-1.0, 0.0])
    np.testing.assert_allclose(values, [0.004, -0.005], atol=3e-4)  # kinks between knots


def test_the_patellar_insertion_rides_a_carrier_that_keeps_the_quadriceps_moment_arms() -> None:
    """gait10dof18musc's vasti and rectus femoris insert at a point that moves with the knee.
    The import carries it on a MuJoCo body whose slides follow fitted quartics of the knee
    angle: the site sits where the quartics say at any knee angle, and the knee moment arms
    pass the conversion's bound (2 mm RMS or 5 % of the peak: 1.3-1.5 mm), where the point
    fixed at its default place misses it (7-9 mm); the other stand-ins fitted (``convert``)
    in both."""
    model = MODELS / "gait10dof18musc.osim"
    body = converted("gait10dof18musc").body
    vasti = next(m for m in body.muscles if m.name == "vasti_r")
    index, point = next((i, p) for i, p in enumerate(vasti.path) if p.moves_with)
    assert point.stand_in is not None and point.stand_in.follow is not None

    mj_model = build_spec(body).compile()
    data = mujoco.MjData(mj_model)
    knee = mj_model.joint("knee_angle_r")
    for angle in (-1.8, -0.9, 0.0):
        data.qpos[knee.qposadr] = angle
        set_coupled_qpos(mj_model, data)
        mujoco.mj_kinematics(mj_model, data)
        tibia = mj_model.body("tibia_r")
        site = data.site(f"vasti_r_p{index}").xpos
        local = data.xmat[tibia.id].reshape(3, 3).T @ (site - data.xpos[tibia.id])
        expected = [polyval(angle, c) for c in point.stand_in.follow]
        np.testing.assert_allclose(local, expected, atol=1e-9)

    options = {"poses": 2, "force_poses": 1, "drop_s": 0.01}
    quadriceps = {"vasti_r", "rect_fem_r"}

    def knee_pairs(report: ConversionReport) -> list[bool]:
        return [
            p.passed
            for p in report.pairs
            if p.muscle in quadriceps and p.coordinate == "knee_angle_r"
        ]

    assert knee_pairs(measure_conversion(model, body, **options)) == [True, True]
    fixed = measure_conversion(model, _without_stand_ins(body, carriers_only=True), **options)
    assert knee_pairs(fixed) == [False, False]


def test_an_opensim_3_model_is_upgraded_by_opensim_and_imported() -> None:
    """The 2019 challenge's legs are an OpenSim 3.0 file (``Version="30000"``) whose tags
    (``HuntCrossleyForce::ContactParametersSet``) no strict XML parser takes; OpenSim 4
    loads and upgrades it, and so does the import, saying so."""
    result = import_osim(MODELS / "gait14dof22musc_20170320.osim")
    body, report = result.body, result.report
    assert len(body.muscles) == 22 and len(body.segments) == 13
    assert sum(1 for s in body.contact_spheres if s.part == "foot") >= 4
    assert any("document version 30000" in note and "upgraded" in note for note in report.notes)
