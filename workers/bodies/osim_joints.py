"""OpenSim joints and bodies as the neutral body's joints and segments (see
:mod:`workers.bodies.osim_import` for the rules)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from gaitforge.workers.bodies.functions import Linear, Spline, evaluate
from gaitforge.workers.bodies.osim_basics import (
    Coordinates,
    Frame,
    ImportContext,
    ImportReport,
    UnsupportedPart,
    as_tuple,
    clean_float,
    frame_in_base,
    identity_sign,
    items,
    read_function,
    resolve_coupling,
    vec3_array,
)
from gaitforge.workers.bodies.rotations import axis_rotation, euler_xyz
from gaitforge.workers.bodies.schema import (
    GROUND,
    Coupling,
    Dof,
    Joint,
    JointLimit,
    Segment,
)

MIN_INERTIA = 1e-6
"""kg m^2: moments below this (OpenSim allows zero) are raised to it; the report says so."""

# ---- joints ----------------------------------------------------------------------------


@dataclass
class _Axis:
    """One motion of a joint in application order: along/about ``axis`` (joint frame) by
    ``function(coordinate)``, or by a constant when ``coordinate`` is None."""

    kind: str  # "slide" | "hinge"
    axis: np.ndarray
    coordinate: str | None
    function: Linear | Spline
    label: str


_FIXED_AXES: dict[str, list[tuple[str, tuple[float, float, float], int]]] = {
    # joint class -> (kind, axis, coordinate index) in the order they act
    "PinJoint": [("hinge", (0, 0, 1), 0)],
    "SliderJoint": [("slide", (1, 0, 0), 0)],
    "UniversalJoint": [("hinge", (1, 0, 0), 0), ("hinge", (0, 1, 0), 1)],
    "GimbalJoint": [("hinge", (1, 0, 0), 0), ("hinge", (0, 1, 0), 1), ("hinge", (0, 0, 1), 2)],
    "BallJoint": [("hinge", (1, 0, 0), 0), ("hinge", (0, 1, 0), 1), ("hinge", (0, 0, 1), 2)],
    "PlanarJoint": [("slide", (1, 0, 0), 1), ("slide", (0, 1, 0), 2), ("hinge", (0, 0, 1), 0)],
    "FreeJoint": [
        ("slide", (1, 0, 0), 3),
        ("slide", (0, 1, 0), 4),
        ("slide", (0, 0, 1), 5),
        ("hinge", (1, 0, 0), 0),
        ("hinge", (0, 1, 0), 1),
        ("hinge", (0, 0, 1), 2),
    ],
    "WeldJoint": [],
}


def _joint_axes(joint: Any, report: ImportReport) -> list[_Axis]:
    import opensim

    kind = joint.getConcreteClassName()
    where = joint.getAbsolutePathString()
    if kind in _FIXED_AXES:
        if kind == "BallJoint":
            report.approximated.append(
                f"{where}: ball joint as three hinges (X, Y, Z body-fixed): a gimbal"
            )
        coords = [joint.get_coordinates(i).getName() for i in range(joint.numCoordinates())]
        return [
            _Axis(k, np.array(a, dtype=float), coords[i], Linear(), coords[i])
            for k, a, i in _FIXED_AXES[kind]
        ]
    if kind != "CustomJoint":
        raise UnsupportedPart(f"{where}: joint type {kind} is not supported")
    transform = opensim.CustomJoint.safeDownCast(joint).getSpatialTransform()
    axes: list[_Axis] = []
    for index in (3, 4, 5, 0, 1, 2):  # translations act first, along the joint frame
        ax = transform.getTransformAxis(index)
        names = ax.getCoordinateNamesInArray()
        coords = list(items(names))
        label = ax.getName()
        fn = read_function(ax.get_function(), f"{where}/{label}", report)
        if len(coords) > 1:
            raise UnsupportedPart(f"{where}/{label}: a function of {len(coords)} coordinates")
        axes.append(
            _Axis(
                "slide" if index >= 3 else "hinge",
                vec3_array(ax.getAxis()),
                coords[0] if coords else None,
                fn,
                label,
            )
        )
    return axes


def _dof_range(fn: Linear | Spline, span: tuple[float, float]) -> tuple[float, float]:
    """The values a coupled dof takes over its driver's range, padded by 10 %."""
    values = evaluate(fn, np.linspace(span[0], span[1], 61))
    lo, hi = float(values.min()), float(values.max())
    pad = max(1e-3, 0.1 * (hi - lo))
    return (clean_float(lo - pad), clean_float(hi + pad))


