"""Fixed stand-ins for a muscle's conditional and moving path points, for backends that have
neither (MuJoCo), fitted on the OpenSim model being imported.

Each rotational coordinate the muscle spans is swept over its range (the others at their
defaults) and OpenSim's own muscle-tendon length is the reference. The candidates are, for
a conditional point, kept or dropped; for a moving point, followed along its path by a
carrier (``StandIn.follow``, whose quartics ``osim_carriers`` fits once it is chosen), or
fixed where the point is at one of the sweep's poses, either on its own segment or on the
parent of the joint its coordinate turns (a patella-like point rides with the femur). A
candidate path's length is the sum of its straight pieces; the choice minimises the RMS
error of the moment arm (``-dL/dq``) over what the conversion allows, summed over the
sweeps, then of the length, by coordinate descent over the muscle's special points (two
passes). A muscle with wrap objects keeps the default rule (a straight-piece length would
not be its length).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from gaitforge.workers.bodies.osim_basics import (
    ARM_TOLERANCE_M,
    ImportContext,
    arm_allowance,
    as_tuple,
    joints_between,
    vec3_array,
)
from gaitforge.workers.bodies.osim_carriers import fit_carrier
from gaitforge.workers.bodies.schema import GROUND, PathPoint, StandIn

SWEEP_POINTS = 21
"""poses per coordinate sweep (and candidate poses of a moving point)"""


@dataclass
class _Candidate:
    """One way to stand in for a point: ``ground[k]`` its position at sweep pose ``k`` (None:
    the point is left out), and the stand-in it would be (None: a moving point followed by
    a carrier, whose quartics are fitted once it is chosen)."""

    ground: np.ndarray | None  # [poses, 3] m
    stand_in: StandIn | None


def fit_stand_ins(muscle: Any, points: list[PathPoint], ctx: ImportContext) -> list[PathPoint]:
    """``points`` with a fitted ``stand_in`` on each conditional or moving point (the OpenSim
    ``muscle`` has no wraps; see the module)."""
    special = [i for i, p in enumerate(points) if p.active_when or p.moves_with]
    if not special:
        return points
    spanned = spanned_coordinates(points, ctx)
    if not spanned:
        return points
    sweeps = [_Sweep(muscle, points, coordinate, ctx) for coordinate in spanned]
    choice = {i: 0 for i in special}  # index into each point's candidates, summed over sweeps
    for _ in range(2):
        for i in special:
            scores = [
                sum(s.error({**choice, i: c}) for s in sweeps)
                for c in range(len(sweeps[0].candidates[i]))
            ]
            choice[i] = int(np.argmin(scores))
    fitted = list(points)
    for i in special:
        stand_in = sweeps[0].candidates[i][choice[i]].stand_in
        if stand_in is None:
            stand_in = fit_carrier(muscle, i, points[i], ctx)
        fitted[i] = points[i].model_copy(update={"stand_in": stand_in})
    return fitted


def spanned_coordinates(points: list[PathPoint], ctx: ImportContext) -> list[str]:
    """The free rotational coordinates of the joints between the segments the points sit on."""
    free = set(ctx.coords.info) - set(ctx.coords.couplers)
    return [
        name
        for joint in joints_between(ctx.model, {p.segment for p in points})
        for name in (joint.get_coordinates(k).getName() for k in range(joint.numCoordinates()))
        if name in free and ctx.coords.info[name].getMotionType() != 2  # 2: translational
    ]


class _Sweep:
    """One coordinate swept: OpenSim's length, every point's positions, and each special
    point's candidates (the same candidates, in the same order, in every sweep)."""

    def __init__(self, muscle: Any, points: list[PathPoint], coordinate: str, ctx: ImportContext):
        state = ctx.state
        point_set = muscle.getGeometryPath().getPathPointSet()
        values = sweep_values(ctx, coordinate)
        self.step = float(values[1] - values[0])
        n = len(points)
        special = [i for i, p in enumerate(points) if p.active_when or p.moves_with]
        hosts = {i: _moving_places(points[i], point_set.get(i), ctx) for i in special}
        self.fixed = np.zeros((SWEEP_POINTS, n, 3))
        self.length = np.zeros(SWEEP_POINTS)
        hosted = {i: np.zeros((len(hosts[i]), SWEEP_POINTS, 3)) for i in special}
        for k, _value in enumerate(ctx.posed(coordinate, values)):
            self.length[k] = muscle.getLength(state)
            for i in range(n):
                self.fixed[k, i] = vec3_array(point_set.get(i).getLocationInGround(state))
            for i in special:
                for c, (host, local, _) in enumerate(hosts[i]):
                    hosted[i][c, k] = vec3_array(host.findStationLocationInGround(state, local))
        self.candidates = {
            i: _candidates(points[i], self.fixed[:, i], hosts[i], hosted[i], ctx) for i in special
        }
        self.reference_arm = -np.gradient(self.length, self.step)

    def error(self, choice: dict[int, int]) -> float:
        """RMS moment-arm error over what the conversion allows (2 mm or 5 % of the peak
        moment arm), plus a tenth of the RMS length error over 2 mm, of a choice."""
        pieces = []
        for i in range(self.fixed.shape[1]):
            if i in choice:
                ground = self.candidates[i][choice[i]].ground
                if ground is None:
                    continue
                pieces.append(ground)
            else:
                pieces.append(self.fixed[:, i])
        path = np.stack(pieces, axis=1)  # [poses, points, 3]
        length = np.linalg.norm(np.diff(path, axis=1), axis=2).sum(axis=1)
        arm = -np.gradient(length, self.step)
        arm_rms = float(np.sqrt(np.mean((arm - self.reference_arm) ** 2)))
        length_rms = float(np.sqrt(np.mean((length - self.length) ** 2)))
        return arm_rms / arm_allowance(self.reference_arm) + 0.1 * length_rms / ARM_TOLERANCE_M


