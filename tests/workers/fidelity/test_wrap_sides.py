"""Choosing which muscles keep MuJoCo's wrap side sites, against OpenSim (real simulators)."""

from __future__ import annotations

from pathlib import Path

from gaitforge.workers.bodies.osim_import import import_osim
from gaitforge.workers.bodies.schema import WrapRef
from gaitforge.workers.fidelity.conversion import measure_conversion
from gaitforge.workers.fidelity.wrap_sides import choose_wrap_sides

ARM26 = Path(__file__).resolve().parents[3] / "examples" / "models" / "arm26.osim"


def test_a_side_site_that_forces_the_long_way_round_is_dropped() -> None:
    """arm26's long triceps passes its humeral-head ellipsoid on the far side over much of
    the shoulder's range: OpenSim leaves it straight there, MuJoCo's side site would send it
    round (70 allowances of moment-arm error, 0.9 without)."""
    body = import_osim(ARM26).body
    tuned, notes = choose_wrap_sides(ARM26, body)
    sides = {m.name: [e.use_side for e in m.path if isinstance(e, WrapRef)] for m in tuned.muscles}
    assert sides["TRIlong"] == [False] * len(sides["TRIlong"])
    assert any("TRIlong" in n for n in notes)
    options = {"poses": 1, "force_poses": 1, "drop_s": 0.0}
    before = measure_conversion(ARM26, body, **options)
    after = measure_conversion(ARM26, tuned, **options)
    assert after.pass_share > before.pass_share
    triceps = [p for p in after.pairs if p.muscle == "TRIlong"]
    assert triceps and all(p.passed for p in triceps)
