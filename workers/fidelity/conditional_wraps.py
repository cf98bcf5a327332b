"""Wrap cylinders in place of conditional path points, fitted against the OpenSim original.

A conditional via point usually stands for a muscle wrapping over bone: it joins the path
once the joint turns far enough that the straight line would cut through the bone. MuJoCo has
no conditional sites, but its tendons wrap cylinders only where the path would cross them,
which is the same behaviour by geometry. For each conditional point the fit tries cylinders
on the point's segment whose surface passes through the point (radii of
:data:`RADII_M`, centres in :data:`DIRECTIONS` directions about the axis of the joint the
point's coordinate turns, with and without a side site on the point's side) against the
stand-in the import chose. All candidates of all muscles are built into one MuJoCo model as
copies of their muscle's tendon (a tendon's length depends only on its own path), swept over
every rotational coordinate the muscle spans beside OpenSim's own muscle, and the candidate
with the fewest muscle-coordinate pairs beyond what the conversion allows, then the least
error, replaces the stand-in if it beats it.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from gaitforge.workers.bodies.osim_basics import arm_allowance
from gaitforge.workers.bodies.rotations import euler_xyz, rotation_xyz
from gaitforge.workers.bodies.schema import (
    Body,
    Muscle,
    PathElement,
    PathPoint,
    StandIn,
    WrapObject,
)
from gaitforge.workers.fidelity.conversion_sides import MujocoSide, OpenSimSide
from gaitforge.workers.fidelity.conversion_sweeps import DEFAULT_SWEEP_POINTS, sweep_coordinate
from gaitforge.workers.sim.mujoco.build import build_spec

logger = logging.getLogger(__name__)

RADII_M = (0.005, 0.01, 0.02, 0.04)
DIRECTIONS = 8
COPY = "~"
"""Separates a muscle's name from its candidate's number in the fitting model."""
FAILED_PAIR = 100.0
"""A pair beyond what is allowed costs as much as this many allowances of error: the fit
keeps pairs within bounds first, then lowers the error."""


@dataclass(frozen=True)
class _Candidate:
    muscle: str
    point: int  # index in the muscle's path
    wrap: WrapObject | None  # None: the stand-in the import chose


def _joint_axis(body: Body, coordinate: str, segment: str) -> np.ndarray:
    """The hinge axis of ``coordinate`` in ``segment``'s frame (segment is the joint's parent
    or child; other dofs of the joint taken at zero)."""
    joint = body.joint_of_dof(coordinate)
    axis = np.asarray(body.dof(coordinate).axis, dtype=float)
    if segment == joint.parent:
        axis = rotation_xyz(joint.orientation_in_parent) @ axis
    return axis / np.linalg.norm(axis)


def _cylinders(body: Body, muscle: Muscle, index: int) -> list[WrapObject]:
    point = muscle.path[index]
    assert isinstance(point, PathPoint) and point.active_when is not None
    axis = _joint_axis(body, point.active_when.coordinate, point.segment)
    helper = np.eye(3)[int(np.argmin(np.abs(axis)))]
    u = np.cross(axis, helper)
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    turn = np.column_stack([u, v, axis])  # the cylinder's frame: Z along the axis
    orientation = tuple(float(a) for a in euler_xyz(turn))
    at = np.asarray(point.location)
    wraps = []
    for radius in RADII_M:
        for k in range(DIRECTIONS):
            angle = 2 * math.pi * k / DIRECTIONS
            inward = math.cos(angle) * u + math.sin(angle) * v
            centre = at + radius * inward
            for side in (True, False):
                wraps.append(
                    WrapObject(
                        name=f"{muscle.name}_p{index}_wrap_{len(wraps)}",
                        segment=point.segment,
                        type="cylinder",
                        location=tuple(float(x) for x in centre),
                        axis=tuple(float(x) for x in axis),
                        orientation=orientation,
                        radius=radius,
                        length=0.05,
                        side=tuple(float(x) for x in at - radius * inward) if side else None,
                    )
                )
    return wraps


def _replaceable(muscle: Muscle, index: int) -> bool:
    """A conditional point a wrap can replace: the nearest points MuJoCo keeps on each side,
    past conditional points it drops (vastus medialis' two over the femoral condyle), are
    sites."""
    path = muscle.path
    for step in (-1, 1):
        j = index + step
        while 0 <= j < len(path) and _dropped(path[j]):
            j += step
        if not 0 <= j < len(path):
            return False
        neighbour = path[j]
        if not isinstance(neighbour, PathPoint):
            return False
        if neighbour.active_when is not None and not (
            neighbour.stand_in is not None and neighbour.stand_in.keep
        ):
            return False
    return True


def _no_site_between(path: list[PathElement], i: int, j: int) -> bool:
    """Whether every point strictly between path elements ``i`` and ``j`` is dropped."""
    return all(_dropped(path[k]) for k in range(min(i, j) + 1, max(i, j)))


def _dropped(element: PathElement) -> bool:
    """A conditional point the import's stand-in leaves out of MuJoCo's path."""
    stand_in = isinstance(element, PathPoint) and element.stand_in
    return bool(stand_in) and not stand_in.keep and stand_in.wrap is None


def _with_wrap(muscle: Muscle, index: int, wrap: WrapObject, name: str) -> Muscle:
    point = muscle.path[index]
    assert isinstance(point, PathPoint)
    stand_in = StandIn(keep=False, wrap=wrap.name)
    path = list(muscle.path)
    path[index] = point.model_copy(update={"stand_in": stand_in})
    return muscle.model_copy(update={"name": name, "path": path})


def fit_conditional_wraps(
    osim_path: Path, body: Body, sweep_points: int = DEFAULT_SWEEP_POINTS
) -> tuple[Body, list[str]]:
    """``body`` with each conditional point whose muscle MuJoCo follows better over a fitted
    wrap cylinder given that cylinder as its stand-in; one line per point so replaced."""
    candidates: list[_Candidate] = []
    copies: list[Muscle] = []
    wraps: list[WrapObject] = []
    for muscle in body.muscles:
        for index, element in enumerate(muscle.path):
            if not isinstance(element, PathPoint) or element.active_when is None:
                continue
            if not _replaceable(muscle, index):
                continue
            candidates.append(_Candidate(muscle.name, index, None))
            copies.append(muscle.model_copy(update={"name": f"{muscle.name}{COPY}{len(copies)}"}))
            for wrap in _cylinders(body, muscle, index):
                candidates.append(_Candidate(muscle.name, index, wrap))
                copies.append(_with_wrap(muscle, index, wrap, f"{muscle.name}{COPY}{len(copies)}"))
                wraps.append(wrap)
    if not candidates:
        return body, []
    trial = body.model_copy(
        update={"muscles": copies, "wrap_objects": [*body.wrap_objects, *wraps]}
    )
    scores = _scores(Path(osim_path), trial, [c.muscle for c in candidates], sweep_points)
    best: dict[tuple[str, int], tuple[float, _Candidate]] = {}
    for candidate, score in zip(candidates, scores, strict=True):
        key = (candidate.muscle, candidate.point)
        if key not in best or score < best[key][0] - 1e-9:
            best[key] = (score, candidate)
    baseline = {
        (c.muscle, c.point): s for c, s in zip(candidates, scores, strict=True) if c.wrap is None
    }
    paths = {m.name: m.path for m in body.muscles}
    chosen: dict[tuple[str, int], _Candidate] = {}
    for key, (_, candidate) in sorted(best.items(), key=lambda item: item[1][0]):
        name, index = key
        if candidate.wrap is not None and not any(
            other == name and _no_site_between(paths[name], index, j) for other, j in chosen
        ):  # MuJoCo needs a site between two wraps: the better of the two keeps its wrap
            chosen[key] = candidate
    muscles = []
    added: list[WrapObject] = []
    notes = []
    for muscle in body.muscles:
        for (name, index), candidate in sorted(chosen.items()):
            if name != muscle.name:
                continue
            assert candidate.wrap is not None
            wrap = candidate.wrap.model_copy(update={"name": f"{name}_p{index}_wrap"})
            muscle = _with_wrap(muscle, index, wrap, name)
            added.append(wrap)
            notes.append(
                f"muscle {name}: conditional point {index} as a wrap cylinder of radius "
                f"{wrap.radius * 1000:.0f} mm on MuJoCo (pairs beyond bounds, plus error: "
                f"{baseline[(name, index)]:.2f} -> {best[(name, index)][0]:.2f})"
            )
        muscles.append(muscle)
    logger.info("%s: %d conditional points as wrap cylinders", body.name, len(added))
    fitted = body.model_copy(
        update={"muscles": muscles, "wrap_objects": [*body.wrap_objects, *added]}
    )
    return Body.model_validate(fitted.model_dump()), notes


def _scores(osim_path: Path, trial: Body, originals: list[str], points: int) -> list[float]:
    """Per copy in ``trial.muscles`` (copy of ``originals[i]``): over the original's
    rotational coordinates, the pairs beyond what is allowed plus the sum of the moment arm's
    RMS error over what is allowed, divided by :data:`FAILED_PAIR`."""
    osim = OpenSimSide(osim_path)
    mj = MujocoSide(build_spec(trial).compile())
    spans = osim.spanned()
    rows = [mj.tendons[m.name] for m in trial.muscles]
    scores = np.zeros(len(rows))
    for coordinate in sorted({c for o in set(originals) for c in spans.get(o, [])}):
        if not osim.rotational(coordinate) or coordinate not in mj.joints:
            continue
        users = [i for i, o in enumerate(originals) if coordinate in spans.get(o, [])]
        names = sorted({originals[i] for i in users})
        sweep = sweep_coordinate(osim, mj, coordinate, names, [rows[i] for i in users], points)
        for j, i in enumerate(users):
            reference = sweep.arm_osim[names.index(originals[i])]
            error = float(np.sqrt(np.mean((sweep.arm_mujoco[j] - reference) ** 2)))
            error /= arm_allowance(reference)
            scores[i] += error / FAILED_PAIR + (error > 1.0)
    return scores.tolist()
