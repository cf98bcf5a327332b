"""Wrap cylinders fitted in place of conditional path points, against OpenSim (real
simulators). The fitted bodies are ``convert``'s (``tests.workers.converted``, once per
session): the import, this fit, then the choice of wrap side sites, which leaves these two
models as the fit made them (``convert``'s body equals ``fit_conditional_wraps``'s here),
and the fit's notes among the report's approximations."""

from __future__ import annotations

import pytest
from gaitforge.workers.bodies.osim_import import import_osim
from gaitforge.workers.bodies.schema import PathPoint
from gaitforge.workers.fidelity.conversion import measure_conversion

from tests.workers.converted import MODELS, converted

GAIT10 = MODELS / "gait10dof18musc.osim"

pytestmark = pytest.mark.xdist_group("converted")  # one worker converts each model once


def test_cylinders_in_place_of_conditional_points_keep_more_moment_arms() -> None:
    """gait10dof18musc's gastrocnemius bends over the femoral condyles through a conditional
    point: a fitted 5 mm cylinder brings its knee moment arm within bounds (4.9 -> under 2 mm
    RMS), and the model's share of pairs within bounds rises (16 -> 18 of 24)."""
    body = import_osim(GAIT10).body
    result = converted("gait10dof18musc")
    fitted, notes = result.body, result.report.approximated
    gastroc = next(m for m in fitted.muscles if m.name == "gastroc_r")
    wrapped = [p for p in gastroc.path if isinstance(p, PathPoint) and p.stand_in]
    assert wrapped and wrapped[0].stand_in.wrap in {w.name for w in fitted.wrap_objects}
    assert any(n.startswith("muscle gastroc_r: conditional point 1 as a wrap") for n in notes)
    options = {"poses": 1, "force_poses": 1, "drop_s": 0.0}
    before = measure_conversion(GAIT10, body, **options)
    after = measure_conversion(GAIT10, fitted, **options)
    assert after.pass_share > before.pass_share
    knee = next(p for p in after.pairs if (p.muscle, p.coordinate) == ("gastroc_r", "knee_angle_r"))
    assert knee.passed


def test_two_conditional_points_in_a_row_take_one_wrap_between_sites() -> None:
    """gait2392's vastus medialis crosses the femoral condyle through two conditional points
    in a row, both left out by the import. One of them becomes a wrap cylinder (MuJoCo needs
    a site between two wraps), the other stays out, and the knee moment arm comes within
    bounds (10 mm RMS before)."""
    model = MODELS / "gait2392_millard2012muscle.osim"
    fitted = converted("gait2392_millard2012muscle").body
    vastus = next(m for m in fitted.muscles if m.name == "vas_med_r")
    conditional = [p for p in vastus.path if isinstance(p, PathPoint) and p.active_when]
    assert len(conditional) == 2
    assert sum(1 for p in conditional if p.stand_in and p.stand_in.wrap) == 1
    report = measure_conversion(model, fitted, poses=1, force_poses=1, drop_s=0.0)
    pairs = {(p.muscle, p.coordinate): p.passed for p in report.pairs}
    assert pairs[("vas_med_r", "knee_angle_r")]