def _build_joint(
    joint: Any,
    coords: Coordinates,
    parent_frame: Frame,
    placed: set[str],
    report: ImportReport,
) -> Joint:
    """The neutral joint (parent and child filled in by the caller).

    ``parent_frame`` is OpenSim's parent offset frame in the parent segment's frame;
    ``placed`` collects the coordinates that have their free dof (the first axis driven by
    a coordinate through the identity, or its negative, is that coordinate's dof).
    """
    where = joint.getAbsolutePathString()
    location, orientation = parent_frame.p.copy(), parent_frame.r.copy()
    dofs: list[dict[str, Any]] = []
    moving_rotation_seen = False
    for ax in _joint_axes(joint, report):
        axis = ax.axis / np.linalg.norm(ax.axis)
        constant = ax.coordinate is None or (
            isinstance(ax.function, Linear) and ax.function.slope == 0
        )
        if constant:
            value = float(evaluate(ax.function, 0.0))
            if value == 0.0:
                continue
            if ax.kind == "slide":  # translations act first, along the joint frame
                location = location + orientation @ axis * value
                continue
            if not moving_rotation_seen:  # fold into the joint frame's orientation
                turn = axis_rotation(axis, value)
                orientation = orientation @ turn
                for dof in dofs:  # the slides before it act along the unturned frame
                    dof["axis"] = as_tuple(turn.T @ np.asarray(dof["axis"]))
                continue
            driver = next((d["name"] for d in dofs if "coupled" not in d), None)
            driver = driver or next(iter(coords.info))
            report.approximated.append(
                f"{where}/{ax.label}: a fixed rotation after a moving one, kept as a dof "
                f"coupled to {driver!r} with zero slope"
            )
            coordinate, fn = driver, Linear(slope=0.0, intercept=value)
        else:
            assert ax.coordinate is not None
            coordinate, fn = resolve_coupling(ax.coordinate, ax.function, coords)
        info = coords.info[coordinate]
        span = coords.span(coordinate)
        default = min(max(info.getDefaultValue(), span[0]), span[1])
        sign = identity_sign(fn)
        if sign and coordinate not in placed:
            placed.add(coordinate)
            dofs.append(
                {
                    "name": coordinate,
                    "type": ax.kind,
                    "axis": as_tuple(sign * axis),
                    "range": span,
                    "default": default,
                    "limited": bool(info.get_clamped()),
                }
            )
        else:
            dofs.append(
                {
                    "name": f"{joint.getName()}_{ax.label}",
                    "type": ax.kind,
                    "axis": as_tuple(axis),
                    "range": _dof_range(fn, span),
                    "default": clean_float(float(evaluate(fn, default))),
                    "limited": False,
                    "coupled": Coupling(coordinate=coordinate, function=fn),
                }
            )
        moving_rotation_seen = moving_rotation_seen or ax.kind == "hinge"
    return Joint(
        name=joint.getName(),
        parent=GROUND,
        child=GROUND,
        location_in_parent=as_tuple(location),
        orientation_in_parent=as_tuple(np.asarray(euler_xyz(orientation))),
        dofs=[Dof(**d) for d in dofs],
    )


# ---- segments ----------------------------------------------------------------------------


