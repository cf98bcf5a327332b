"""The example OpenSim models converted once per test session, for the tests that only read
the result: ``convert`` (what ``gaitforge bodies import`` writes), the import and then
MuJoCo's stand-ins fitted against the original, half a minute for gait2392 here."""

from __future__ import annotations

import copy
import functools
from pathlib import Path

from gaitforge.service.ops.bodies import convert
from gaitforge.workers.bodies.osim_import import ImportResult

MODELS = Path(__file__).resolve().parents[2] / "examples" / "models"


@functools.cache
def _converted(model: str) -> ImportResult:
    return convert(MODELS / f"{model}.osim")


def converted(model: str) -> ImportResult:
    """``convert`` of ``examples/models/<model>.osim``: a copy of the session's one (a test
    may change what it gets)."""
    return copy.deepcopy(_converted(model))
