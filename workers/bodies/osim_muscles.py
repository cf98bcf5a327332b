"""OpenSim muscles, their path points and wrap objects as the neutral body's (see
:mod:`workers.bodies.osim_import` for the rules)."""

from __future__ import annotations

from typing import Any

import numpy as np
from gaitforge.workers.bodies.functions import Linear, Spline, evaluate
from gaitforge.workers.bodies.osim_basics import (
    ImportContext,
    UnsupportedPart,
    as_tuple,
    coordinate_of,
    frame_in_base,
    items,
    read_function,
    resolve_coupling,
    vec3_array,
)
from gaitforge.workers.bodies.osim_stand_ins import (
    fit_stand_ins,
    spanned_coordinates,
    sweep_values,
)
from gaitforge.workers.bodies.rotations import euler_xyz, rotation_xyz
from gaitforge.workers.bodies.schema import (
    ActiveRange,
    MovingLocation,
    Muscle,
    PathPoint,
    WrapObject,
    WrapRef,
)

# ---- muscles ---------------------------------------------------------------------------


def _path_point(point: Any, ctx: ImportContext) -> PathPoint:
    import opensim

    where = point.getAbsolutePathString()
    kind = point.getConcreteClassName()
    if kind == "MovingPathPoint":
        return _moving_point(opensim.MovingPathPoint.safeDownCast(point), ctx)
    segment, location = ctx.in_segment(
        point.getParentFrame(), vec3_array(opensim.PathPoint.safeDownCast(point).get_location())
    )
    if kind == "PathPoint":
        return PathPoint(segment=segment, location=as_tuple(location))
    if kind != "ConditionalPathPoint":
        raise UnsupportedPart(f"{where}: path point type {kind} is not supported")
    cp = opensim.ConditionalPathPoint.safeDownCast(point)
    coordinate = coordinate_of(cp.getSocket("coordinate").getConnecteePath())
    lo, hi = cp.get_range(0), cp.get_range(1)
    if coordinate in ctx.coords.couplers:
        independent, fn = ctx.coords.couplers[coordinate]
        if not isinstance(fn, Linear) or fn.slope == 0:
            raise UnsupportedPart(f"{where}: conditional on a nonlinearly coupled coordinate")
        lo, hi = sorted(((lo - fn.intercept) / fn.slope, (hi - fn.intercept) / fn.slope))
        coordinate = independent
    return PathPoint(
        segment=segment,
        location=as_tuple(location),
        active_when=ActiveRange(coordinate=coordinate, range=(lo, hi)),
    )


def _moving_point(point: Any, ctx: ImportContext) -> PathPoint:
    where = point.getAbsolutePathString()
    sockets = ("x_coordinate", "y_coordinate", "z_coordinate")
    coordinates = [coordinate_of(point.getSocket(s).getConnecteePath()) for s in sockets]
    functions = [
        read_function(f, f"{where}/{n}", ctx.report)
        for f, n in (
            (point.get_x_location(), "x_location"),
            (point.get_y_location(), "y_location"),
            (point.get_z_location(), "z_location"),
        )
    ]
    if len(set(coordinates)) > 1:
        raise UnsupportedPart(f"{where}: moves with {len(set(coordinates))} coordinates")
    coordinate, resolved = coordinates[0], []
    for fn in functions:
        driver, composed = resolve_coupling(coordinates[0], fn, ctx.coords)
        coordinate = driver
        resolved.append(composed)
    base, offset = frame_in_base(point.getParentFrame())
    frame = ctx.frames[base]
    turn = frame.r.T @ offset.r
    if not np.allclose(turn, np.eye(3), atol=1e-9):
        raise UnsupportedPart(f"{where}: a moving point in a turned frame")
    shift = frame.point_in(offset.p)
    moved = [_shifted(fn, float(d)) for fn, d in zip(resolved, shift, strict=True)]
    info = ctx.coords.info[coordinate]
    span = ctx.coords.span(coordinate)
    default = min(max(info.getDefaultValue(), span[0]), span[1])
    location = np.array([float(evaluate(fn, default)) for fn in moved])
    return PathPoint(
        segment=base,
        location=as_tuple(location),
        moves_with=MovingLocation(coordinate=coordinate, x=moved[0], y=moved[1], z=moved[2]),
    )


def _shifted(fn: Linear | Spline, by: float) -> Linear | Spline:
    if by == 0.0:
        return fn
    if isinstance(fn, Linear):
        return Linear(slope=fn.slope, intercept=fn.intercept + by)
    return Spline(x=fn.x, y=[y + by for y in fn.y])