def read_segment(body: Any, frame: Frame, report: ImportReport) -> Segment:
    """The segment of OpenSim ``body``, expressed in its joint's child ``frame``."""
    where = body.getAbsolutePathString()
    inertia = body.getInertia()
    moments, products = vec3_array(inertia.getMoments()), vec3_array(inertia.getProducts())
    xy, xz, yz = products
    tensor = np.array([[moments[0], xy, xz], [xy, moments[1], yz], [xz, yz, moments[2]]])
    tensor = frame.r.T @ tensor @ frame.r
    diagonal = np.diag(tensor).copy()
    if (diagonal < MIN_INERTIA).any():
        report.approximated.append(
            f"{where}: inertia moments {np.round(diagonal, 8).tolist()} kg m^2 raised to at "
            f"least {MIN_INERTIA:g}"
        )
        diagonal = np.maximum(diagonal, MIN_INERTIA)
    mass = body.getMass()
    if mass <= 0:
        report.approximated.append(f"{where}: mass {mass:g} kg raised to 1e-3 kg")
        mass = 1e-3
    return Segment(
        name=body.getName(),
        mass=mass,
        com=as_tuple(frame.point_in(vec3_array(body.getMassCenter()))),
        inertia=as_tuple(diagonal),
        inertia_products=as_tuple(np.array([tensor[0, 1], tensor[0, 2], tensor[1, 2]])),
    )


def child_frames(model: Any) -> dict[str, Frame]:
    """Each body's joint child frame in the body's frame (identity for bodies without)."""
    frames = {GROUND: Frame.identity()}
    for body in items(model.getBodySet()):
        frames[body.getName()] = Frame.identity()
    for joint in items(model.getJointSet()):
        base, frame = frame_in_base(joint.getChildFrame())
        frames[base] = frame
    return frames


def read_joints(ctx: ImportContext) -> list[Joint]:
    joints, placed = [], set()
    joint_set = ctx.model.getJointSet()
    for joint in items(joint_set):
        parent, offset = frame_in_base(joint.getParentFrame())
        child, _ = frame_in_base(joint.getChildFrame())
        in_parent = Frame(
            ctx.frames[parent].point_in(offset.p), ctx.frames[parent].rotation_in(offset.r)
        )
        built = _build_joint(joint, ctx.coords, in_parent, placed, ctx.report)
        joints.append(built.model_copy(update={"parent": parent, "child": child}))
    free = set(ctx.coords.info) - set(ctx.coords.couplers)
    for name in sorted(free - placed):
        raise UnsupportedPart(
            f"{ctx.coords.info[name].getAbsolutePathString()}: coordinate {name!r} moves its "
            "joint only through functions (no axis follows it one to one)"
        )
    for name in ctx.coords.couplers:
        ctx.report.notes.append(
            f"coordinate {name!r} follows {ctx.coords.couplers[name][0]!r} (coordinate "
            "coupler): its axes are dofs coupled to that coordinate"
        )
    limits = read_limit_forces(ctx)
    return [
        joint.model_copy(
            update={
                "dofs": [
                    d.model_copy(update={"limit": limits[d.name]}) if d.name in limits else d
                    for d in joint.dofs
                ]
            }
        )
        for joint in joints
    ]


def read_limit_forces(ctx: ImportContext) -> dict[str, JointLimit]:
    """Each CoordinateLimitForce of the model as its coordinate's :class:`JointLimit`.

    OpenSim gives a rotational coordinate's limits and transition in degrees and its
    stiffness and damping per degree: they are turned into radians. The schema has one
    stiffness for both sides: where they differ the larger is kept, and the report says so.
    """
    import opensim

    limits: dict[str, JointLimit] = {}
    for force in items(ctx.model.getForceSet()):
        limit = opensim.CoordinateLimitForce.safeDownCast(force)
        if limit is None or not force.get_appliesForce():
            continue
        name = limit.get_coordinate()
        rotational = ctx.coords.info[name].getMotionType() == opensim.Coordinate.Rotational
        per = math.degrees(1.0) if rotational else 1.0
        to_si = math.radians(1.0) if rotational else 1.0
        upper, lower = limit.get_upper_stiffness(), limit.get_lower_stiffness()
        if upper != lower:
            ctx.report.approximated.append(
                f"{force.getAbsolutePathString()}: upper and lower stiffness {upper} and "
                f"{lower} as one, {max(upper, lower)} (per degree or metre)"
            )
        limits[name] = JointLimit(
            range=(limit.get_lower_limit() * to_si, limit.get_upper_limit() * to_si),
            stiffness=max(upper, lower) * per,
            damping=limit.get_damping() * per,
            transition=limit.get_transition() * to_si,
        )
    return limits
