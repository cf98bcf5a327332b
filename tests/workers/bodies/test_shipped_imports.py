"""Bodies shipped from an OpenSim model are what ``gaitforge bodies import`` makes of it today
(rewrite them with the command in their header when the importer changes)."""

from __future__ import annotations

from pathlib import Path

import pytest
from gaitforge.workers.bodies import load_body
from gaitforge.workers.bodies.osim_import import import_osim

MODELS = Path(__file__).resolve().parents[3] / "examples" / "models"
SHIPPED = {"gait2354": "gait2354_simbody.osim"}


@pytest.mark.parametrize("body", sorted(SHIPPED))
def test_a_shipped_import_equals_a_fresh_one(body: str) -> None:
    fresh = import_osim(MODELS / SHIPPED[body], name=body).body
    assert load_body(body) == fresh