def _hill_parameters(muscle: Any, ctx: ImportContext) -> dict[str, float]:
    import opensim

    kind = muscle.getConcreteClassName()
    params: dict[str, float] = {
        "max_isometric_force": muscle.get_max_isometric_force(),
        "optimal_fiber_length": muscle.get_optimal_fiber_length(),
        "tendon_slack_length": muscle.get_tendon_slack_length(),
        "pennation_angle": muscle.get_pennation_angle_at_optimal(),
        "max_contraction_velocity": muscle.get_max_contraction_velocity(),
    }
    if kind == "Thelen2003Muscle":
        m = opensim.Thelen2003Muscle.safeDownCast(muscle)
        params |= {
            "passive_fibre_strain": m.get_FmaxMuscleStrain(),
            "passive_shape": m.get_KshapePassive(),
            "tendon_strain_at_fmax": m.get_FmaxTendonStrain(),
            "activation_time": m.get_activation_time_constant(),
            "deactivation_time": m.get_deactivation_time_constant(),
        }
    elif kind == "Millard2012EquilibriumMuscle":
        m = opensim.Millard2012EquilibriumMuscle.safeDownCast(muscle)
        params |= {
            "passive_fibre_strain": m.getFiberForceLengthCurve().get_strain_at_one_norm_force(),
            "tendon_strain_at_fmax": m.getTendonForceLengthCurve().get_strain_at_one_norm_force(),
            "activation_time": m.get_activation_time_constant(),
            "deactivation_time": m.get_deactivation_time_constant(),
        }
    else:
        ctx.report.approximated.append(
            f"{muscle.getAbsolutePathString()}: {kind} imported by its Hill parameters only "
            "(curves and time constants are the body defaults)"
        )
    return params


def _muscle(muscle: Any, wraps: dict[str, WrapObject], ctx: ImportContext) -> Muscle:
    where = muscle.getAbsolutePathString()
    geometry = muscle.getGeometryPath()
    point_set = geometry.getPathPointSet()
    points = [_path_point(p, ctx) for p in items(point_set)]
    gaps: dict[int, str] = {}
    wrap_set = geometry.getWrapSet()
    if wrap_set.getSize() == 0:
        points = fit_stand_ins(muscle, points, ctx)
    wrapped = _where_opensim_wraps(muscle, points, ctx) if wrap_set.getSize() else {}
    for path_wrap in items(wrap_set):
        name = path_wrap.get_wrap_object()
        if name not in wraps:
            ctx.report.dropped.append(f"{where}: wraps over {name!r}, which was not imported")
            continue
        gap = _wrap_gap(
            muscle, path_wrap, wraps[name], ctx, taken=set(gaps), wrapped=wrapped.get(name, {})
        )
        if gap is None:
            ctx.report.dropped.append(
                f"{where}: wrap {name!r} (no free path segment within its range: a backend "
                "needs a point between two wraps)"
            )
            continue
        gaps[gap] = name
    path: list[PathPoint | WrapRef] = []
    for i, point in enumerate(points):
        path.append(point)
        if i in gaps:
            path.append(WrapRef(wrap=gaps[i]))
    return Muscle(name=muscle.getName(), path=path, **_hill_parameters(muscle, ctx))


def _where_opensim_wraps(
    muscle: Any, points: list[PathPoint], ctx: ImportContext
) -> dict[str, dict[int, int]]:
    """Per wrap object (OpenSim's name): on how many poses OpenSim wraps the muscle's path
    over it on each path segment (index of the segment's first point), each rotational
    coordinate the muscle spans swept over its range, the others at their defaults."""
    import opensim

    geometry = muscle.getGeometryPath()
    point_set = geometry.getPathPointSet()
    index = {point_set.get(i).getName(): i for i in range(point_set.getSize())}
    counts: dict[str, dict[int, int]] = {}
    for coordinate in spanned_coordinates(points, ctx):
        for _ in ctx.posed(coordinate, sweep_values(ctx, coordinate)):
            current = geometry.getCurrentPath(ctx.state)
            gap = -1
            for k in range(current.getSize()):
                point = current.get(k)
                wrap_point = opensim.PathWrapPoint.safeDownCast(point)
                if wrap_point is None:
                    gap = index.get(point.getName(), gap)
                elif gap >= 0:
                    per_gap = counts.setdefault(wrap_point.getWrapObject().getName(), {})
                    per_gap[gap] = per_gap.get(gap, 0) + 1
    return counts


