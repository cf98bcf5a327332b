"""``tests.tolerance``: floats within a tolerance, everything else exactly, and the first
difference named by its path."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import BaseModel

from tests.tolerance import assert_close, first_difference


class _Fit(BaseModel):
    name: str
    follow: tuple[tuple[float, ...], ...]


def test_last_digit_differences_pass_and_real_ones_are_named_by_path() -> None:
    here = _Fit(name="vasti", follow=((0.06171260522884271, 0.0),))
    there = _Fit(name="vasti", follow=((0.06171260522884277, 1e-17),))  # another BLAS
    assert here != there
    assert_close(here, there)
    moved = _Fit(name="vasti", follow=((0.0618, 0.0),))
    with pytest.raises(AssertionError, match=r"^follow\[0\]\[0\]: 0\.0618 != 0\.0617"):
        assert_close(moved, here)
    assert first_difference(here, here.model_copy(update={"name": "rf"})) == (
        "name: 'vasti' != 'rf'"
    )


def test_structures_must_match_exactly_and_arrays_by_element() -> None:
    assert (
        first_difference({"a": 1}, {"b": 1}) == "<root>: keys differ (extra ['a'], missing ['b'])"
    )
    assert first_difference([1.0], (1.0,)) == "<root>: list != tuple"
    assert first_difference({"n": 3}, {"n": 3.0}) is None  # as ==: 3 == 3.0
    assert first_difference(True, 1.0) is not None  # a flag is no number
    assert first_difference(math.nan, math.nan) is None
    assert first_difference(math.inf, -math.inf) is not None
    a = np.array([[1.0, 2.0], [3.0, np.inf]])
    assert first_difference(a, a * (1 + 1e-15)) is None
    found = first_difference(a, np.array([[1.0, 2.0], [3.1, np.inf]]))
    assert found is not None and found.startswith("<root>[1, 0]: ")
    assert first_difference(a, a[0]) == "<root>: shape (2, 2) != (2,)"
    assert first_difference(np.array([0.0]), [1e-13]) is None  # within the absolute tolerance
