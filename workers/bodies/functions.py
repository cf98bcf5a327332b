"""Functions of one coordinate that a body may use: OpenSim's ``LinearFunction`` (and
``Constant``, a zero slope) and ``SimmSpline``, evaluated here without a simulator.

``SimmSpline`` is the Forsythe-Malcolm-Moler cubic spline (the end conditions match the third
derivatives of the cubics through the first and through the last four knots; a line through
two knots, a parabola through three), extended
linearly beyond its end knots with their slopes. :func:`evaluate` reproduces OpenSim's
values to rounding (``tests/workers/test_body_functions.py``).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Discriminator, Field, Tag, model_validator


class Linear(BaseModel):
    """``y = slope * x + intercept``; a constant has slope 0."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    type: Literal["linear"] = "linear"
    slope: float = 1.0
    intercept: float = 0.0


class Spline(BaseModel):
    """A cubic spline through the knots ``(x[i], y[i])`` (OpenSim's ``SimmSpline``)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    type: Literal["spline"] = "spline"
    x: list[float] = Field(min_length=2, description="knots, strictly increasing")
    y: list[float] = Field(min_length=2, description="values at the knots")

    @model_validator(mode="after")
    def _check(self) -> Spline:
        if len(self.x) != len(self.y):
            raise ValueError(f"x has {len(self.x)} knots and y {len(self.y)} values")
        if any(b <= a for a, b in zip(self.x, self.x[1:], strict=False)):
            raise ValueError("x must be strictly increasing")
        return self


def _kind(value: Any) -> str | None:
    """``type`` where given; else a spline if it has knots (files may leave ``type`` out)."""
    if isinstance(value, dict):
        return value.get("type") or ("spline" if "x" in value else "linear")
    return getattr(value, "type", None)


Function = Annotated[
    Annotated[Linear, Tag("linear")] | Annotated[Spline, Tag("spline")], Discriminator(_kind)
]
"""A function of one coordinate: ``{slope, intercept}`` or ``{x: [...], y: [...]}``."""


def _fmm_coefficients(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``b, c, d`` of ``y[i] + b[i] t + c[i] t^2 + d[i] t^3`` with ``t = x - x[i]`` (FMM)."""
    n = len(x)
    if n == 2:  # too few knots for the end conditions: OpenSim's spline is then a line
        slope = (y[1] - y[0]) / (x[1] - x[0])
        return np.full(n, slope), np.zeros(n), np.zeros(n)
    if n == 3:  # ... and a parabola through three
        a2, a1, _ = np.polyfit(x, y, 2)
        return 2.0 * a2 * x + a1, np.full(n, a2), np.zeros(n)
    h = np.diff(x)
    diag = np.empty(n)
    upper = np.empty(n)
    rhs = np.empty(n)
    upper[:-1] = h
    slopes = np.diff(y) / h
    diag[1:-1] = 2.0 * (h[:-1] + h[1:])
    rhs[1:-1] = slopes[1:] - slopes[:-1]
    third_start = (slopes[2] - slopes[1]) / (x[3] - x[1]) - (slopes[1] - slopes[0]) / (x[2] - x[0])
    third_end = (slopes[-1] - slopes[-2]) / (x[-1] - x[-3]) - (slopes[-2] - slopes[-3]) / (
        x[-2] - x[-4]
    )
    diag[0], diag[-1] = -h[0], -h[-1]
    rhs[0] = third_start * h[0] ** 2 / (x[3] - x[0])
    rhs[-1] = -third_end * h[-1] ** 2 / (x[-1] - x[-4])
    # Forward elimination and back substitution of the symmetric tridiagonal system.
    for i in range(1, n):
        t = upper[i - 1] / diag[i - 1]
        diag[i] -= t * upper[i - 1]
        rhs[i] -= t * rhs[i - 1]
    sigma = np.empty(n)
    sigma[-1] = rhs[-1] / diag[-1]
    for i in range(n - 2, -1, -1):
        sigma[i] = (rhs[i] - upper[i] * sigma[i + 1]) / diag[i]
    b = np.empty(n)
    c = 3.0 * sigma
    d = np.empty(n)
    b[:-1] = slopes - h * (sigma[1:] + 2.0 * sigma[:-1])
    d[:-1] = (sigma[1:] - sigma[:-1]) / h
    b[-1] = slopes[-1] + h[-1] * (sigma[-2] + 2.0 * sigma[-1])
    c[-1] = 3.0 * sigma[-1]
    d[-1] = d[-2]
    return b, c, d


def evaluate(function: Linear | Spline, x: np.ndarray | float) -> np.ndarray:
    """The function's values at ``x`` (any shape; same shape out)."""
    q = np.asarray(x, dtype=float)
    if isinstance(function, Linear):
        return function.slope * q + function.intercept
    knots, values = np.asarray(function.x), np.asarray(function.y)
    b, c, d = _fmm_coefficients(knots, values)
    i = np.clip(np.searchsorted(knots, q, side="right") - 1, 0, len(knots) - 1)
    t = q - knots[i]
    inside = values[i] + t * (b[i] + t * (c[i] + t * d[i]))
    below = values[0] + b[0] * (q - knots[0])
    above = values[-1] + b[-1] * (q - knots[-1])
    return np.where(q < knots[0], below, np.where(q > knots[-1], above, inside))


def derivative(function: Linear | Spline, x: np.ndarray | float) -> np.ndarray:
    """``d function / d x`` at ``x`` (any shape; same shape out)."""
    q = np.asarray(x, dtype=float)
    if isinstance(function, Linear):
        return np.full_like(q, function.slope)
    knots = np.asarray(function.x)
    b, c, d = _fmm_coefficients(knots, np.asarray(function.y))
    i = np.clip(np.searchsorted(knots, q, side="right") - 1, 0, len(knots) - 1)
    t = q - knots[i]
    inside = b[i] + t * (2.0 * c[i] + 3.0 * t * d[i])
    return np.where(q < knots[0], b[0], np.where(q > knots[-1], b[-1], inside))
