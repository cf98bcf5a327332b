"""Confidence intervals for evaluation results, from ``scipy.stats``: a mean with Student's t
interval and a proportion with Wilson's score interval, both at 95 %."""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence
from dataclasses import dataclass

from scipy import stats

CONFIDENCE = 0.95


@dataclass(frozen=True)
class Stat:
    """Mean of per-episode values with a 95 % confidence interval ``[low, high]`` (Student's
    t; a single episode gives ``low == high == mean``). Same unit as the values."""

    mean: float
    low: float
    high: float
    std: float
    n: int

    @classmethod
    def of(cls, values: Sequence[float]) -> Stat:
        n = len(values)
        if n == 0:
            return cls(math.nan, math.nan, math.nan, math.nan, 0)
        mean = statistics.fmean(values)
        if n == 1:
            return cls(mean, mean, mean, 0.0, 1)
        std = statistics.stdev(values)
        if std == 0.0:  # scipy gives NaN for a zero scale; the interval is the point
            return cls(mean, mean, mean, 0.0, n)
        low, high = stats.t.interval(CONFIDENCE, n - 1, loc=mean, scale=std / math.sqrt(n))
        return cls(mean, float(low), float(high), std, n)


@dataclass(frozen=True)
class Rate:
    """A proportion (0..1) of ``n`` episodes with its 95 % Wilson score interval."""

    value: float
    low: float
    high: float
    count: int
    n: int

    @classmethod
    def of(cls, count: int, n: int) -> Rate:
        if n == 0:
            return cls(math.nan, math.nan, math.nan, 0, 0)
        ci = stats.binomtest(count, n).proportion_ci(CONFIDENCE, method="wilson")
        low = 0.0 if count == 0 else float(ci.low)
        high = 1.0 if count == n else float(ci.high)
        return cls(count / n, low, high, count, n)