def sweep_values(ctx: ImportContext, coordinate: str) -> np.ndarray:
    return np.linspace(*ctx.coords.span(coordinate), SWEEP_POINTS)


def _candidates(
    point: PathPoint,
    ground: np.ndarray,
    hosts: list[tuple[Any, Any, StandIn]],
    hosted: np.ndarray,
    ctx: ImportContext,
) -> list[_Candidate]:
    """A point's stand-ins, the first one tried first, with positions over a sweep: a
    conditional point kept (``ground``, its own positions) or dropped; a moving point
    followed (``ground``) or fixed at each of its ``hosts`` places (``hosted[c]``)."""
    if point.active_when is None:
        fixed = [_Candidate(hosted[c], stand_in) for c, (_, _, stand_in) in enumerate(hosts)]
        return [_Candidate(ground, None), *fixed] if point.segment != GROUND else fixed
    lo, hi = point.active_when.range
    default = ctx.coords.info[point.active_when.coordinate].getDefaultValue()
    keep, drop = _Candidate(ground, StandIn(keep=True)), _Candidate(None, StandIn(keep=False))
    return [keep, drop] if lo <= default <= hi else [drop, keep]


def _moving_places(
    point: PathPoint, opensim_point: Any, ctx: ImportContext
) -> list[tuple[Any, Any, StandIn]]:
    """Where a moving point may be fixed: where it is at each pose of its coordinate's sweep,
    on its own segment or on the parent of its coordinate's joint (the place nearest its
    default pose first). Each as (OpenSim body, location there, the stand-in)."""
    if point.moves_with is None:
        return []
    model, state = ctx.model, ctx.state
    coordinate = point.moves_with.coordinate
    info = ctx.coords.info[coordinate]
    default = info.getValue(state)
    parent = info.getJoint().getParentFrame().findBaseFrame().getName()
    names = [point.segment] + ([parent] if parent != point.segment and parent in ctx.frames else [])
    hosts = [model.getBodySet().get(n) for n in names if n != "ground"]
    values = sorted(sweep_values(ctx, coordinate), key=lambda v: abs(v - default))
    places = []
    for _ in ctx.posed(coordinate, values):
        where = opensim_point.getLocationInGround(state)
        for host in hosts:
            local = model.getGround().findStationLocationInAnotherFrame(state, where, host)
            location = ctx.frames[host.getName()].point_in(vec3_array(local))
            stand_in = StandIn(segment=host.getName(), location=as_tuple(location))
            places.append((host, local, stand_in))
    return places
