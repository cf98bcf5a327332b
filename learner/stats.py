"""Confidence intervals for evaluation results: a mean with Student's t interval and a
proportion with Wilson's score interval, both at 95 %."""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence
from dataclasses import dataclass

CONFIDENCE = 0.95

# two-sided 95 % quantiles of Student's t, df = 1..30
_T975 = (12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179,
         2.160, 2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064,
         2.060, 2.056, 2.052, 2.048, 2.045, 2.042)  # fmt: skip


def t_quantile_975(df: int) -> float:
    """The 97.5 % quantile of Student's t with ``df`` degrees of freedom (table to 30, then
    the Cornish-Fisher expansion, within 1e-3 of the exact value)."""
    if df < 1:
        raise ValueError("df must be >= 1")
    if df <= len(_T975):
        return _T975[df - 1]
    z = statistics.NormalDist().inv_cdf(0.975)
    return z + (z**3 + z) / (4 * df) + (5 * z**5 + 16 * z**3 + 3 * z) / (96 * df**2)


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
        half = t_quantile_975(n - 1) * std / math.sqrt(n)
        return cls(mean, mean - half, mean + half, std, n)


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
        p = count / n
        z = statistics.NormalDist().inv_cdf(0.5 + CONFIDENCE / 2)
        denom = 1 + z**2 / n
        centre = (p + z**2 / (2 * n)) / denom
        half = z * math.sqrt(p * (1 - p) / n + z**2 / (4 * n**2)) / denom
        low = 0.0 if count == 0 else max(0.0, centre - half)
        high = 1.0 if count == n else min(1.0, centre + half)
        return cls(p, low, high, count, n)