def _wrap_gap(
    muscle: Any,
    path_wrap: Any,
    wrap: WrapObject,
    ctx: ImportContext,
    taken: set[int],
    wrapped: dict[int, int],
) -> int | None:
    """The path segment (index of its first point) a wrap acts on, within OpenSim's range
    and free: the one OpenSim wraps over it on most of the muscle's swept poses (``wrapped``:
    segment -> poses), or, where it never does, the one passing closest to the wrap's centre
    in the default pose."""
    point_set = muscle.getGeometryPath().getPathPointSet()
    n = point_set.getSize()
    first, last = path_wrap.get_range(0), path_wrap.get_range(1)
    first = 1 if first < 1 else first
    last = n if last < 1 or last > n else last
    free = [gap for gap in range(first - 1, last - 1) if gap not in taken]
    seen = [gap for gap in free if wrapped.get(gap, 0) > 0]
    if seen:
        return max(seen, key=lambda gap: wrapped[gap])
    ground = [vec3_array(point_set.get(i).getLocationInGround(ctx.state)) for i in range(n)]
    segment_frame = ctx.frames[wrap.segment]
    body = ctx.model.getBodySet().get(wrap.segment)
    centre_in_body = segment_frame.p + segment_frame.r @ np.asarray(wrap.location)
    centre = vec3_array(body.findStationLocationInGround(ctx.state, opensim_vec3(centre_in_body)))
    best: tuple[float, int] | None = None
    for gap in free:
        a, b = ground[gap], ground[gap + 1]
        t = float(np.clip(np.dot(centre - a, b - a) / max(np.dot(b - a, b - a), 1e-12), 0, 1))
        distance = float(np.linalg.norm(a + t * (b - a) - centre))
        if best is None or distance < best[0]:
            best = (distance, gap)
    return None if best is None else best[1]


def opensim_vec3(v: np.ndarray) -> Any:
    import opensim

    return opensim.Vec3(float(v[0]), float(v[1]), float(v[2]))


def read_wrap(
    obj: Any, segment: str, ctx: ImportContext, used_names: set[str]
) -> WrapObject | None:
    import opensim

    where = obj.getAbsolutePathString()
    kind = obj.getConcreteClassName()
    if not obj.get_active():
        ctx.report.dropped.append(f"{where}: inactive wrap object")
        return None
    frame = ctx.frames[segment]
    location = frame.point_in(vec3_array(obj.get_translation()))
    r = frame.rotation_in(rotation_xyz(vec3_array(obj.get_xyz_body_rotation())))
    name = obj.getName() if obj.getName() not in used_names else f"{segment}_{obj.getName()}"
    used_names.add(name)
    extra: dict[str, Any] = {}
    if kind == "WrapCylinder":
        c = opensim.WrapCylinder.safeDownCast(obj)
        radii = np.array([c.get_radius(), c.get_radius(), c.get_length() / 2])
        extra = {"type": "cylinder", "radius": c.get_radius(), "length": c.get_length()}
    elif kind == "WrapSphere":
        radius = opensim.WrapSphere.safeDownCast(obj).get_radius()
        radii = np.full(3, radius)
        extra = {"type": "sphere", "radius": radius}
    elif kind == "WrapEllipsoid":
        radii = vec3_array(opensim.WrapEllipsoid.safeDownCast(obj).get_dimensions())
        extra = {"type": "ellipsoid", "radius": float(radii.mean()), "radii": as_tuple(radii)}
        ctx.report.notes.append(
            f"{where}: ellipsoid wrap; MuJoCo has none and uses a sphere of the mean radius "
            f"{radii.mean():.4f} m"
        )
    else:
        ctx.report.dropped.append(f"{where}: wrap type {kind} is not supported")
        return None
    quadrant = obj.get_quadrant().strip().lower()
    side = None
    if quadrant not in {"", "all"}:
        k = "xyz".index(quadrant[-1])
        sign = -1.0 if quadrant.startswith("-") else 1.0
        side = as_tuple(location + r[:, k] * sign * 2.0 * radii[k])
    return WrapObject(
        name=name,
        segment=segment,
        location=as_tuple(location),
        axis=as_tuple(r[:, 2]),
        orientation=as_tuple(np.asarray(euler_xyz(r))),
        side=side,
        **extra,
    )


def read_muscles(ctx: ImportContext, wraps: dict[str, WrapObject]) -> list[Muscle]:
    import opensim

    muscles = []
    force_set = ctx.model.getForceSet()
    for force in items(force_set):
        where = force.getAbsolutePathString()
        muscle = opensim.Muscle.safeDownCast(force)
        if opensim.CoordinateLimitForce.safeDownCast(force) is not None:
            continue  # the dof's limit (osim_joints.read_limit_forces)
        if muscle is None:
            ctx.report.dropped.append(
                f"{where}: {force.getConcreteClassName()} (only muscles are imported)"
            )
            continue
        if not force.get_appliesForce():
            ctx.report.dropped.append(f"{where}: a disabled muscle")
            continue
        if opensim.GeometryPath.safeDownCast(muscle.getPath()) is None:
            kind = muscle.getPath().getConcreteClassName()
            ctx.report.dropped.append(f"{where}: a muscle on a {kind} (only geometry paths)")
            continue
        muscles.append(_muscle(muscle, wraps, ctx))
    millard = sum(
        1 for f in items(force_set) if f.getConcreteClassName() == "Millard2012EquilibriumMuscle"
    )
    if millard:
        ctx.report.approximated.append(
            f"{millard} Millard 2012 muscles: their passive fibre "
            "curve is kept by its strain at one norm force, with Thelen 2003's shape (4)"
        )
    return muscles
