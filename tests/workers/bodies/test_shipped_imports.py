"""Bodies shipped from an OpenSim model are what ``gaitforge bodies import`` makes of it today
(rewrite them with the command in their header when the importer changes)."""

from __future__ import annotations

from pathlib import Path

import pytest
from gaitforge.service.ops.bodies import convert
from gaitforge.workers.bodies import load_body

from tests.tolerance import assert_close

MODELS = Path(__file__).resolve().parents[3] / "examples" / "models"
SHIPPED = {
    "gait2354": ("gait2354_simbody.osim", False),
    "gait14dof22musc": ("gait14dof22musc_20170320.osim", True),
}
"""body -> (its model, whether MuJoCo's stand-ins were fitted: the command in its header)"""


@pytest.mark.parametrize("body", sorted(SHIPPED))
def test_a_shipped_import_equals_a_fresh_one(body: str) -> None:
    """Equal but for the last digits of fitted numbers: the shipped file was written on
    another machine, and least-squares fits (the carriers' quartics) differ there."""
    model, fit = SHIPPED[body]
    fresh = convert(MODELS / model, name=body, fit=fit).body
    assert_close(load_body(body), fresh)
