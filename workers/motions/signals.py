"""Signal helpers for writing motion files: OpenSim tables, strides, periodic series."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np

SAMPLES = 60
"""Samples per cycle in the written files."""
HARMONICS = 15
"""Fourier harmonics kept per stride (gait kinematics hold >99.9 % of their power below 10)."""


def read_mot(path: Path) -> dict[str, np.ndarray]:
    """An OpenSim .mot/.sto table: column name -> values (as stored; degrees stay degrees)."""
    lines = path.read_text().splitlines()
    start = next(i for i, line in enumerate(lines) if line.strip().lower() == "endheader")
    names = lines[start + 1].split()
    body = [line for line in lines[start + 2 :] if line.strip()]
    rows = np.array([[float(v) for v in line.split()] for line in body])
    return {name: rows[:, i] for i, name in enumerate(names)}


def rising_edges(t: np.ndarray, flag: np.ndarray) -> list[float]:
    """Times where ``flag`` turns on (off before, on after)."""
    idx = np.flatnonzero(~flag[:-1] & flag[1:]) + 1
    return [float(t[i]) for i in idx]


def cycle(t: np.ndarray, x: np.ndarray, t0: float, t1: float, n: int = SAMPLES) -> np.ndarray:
    """``x(t)`` over one stride [t0, t1) as a closed periodic series [n] (see module doc)."""
    grid = t0 + (t1 - t0) * np.arange(n + 1) / n
    y = np.interp(grid, t, x)
    y = y[:-1] - (y[-1] - y[0]) * np.arange(n) / n
    spec = np.fft.rfft(y)
    spec[HARMONICS + 1 :] = 0
    return np.fft.irfft(spec, n)


def periodic_rate(x: np.ndarray, period: float) -> np.ndarray:
    """d/dt of a periodic series [n] by central differences."""
    dt = period / len(x)
    return (np.roll(x, -1) - np.roll(x, 1)) / (2 * dt)


def _runs(flag: np.ndarray) -> list[tuple[int, int, bool]]:
    """(start, stop, value) of each run of equal values."""
    edges = [0, *(np.flatnonzero(flag[1:] != flag[:-1]) + 1).tolist(), len(flag)]
    return [(a, b, bool(flag[a])) for a, b in itertools.pairwise(edges)]


def debounce(flag: np.ndarray, frames: int = 3) -> np.ndarray:
    """``flag`` with off-gaps and then on-runs shorter than ``frames`` inside it removed."""
    out = flag.copy()
    for value in (False, True):
        for a, b, v in _runs(out):
            if v == value and b - a < frames and a > 0 and b < len(out):
                out[a:b] = not value
    return out
