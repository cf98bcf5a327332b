"""The muscle-geometry measure of a conversion: each muscle swept over every rotational free
coordinate it spans, path length and moment arm on both sides (the pairs' pass criteria are
``conversion_report.PairResult``'s); also how ``wrap_sides`` and ``conditional_wraps`` compare
a body's variants.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from gaitforge.workers.fidelity.conversion_report import PairResult
from gaitforge.workers.fidelity.conversion_sides import MujocoSide, OpenSimSide

DEFAULT_SWEEP_POINTS = 25
"""coordinate values of each muscle-coordinate sweep"""


@dataclass
class CoordinateSweep:
    """One coordinate swept over its range, the others at their defaults: ``q`` [points]
    (rad), OpenSim's path lengths and moment arms (m) [muscles, points] and MuJoCo's of the
    tendons swept [tendons, points] (NaN where a tendon is missing or MuJoCo lacks the
    coordinate)."""

    q: np.ndarray
    length_osim: np.ndarray
    arm_osim: np.ndarray
    length_mujoco: np.ndarray
    arm_mujoco: np.ndarray


def sweep_coordinate(
    osim: OpenSimSide,
    mj: MujocoSide,
    coordinate: str,
    muscles: list[str],
    rows: list[int | None],
    points: int,
) -> CoordinateSweep:
    """OpenSim's ``muscles`` and MuJoCo's tendon ``rows`` (None: no tendon) over ``points``
    values of rotational ``coordinate`` across its range."""
    q = np.linspace(*osim.ranges()[coordinate], points)
    defaults = osim.defaults()
    length_os, arm_os = np.zeros((len(muscles), points)), np.zeros((len(muscles), points))
    length_mj = np.full((len(rows), points), math.nan)
    arm_mj = np.full((len(rows), points), math.nan)
    for k, value in enumerate(q):
        pose = {**defaults, coordinate: float(value)}
        osim.set_pose(pose)
        for i, muscle in enumerate(muscles):
            path = osim.muscles[muscle]
            length_os[i, k] = path.getLength(osim.state)
            arm_os[i, k] = path.computeMomentArm(osim.state, osim.coordinates[coordinate])
        if coordinate not in mj.joints:
            continue
        mj.set_pose(pose)
        lengths, arms = mj.lengths(), mj.moment_arms(coordinate)
        for i, row in enumerate(rows):
            if row is not None:
                length_mj[i, k], arm_mj[i, k] = lengths[row], arms[row]
    return CoordinateSweep(q, length_os, arm_os, length_mj, arm_mj)


def sweep_pairs(
    osim: OpenSimSide,
    mj: MujocoSide,
    points: int,
    notes: list[str],
    only: list[str] | None = None,
) -> list[PairResult]:
    """Every muscle (or those in ``only``) over every rotational free coordinate it spans
    (OpenSim's topology)."""
    spans = osim.spanned()
    if only is not None:
        spans = {m: c for m, c in spans.items() if m in only}
    slides = sorted({c for cs in spans.values() for c in cs if not osim.rotational(c)})
    if slides:
        notes.append(f"translational coordinates not swept: {', '.join(slides)}")
    absent = [m for m in spans if m not in mj.tendons]
    if absent:
        notes.append(f"muscles without a MuJoCo tendon (their pairs fail): {', '.join(absent)}")
    by_coordinate: dict[str, list[str]] = {}
    for muscle, coordinates in spans.items():
        for c in coordinates:
            if osim.rotational(c):
                by_coordinate.setdefault(c, []).append(muscle)
    pairs: list[PairResult] = []
    for coordinate, muscles in by_coordinate.items():
        rows = [mj.tendons.get(m) for m in muscles]
        sweep = sweep_coordinate(osim, mj, coordinate, muscles, rows, points)
        pairs += [
            PairResult(
                muscle,
                coordinate,
                sweep.q,
                sweep.length_osim[i],
                sweep.length_mujoco[i],
                sweep.arm_osim[i],
                sweep.arm_mujoco[i],
            )
            for i, muscle in enumerate(muscles)
        ]
    muscle_order = {name: i for i, name in enumerate(osim.muscles)}
    coordinate_order = {name: i for i, name in enumerate(osim.coordinates)}
    pairs.sort(key=lambda p: (muscle_order[p.muscle], coordinate_order[p.coordinate]))
    return pairs
