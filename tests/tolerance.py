"""Comparing computed results across machines.

Machines differ in floating-point detail (the BLAS and LAPACK numpy was built with, libm,
SIMD paths), so a float computed here can differ in its last digits from the same float
computed elsewhere, or from one written to a file elsewhere. :func:`assert_close` compares
two nested results (pydantic models, dicts, lists, tuples, numpy arrays, floats) exactly
for everything but floats, and floats within a tolerance, naming the first difference::

    from tests.tolerance import assert_close

    assert_close(load_body("gait2354"), import_osim(path).body)
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from pydantic import BaseModel

REL_TOL = 1e-9
"""Relative tolerance on a float. Least-squares fits and sums differ in their last digits
across BLAS builds (a relative 1e-15 or so: a fitted quartic coefficient 0.06171260522884271
on one machine, ...277 on another); 1e-9 leaves orders of magnitude of margin above that
and stays far below anything a model, a fit or a metric could notice."""

ABS_TOL = 1e-12
"""Absolute tolerance on a float, for values at or near zero where a relative tolerance
means nothing (a coefficient that is 0.0 on one machine can be 1e-17 on another)."""


def assert_close(
    actual: Any, expected: Any, *, rel_tol: float = REL_TOL, abs_tol: float = ABS_TOL
) -> None:
    """Assert ``actual`` equals ``expected``: floats within ``rel_tol`` or ``abs_tol`` (as
    :func:`math.isclose`; NaN matches NaN), everything else exactly; the message names the
    path of the first difference (``muscles[3].path[2].stand_in.follow[0][1]``)."""
    difference = first_difference(actual, expected, rel_tol=rel_tol, abs_tol=abs_tol)
    if difference is not None:
        raise AssertionError(difference)


def first_difference(
    actual: Any,
    expected: Any,
    *,
    rel_tol: float = REL_TOL,
    abs_tol: float = ABS_TOL,
    path: str = "",
) -> str | None:
    """The first difference between ``actual`` and ``expected`` as ``"<path>: <what>"``, or
    None where they match (see :func:`assert_close`)."""
    where = path or "<root>"
    if isinstance(actual, BaseModel) or isinstance(expected, BaseModel):
        if type(actual) is not type(expected):
            return f"{where}: {type(actual).__name__} != {type(expected).__name__}"
        return first_difference(
            actual.model_dump(), expected.model_dump(), rel_tol=rel_tol, abs_tol=abs_tol, path=path
        )
    if isinstance(actual, Mapping) and isinstance(expected, Mapping):
        if set(actual) != set(expected):
            extra = sorted(map(str, actual.keys() - expected.keys()))
            missing = sorted(map(str, expected.keys() - actual.keys()))
            return f"{where}: keys differ (extra {extra}, missing {missing})"
        for key in expected:
            if isinstance(key, str) and key.isidentifier():
                step = f"{path}.{key}" if path else key
            else:
                step = f"{path}[{key!r}]"
            found = first_difference(
                actual[key], expected[key], rel_tol=rel_tol, abs_tol=abs_tol, path=step
            )
            if found is not None:
                return found
        return None
    if isinstance(actual, np.ndarray) or isinstance(expected, np.ndarray):
        return _array_difference(np.asarray(actual), np.asarray(expected), rel_tol, abs_tol, where)
    if isinstance(actual, list | tuple) and isinstance(expected, list | tuple):
        if type(actual) is not type(expected):
            return f"{where}: {type(actual).__name__} != {type(expected).__name__}"
        if len(actual) != len(expected):
            return f"{where}: length {len(actual)} != {len(expected)}"
        for i, (a, e) in enumerate(zip(actual, expected, strict=True)):
            found = first_difference(a, e, rel_tol=rel_tol, abs_tol=abs_tol, path=f"{path}[{i}]")
            if found is not None:
                return found
        return None
    if _is_float(actual) or _is_float(expected):
        if (
            _is_number(actual)
            and _is_number(expected)
            and _floats_close(float(actual), float(expected), rel_tol, abs_tol)
        ):
            return None
        return f"{where}: {actual!r} != {expected!r} (rel_tol {rel_tol:g}, abs_tol {abs_tol:g})"
    if actual != expected:
        return f"{where}: {actual!r} != {expected!r}"
    return None


def _is_float(value: Any) -> bool:
    return isinstance(value, float | np.floating)


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(
        value, bool | np.bool_
    )


def _floats_close(a: float, b: float, rel_tol: float, abs_tol: float) -> bool:
    return (math.isnan(a) and math.isnan(b)) or math.isclose(a, b, rel_tol=rel_tol, abs_tol=abs_tol)


def _array_difference(
    actual: np.ndarray, expected: np.ndarray, rel_tol: float, abs_tol: float, where: str
) -> str | None:
    if actual.shape != expected.shape:
        return f"{where}: shape {actual.shape} != {expected.shape}"
    floats = np.issubdtype(actual.dtype, np.floating) or np.issubdtype(expected.dtype, np.floating)
    if floats:
        # math.isclose's symmetric rule, elementwise (np.isclose's is not symmetric)
        a, e = actual.astype(np.float64), expected.astype(np.float64)
        finite = np.isfinite(a) & np.isfinite(e)
        with np.errstate(invalid="ignore", over="ignore"):  # inf - inf, where not finite
            bound = np.maximum(rel_tol * np.maximum(np.abs(a), np.abs(e)), abs_tol)
            near = finite & (np.abs(a - e) <= bound)
        same = near | (a == e) | (np.isnan(a) & np.isnan(e))
    else:
        same = np.asarray(actual == expected)
    if same.all():
        return None
    index = tuple(int(i) for i in np.argwhere(~same)[0])
    at = f"{where}[{', '.join(map(str, index))}]" if index else where
    tolerance = f"rel_tol {rel_tol:g}, abs_tol {abs_tol:g}; " if floats else ""
    return (
        f"{at}: {actual[index]!r} != {expected[index]!r}"
        f" ({tolerance}{int((~same).sum())} of {same.size} differ)"
    )
