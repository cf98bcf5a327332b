"""The body's coordinate functions against OpenSim's own (real ``opensim``)."""

from __future__ import annotations

import numpy as np
import opensim
import pytest
from gaitforge.workers.bodies.functions import Linear, Spline, derivative, evaluate

KNEE_X = [-2.0944, -1.74533, -1.39626, -1.0472, -0.698132, -0.349066, -0.174533, 0.197344]
KNEE_Y = [-0.0032, 0.00179, 0.00411, 0.0041, 0.00212, -0.001, -0.0031, -0.005227]
QUERY = np.linspace(-2.5, 0.5, 61)  # inside the knots and beyond both ends


def _opensim_spline(x: list[float], y: list[float]) -> opensim.SimmSpline:
    spline = opensim.SimmSpline()
    for a, b in zip(x, y, strict=True):
        spline.addPoint(a, b)
    return spline


@pytest.mark.parametrize("knots", [2, 3, 4, 8])
def test_spline_values_and_slopes_are_opensims(knots: int) -> None:
    x, y = KNEE_X[:knots], KNEE_Y[:knots]
    reference = _opensim_spline(x, y)
    first = opensim.StdVectorInt()
    first.append(0)
    values = [reference.calcValue(opensim.Vector(1, float(q))) for q in QUERY]
    slopes = [reference.calcDerivative(first, opensim.Vector(1, float(q))) for q in QUERY]
    np.testing.assert_allclose(evaluate(Spline(x=x, y=y), QUERY), values, atol=1e-12)
    np.testing.assert_allclose(derivative(Spline(x=x, y=y), QUERY), slopes, atol=1e-10)


def test_linear_and_constant() -> None:
    np.testing.assert_allclose(evaluate(Linear(slope=-0.5, intercept=0.1), [0.0, 2.0]), [0.1, -0.9])
    np.testing.assert_allclose(derivative(Linear(slope=0.0, intercept=3.0), [1.0, 2.0]), [0, 0])


def test_spline_knots_must_increase() -> None:
    with pytest.raises(ValueError, match="strictly increasing"):
        Spline(x=[0.0, 0.0, 1.0], y=[1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="knots"):
        Spline(x=[0.0, 1.0], y=[1.0, 2.0, 3.0])
