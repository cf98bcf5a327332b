"""A moving path point's carrier for MuJoCo: the quartics its slides follow, fitted on the
OpenSim model being imported to keep the muscle's moment arm.

MuJoCo has no moving sites; its builder can carry one on a light body whose slides are held
to polynomials of the point's coordinate (``StandIn.follow``,
``workers.sim.mujoco.couplings.add_carrier``). MuJoCo's joint equality is a quartic, and a
least-squares quartic through OpenSim's splines misses their slope near the range's ends
(gait10dof18musc's patellar-tendon insertion: 1.4 mm of place, but the vasti's knee moment arm
4.4 mm RMS and 22 mm worst against OpenSim's). The moment arm is what the conversion is
judged on, and only the part of the point's velocity along the path moves it: a change
``dp`` of the point's place changes the muscle's length by ``g . dp``, with ``g`` the sum of
the unit vectors from its neighbours on OpenSim's current path to the point. So the fit is
the linear least squares of ``g(q) . (P'(q) - p'(q))`` (the moment-arm error, m) together
with ``PLACE_WEIGHT`` times ``P(q) - p(q)`` (the place, m), ``P`` the quartics and ``p``
OpenSim's functions, over the coordinate's range: the vasti's moment arm then stays within
1.5 mm RMS, its place within 3.5 mm.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gaitforge.workers.bodies.functions import derivative, evaluate
from gaitforge.workers.bodies.osim_basics import ImportContext, vec3_array
from gaitforge.workers.bodies.schema import PathPoint, StandIn

FIT_POSES = 101
"""Poses of the point's coordinate over its range where the quartics are fitted."""
PLACE_WEIGHT = 1.0
"""Weight (1/rad) of the place error against the moment-arm error in the fit: lower keeps the
moment arm closer and lets the place drift (0.1: 1.2 mm RMS moment arm, 4 mm place on the
vasti; 0.01: 1.0 mm and 16 mm)."""
DEGREE = 4
"""MuJoCo's joint equality is a polynomial of degree 4."""
CONSTANT_SPAN = 1e-9
"""m: a coordinate of the point that moves less than this over the range has no slide."""


def fit_carrier(muscle: Any, index: int, point: PathPoint, ctx: ImportContext) -> StandIn:
    """The carrier for ``muscle``'s moving point ``index`` (``point``, OpenSim's path point
    at that index of its path point set): ``StandIn.follow`` holds the point's place in its
    segment as three quartics of its coordinate's value (a0..a4, lowest order first)."""
    moving = point.moves_with
    assert moving is not None
    functions = (moving.x, moving.y, moving.z)
    values = np.linspace(*ctx.coords.span(moving.coordinate), FIT_POSES)
    place = np.stack([evaluate(f, values) for f in functions], axis=1)  # [poses, 3] m
    velocity = np.stack([derivative(f, values) for f in functions], axis=1)  # m/rad
    gradient = _length_gradient(muscle, index, point, values, ctx)  # [poses, 3]
    varying = [k for k in range(3) if np.ptp(place[:, k]) > CONSTANT_SPAN]
    if not varying:  # a moving point that does not move
        return StandIn(follow=tuple(_constant(place[0, k]) for k in range(3)))
    powers = np.vander(values, DEGREE + 1, increasing=True)  # [poses, 5]
    slopes = np.zeros_like(powers)
    slopes[:, 1:] = powers[:, :-1] * np.arange(1, DEGREE + 1)
    rows = [np.hstack([gradient[:, [k]] * slopes for k in varying])]
    targets = [np.sum(gradient[:, varying] * velocity[:, varying], axis=1)]
    for j, k in enumerate(varying):
        block = np.zeros((len(values), (DEGREE + 1) * len(varying)))
        block[:, j * (DEGREE + 1) : (j + 1) * (DEGREE + 1)] = PLACE_WEIGHT * powers
        rows.append(block)
        targets.append(PLACE_WEIGHT * place[:, k])
    solution = np.linalg.lstsq(np.vstack(rows), np.concatenate(targets), rcond=None)[0]
    quartics = []
    for k in range(3):
        if k in varying:
            j = varying.index(k)
            coefficients = solution[j * (DEGREE + 1) : (j + 1) * (DEGREE + 1)]
            quartics.append(tuple(float(c) for c in coefficients))
        else:
            quartics.append(_constant(place[0, k]))
    return StandIn(follow=tuple(quartics))


def _constant(value: float) -> tuple[float, ...]:
    return (float(value),) + (0.0,) * DEGREE


def _length_gradient(
    muscle: Any, index: int, point: PathPoint, values: np.ndarray, ctx: ImportContext
) -> np.ndarray:
    """``dL/dp`` of the muscle's length ``L`` by the place ``p`` of its point ``index``, in
    the point's segment frame, at each of ``values`` of the point's coordinate: the sum of
    the unit vectors from the point's neighbours on OpenSim's current path (unitless,
    shape ``[poses, 3]``)."""
    import opensim

    opensim_point = muscle.getGeometryPath().getPathPointSet().get(index)
    name = opensim_point.getName()
    model, state = ctx.model, ctx.state
    host = model.getBodySet().get(point.segment)
    segment = ctx.frames[point.segment]
    gradient = np.zeros((len(values), 3))
    for k, _ in enumerate(ctx.posed(point.moves_with.coordinate, values)):  # type: ignore[union-attr]
        path = muscle.getGeometryPath().getCurrentPath(state)
        places = [vec3_array(path.get(i).getLocationInGround(state)) for i in range(path.getSize())]
        names = [path.get(i).getName() for i in range(path.getSize())]
        if name not in names:
            continue
        i = names.index(name)
        total = np.zeros(3)
        for j in (i - 1, i + 1):
            if 0 <= j < len(places):
                span = places[i] - places[j]
                total += span / max(np.linalg.norm(span), 1e-9)
        in_body = model.getGround().expressVectorInAnotherFrame(state, opensim.Vec3(*total), host)
        gradient[k] = segment.r.T @ vec3_array(in_body)
    return gradient
