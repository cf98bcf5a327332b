"""Build an OpenSim model (``opensim.Model``, Python API only) from a neutral body and a plan.

It mirrors :mod:`workers.sim.mujoco.build` with the scene's pruning applied while building:

* names: bodies are segments, coordinates are dofs, muscles, contact spheres and wrap objects
  keep their names; the ground half-space is ``floor``, obstacles are ``obstacle_<i>``
  (ground-fixed contact spheres parked at x = -100 m, radius 0.1 m, until the simulator
  moves them); one ``HuntCrossleyForce`` per kept contact sphere, ``contact_<sphere>``,
  touching the floor and every obstacle (never another body sphere, as in MuJoCo);
* joints: the joint frame (the parent offset frame) sits at ``location_in_parent`` turned by
  ``orientation_in_parent``; the planar root as a ``PlanarJoint`` (coordinates rotZ, tx, ty),
  single hinges as ``PinJoint`` and single slides as ``SliderJoint`` (their parent and child
  offset frames further turned so that OpenSim's Z, or X for a slide, is the dof's axis),
  anything else as a ``CustomJoint``; a joint whose dofs are all locked is a ``WeldJoint``
  whose parent frame carries the locked values; a locked dof of a joint that keeps others is
  a locked coordinate. A ``CustomJoint``'s rotations are body-fixed (each about its axis as
  turned by the ones before) and its translations are along the parent offset frame's axes,
  applied before the rotations (checked numerically with opensim 4.6), which is the body
  schema's convention when a joint lists its slides before its hinges;
* coupled dofs (``Dof.coupled``): driven from the same joint, an axis of the joint's
  ``CustomJoint`` that the driver's coordinate moves through the function (``SimmSpline``
  through the same knots, or ``LinearFunction``); driven from another joint, a coordinate of
  their own held by a ``CoordinateCouplerConstraint`` ``<dof>_coupler``. A coupled dof is
  locked exactly when its driver is, at the function of the driver's locked value (its own
  entry in ``plan.locked_dofs``, if any, is ignored); it has no limit force;
* passive joint limits: a ``CoordinateLimitForce`` per free, moving dof with a ``limit``
  (OpenSim takes degrees and N m/deg for a coordinate whose motion type is rotational; our
  rad values are converted);
* muscle path points: a point ``active_when`` is a ``ConditionalPathPoint``, one that
  ``moves_with`` a dof a ``MovingPathPoint`` (its x, y and z functions of the coordinate);
  where that coordinate is locked the point is resolved once: kept or left out, or fixed
  where the functions put it;
* wrap objects: cylinders, spheres and ``WrapEllipsoid`` (``dimensions`` the radii), each
  frame turned by its ``orientation`` where given (else a cylinder's Z along its ``axis``);
* controls: a ``PrescribedController`` ``excitations`` with one ``opensim.Constant`` per kept
  muscle (``plan.kept_muscles`` order); the simulator sets the constants between steps;
* pushes (only when asked): a ``PrescribedForce`` ``push`` on the pelvis's centre of mass,
  its three ground-frame components ``opensim.Constant`` functions set the same way;

Muscle model: ``Millard2012EquilibriumMuscle`` (the maintained successor of the reference's
Thelen 2003 muscle, parameterised as our body file is: fibre and tendon strain at one
normalised force). ``DeGrooteFregly2016Muscle`` was measured as the alternative (gait2d,
walk-2d plan, 1 s passive fall, RungeKuttaMerson, 2 shared cores): rigid tendon 0.22 s of wall
time against Millard's 0.31 s, but its compliant tendon (explicit tendon-force state) made the
integrator fail within 0.07 s where Millard's runs (1.3 s), and its curves are fitted for
direct collocation (Moco) rather than to the Thelen/Millard lineage of the reference. A
1.4-fold gain in the rigid case does not pay for a second physiology. Activations start at
Millard's minimum (0.01), the closest it allows to MuJoCo's zero.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
import opensim
from gaitforge.workers.bodies.functions import Linear, Spline, evaluate
from gaitforge.workers.bodies.rotations import axis_rotation, euler_xyz, rotation_xyz
from gaitforge.workers.bodies.schema import (
    GROUND,
    Body,
    Dof,
    Joint,
    PathPoint,
    WrapObject,
    WrapRef,
)
from gaitforge.workers.scenes.prune import PrunePlan
from gaitforge.workers.sim.muscle_curves import thelen_passive, thelen_passive_stiffness_at_one

logger = logging.getLogger(__name__)


def quiet_opensim_log() -> None:
    """OpenSim logs to stdout at INFO by default, and its console sink cannot be detached:
    silence it. Its default file sink would write ``opensim.log`` into the working
    directory: remove it. Its errors also raise, and the simulator logs those (INFO) and
    names them in ``Health``. Called when this module (every OpenSim path) is imported."""
    opensim.Logger.removeFileSink()
    opensim.Logger.setLevelString("off")


quiet_opensim_log()

FLOOR = "floor"
OBSTACLE_PREFIX = "obstacle_"
PARKED = -100.0
"""Forward position (m) of obstacle spheres until the simulator places them."""
TRANSITION_VELOCITY = 0.1
"""m/s: the contacts' slip speed of peak static friction (the reference's HuntCrossleyForce
value)."""
CONTROLLER = "excitations"
PUSH = "push"
"""the ``PrescribedForce`` on the pelvis's centre of mass that scenes with pushes hold
(``Simulator.push``): three ``opensim.Constant`` force functions in ground, N"""
DEG = math.pi / 180.0


@dataclass
class OpenSimBuild:
    """A built model and the handles the simulator needs.

    Attributes:
        model: finalized (``finalizeConnections`` done); ``initSystem`` not called.
        controller: one ``opensim.Constant`` per kept muscle, in ``plan.kept_muscles`` order.
        foot_forces: foot name -> contact ``Force`` names whose ground reactions sum to it.
            Each is a ``HuntCrossleyForce`` whose ``getRecordValues`` hold force (3) and torque
            (3) in ground on each listed geometry's body: the sphere's body first, so values
            0-2 are the reaction on the foot. The floor and obstacles follow, all on ground,
            so each repeats the same (opposite) total: never sum the whole record.
        obstacle_geometry: names of the obstacle ``ContactSphere`` geometries.
    """

    model: opensim.Model
    controller: opensim.PrescribedController
    foot_forces: dict[str, list[str]]
    obstacle_geometry: list[str]


def _vec(v: tuple[float, float, float] | np.ndarray) -> opensim.Vec3:
    return opensim.Vec3(float(v[0]), float(v[1]), float(v[2]))


def _z_to(axis: tuple[float, float, float], frame_axis: int = 2) -> np.ndarray:
    """A rotation taking the frame's axis ``frame_axis`` (2: Z, 0: X) onto ``axis``."""
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    e = np.eye(3)[frame_axis]
    c = float(e @ a)
    if c > 1 - 1e-12:
        return np.eye(3)
    if c < -1 + 1e-12:
        return axis_rotation(np.eye(3)[(frame_axis + 1) % 3], math.pi)
    return axis_rotation(np.cross(e, a), math.acos(c))


def _euler_xyz(r: np.ndarray) -> opensim.Vec3:
    """Body-fixed X-Y-Z Euler angles (OpenSim's frame ``orientation``) of rotation ``r``."""
    return _vec(euler_xyz(r))


def opensim_function(function: Linear | Spline) -> opensim.Function:
    """The OpenSim function of a body's: ``LinearFunction``, or ``SimmSpline`` through the same
    knots (the body's :func:`~gaitforge.workers.bodies.functions.evaluate` reproduces it)."""
    if isinstance(function, Linear):
        return opensim.LinearFunction(function.slope, function.intercept)
    spline = opensim.SimmSpline()
    for x, y in zip(function.x, function.y, strict=True):
        spline.addPoint(x, y)
    return spline


def locked_values(body: Body, plan: PrunePlan) -> dict[str, float]:
    """Dof -> the value (rad or m) it is fixed at: the plan's locked free dofs, and each coupled
    dof whose driver is locked, at the function of the driver's value. A coupled dof follows
    its driver: the plan's own entry for it is ignored."""
    coupled = {d.name: d.coupled for j in body.joints for d in j.dofs if d.coupled is not None}
    locked = {name: v for name, v in plan.locked_dofs.items() if name not in coupled}
    for name, coupling in coupled.items():
        if coupling.coordinate in locked:
            locked[name] = float(evaluate(coupling.function, locked[coupling.coordinate]))
    return locked


def default_values(body: Body) -> dict[str, float]:
    """Dof -> initial value (rad or m): its ``default``, or for a coupled dof the function of
    its driver's default (so that a coupler constraint holds from the start)."""
    defaults = {d.name: d.default for j in body.joints for d in j.dofs}
    for j in body.joints:
        for d in j.dofs:
            if d.coupled is not None:
                driver = defaults[d.coupled.coordinate]
                defaults[d.name] = float(evaluate(d.coupled.function, driver))
    return defaults


def _coupled_in_joint(dof: Dof, joint: Joint) -> bool:
    """Whether ``dof`` is coupled to another dof of the same joint."""
    return dof.coupled is not None and any(d.name == dof.coupled.coordinate for d in joint.dofs)


def _make_joint(
    joint: Joint,
    parent: opensim.PhysicalFrame,
    child: opensim.Body,
    locked: dict[str, float],
    defaults: dict[str, float],
) -> opensim.Joint:
    """The OpenSim joint for ``joint``, welded at the locked values when all its dofs are.

    Args:
        locked: dof -> value it is fixed at (rad or m), as :func:`locked_values` gives.
        defaults: dof -> initial value (rad or m), as :func:`default_values` gives.
    """
    loc, dofs = joint.location_in_parent, joint.dofs
    frame = rotation_xyz(joint.orientation_in_parent)  # joint frame in the parent segment
    zero = _vec((0, 0, 0))
    if all(d.name in locked for d in dofs):  # also the dof-less joints
        rot, pos = frame, np.asarray(loc, dtype=float)
        for d in dofs:  # each dof acts in the frame left by the previous ones
            if d.type == "hinge":
                rot = rot @ axis_rotation(d.axis, locked[d.name])
            else:
                pos = pos + rot @ (np.asarray(d.axis) / np.linalg.norm(d.axis)) * locked[d.name]
        return opensim.WeldJoint(joint.name, parent, _vec(pos), _euler_xyz(rot), child, zero, zero)
    kinds = [
        (d.type, tuple(np.round(np.asarray(d.axis) / np.linalg.norm(d.axis), 12))) for d in dofs
    ]
    coupled_here = any(_coupled_in_joint(d, joint) for d in dofs)
    if not coupled_here and kinds == [
        ("slide", (1, 0, 0)),
        ("slide", (0, 1, 0)),
        ("hinge", (0, 0, 1)),
    ]:
        oj = opensim.PlanarJoint(
            joint.name, parent, _vec(loc), _euler_xyz(frame), child, zero, zero
        )
        order = [dofs[2], dofs[0], dofs[1]]  # PlanarJoint coordinates: rotZ, tx, ty
    elif len(dofs) == 1:
        turn = _z_to(dofs[0].axis, 2 if dofs[0].type == "hinge" else 0)
        cls = opensim.PinJoint if dofs[0].type == "hinge" else opensim.SliderJoint
        oj = cls(
            joint.name,
            parent,
            _vec(loc),
            _euler_xyz(frame @ turn),
            child,
            zero,
            _euler_xyz(turn),
        )
        order = dofs
    else:
        oj, order = _custom_joint(joint, parent, child, locked)
    for i, d in enumerate(order):
        c = oj.upd_coordinates(i)
        c.setName(d.name)
        c.setDefaultValue(locked.get(d.name, defaults[d.name]))
        c.setRangeMin(d.range[0])
        c.setRangeMax(d.range[1])
        c.setDefaultClamped(False)
        c.setDefaultLocked(d.name in locked)
    return oj


def _custom_joint(
    joint: Joint, parent: opensim.PhysicalFrame, child: opensim.Body, locked: dict[str, float]
) -> tuple[opensim.Joint, list[Dof]]:
    """A ``CustomJoint`` and the dofs of its coordinates, in coordinate order.

    Its translations are along the parent offset frame's axes and come before its rotations,
    which are body-fixed, so our dofs must list every slide before every hinge (at most 3 of
    each). A dof coupled to another of this joint is an axis that the driver's coordinate
    moves through the function (a constant where the driver is locked); every other dof is
    an axis of its own coordinate."""
    slides = [d for d in joint.dofs if d.type == "slide"]
    hinges = [d for d in joint.dofs if d.type == "hinge"]
    if joint.dofs != slides + hinges or len(slides) > 3 or len(hinges) > 3:
        raise ValueError(f"joint {joint.name!r}: dofs must be <= 3 slides, then <= 3 hinges")
    st = opensim.SpatialTransform()
    for offset, group in ((0, hinges), (3, slides)):
        for i, d in enumerate(group):
            ax = st.updTransformAxis(offset + i)
            names = opensim.ArrayStr()
            if d.coupled is not None and _coupled_in_joint(d, joint):
                if d.name in locked:
                    ax.set_function(opensim.Constant(locked[d.name]))
                else:
                    names.append(d.coupled.coordinate)
                    ax.set_function(opensim_function(d.coupled.function))
            else:
                names.append(d.name)
                ax.set_function(opensim.LinearFunction(1.0, 0.0))
            ax.setCoordinateNames(names)
            ax.setAxis(_vec(d.axis))
    st.constructIndependentAxes(len(hinges), 0)  # the unused axes complete a basis
    st.constructIndependentAxes(len(slides), 3)
    zero = _vec((0, 0, 0))
    oj = opensim.CustomJoint(
        joint.name,
        parent,
        _vec(joint.location_in_parent),
        _vec(joint.orientation_in_parent),
        child,
        zero,
        zero,
        st,
    )
    oj.finalizeFromProperties()  # creates the coordinates, in the order of their first axes
    by_name = {d.name: d for d in joint.dofs}
    return oj, [by_name[oj.get_coordinates(i).getName()] for i in range(oj.numCoordinates())]


def _add_couplers(model: opensim.Model, body: Body, locked: dict[str, float]) -> None:
    """``CoordinateCouplerConstraint`` ``<dof>_coupler`` for each moving dof coupled to a dof
    of another joint (dependent: the coupled dof; independent: its driver)."""
    for joint in body.joints:
        for d in joint.dofs:
            if d.coupled is None or d.name in locked or _coupled_in_joint(d, joint):
                continue
            coupler = opensim.CoordinateCouplerConstraint()
            coupler.setName(f"{d.name}_coupler")
            independent = opensim.ArrayStr()
            independent.append(d.coupled.coordinate)
            coupler.setIndependentCoordinateNames(independent)
            coupler.setDependentCoordinateName(d.name)
            coupler.setFunction(opensim_function(d.coupled.function))
            model.addConstraint(coupler)


def _add_limits(
    model: opensim.Model, body: Body, locked: dict[str, float], motion: dict[str, int]
) -> None:
    """``CoordinateLimitForce`` ``<dof>_limit`` for each free, moving dof with a ``limit``.

    Args:
        motion: coordinate -> its OpenSim motion type; the force reads a rotational
            coordinate's limits in degrees (a ``CustomJoint`` may make a hinge's coordinate
            otherwise, when the coordinate also moves a translation).
    """
    for d in (d for j in body.joints for d in j.dofs if d.limit and d.name not in locked):
        if d.coupled is not None:
            continue
        lim = d.limit
        s = DEG if motion[d.name] == opensim.Coordinate.Rotational else 1.0  # per rad -> deg
        clf = opensim.CoordinateLimitForce(
            d.name,
            lim.range[1] / s,
            lim.stiffness * s,
            lim.range[0] / s,
            lim.stiffness * s,
            lim.damping * s,
            lim.transition / s,
        )
        clf.setName(f"{d.name}_limit")
        model.addForce(clf)


def _quadrant(wrap: WrapObject, rot: np.ndarray) -> str:
    """OpenSim quadrant (``+x``, ``-y``, ...) of the wrap's ``side`` point, or ``all``."""
    if wrap.side is None:
        return "all"
    local = rot.T @ (np.asarray(wrap.side) - np.asarray(wrap.location))
    if wrap.type == "cylinder":
        local[2] = 0.0  # along the axis says nothing about the side
    k = int(np.argmax(np.abs(local)))
    return f"{'+' if local[k] > 0 else '-'}{'xyz'[k]}"


def _wrap_frame(wrap: WrapObject) -> np.ndarray:
    """The wrap object's frame in its segment: turned by ``orientation`` where given, else a
    cylinder's Z along its ``axis`` (a sphere's or an ellipsoid's frame is the segment's)."""
    if wrap.orientation is not None:
        return rotation_xyz(wrap.orientation)
    return _z_to(wrap.axis) if wrap.type == "cylinder" else np.eye(3)


def _add_wraps(
    body: Body, bodies: dict[str, opensim.PhysicalFrame], used: set[str]
) -> dict[str, opensim.WrapObject]:
    """The wrap objects named in ``used``, added to their segments, by name."""
    objects: dict[str, opensim.WrapObject] = {}
    for w in (w for w in body.wrap_objects if w.name in used):
        rot = _wrap_frame(w)
        if w.type == "cylinder":
            obj = opensim.WrapCylinder()
            obj.set_radius(w.radius)
            obj.set_length(w.length)
        elif w.type == "ellipsoid":
            assert w.radii is not None  # the schema requires them for an ellipsoid
            obj = opensim.WrapEllipsoid()
            obj.set_dimensions(_vec(w.radii))
        else:
            obj = opensim.WrapSphere()
            obj.set_radius(w.radius)
        obj.setName(w.name)
        obj.set_translation(_vec(w.location))
        obj.set_xyz_body_rotation(_euler_xyz(rot))
        obj.set_quadrant(_quadrant(w, rot))
        bodies[w.segment].addWrapObject(obj)
        objects[w.name] = obj
    return objects


def fit_passive_curve(curve: opensim.FiberForceLengthCurve, strain: float, shape: float) -> None:
    """Shape Millard's passive curve after Thelen 2003's: same strain at one norm force and
    slope there; low-force stiffness and curviness picked on a small grid to follow it."""
    curve.set_strain_at_one_norm_force(strain)
    stiffness = thelen_passive_stiffness_at_one(strain, shape)
    lengths = np.linspace(1.0, 1.0 + strain, 11)
    target = thelen_passive(lengths, strain, shape)
    best: tuple[float, float, float] | None = None
    for low in (0.01, 0.02, 0.05, 0.1, 0.2):
        low_stiffness = min(low * stiffness, 0.9 / strain)  # OpenSim requires < 1 / strain
        for curviness in np.linspace(0.3, 1.0, 8):
            curve.setOptionalProperties(low_stiffness, stiffness, float(curviness))
            error = float(np.square([curve.calcValue(x) for x in lengths] - target).sum())
            if best is None or error < best[0]:
                best = (error, low_stiffness, float(curviness))
    assert best is not None
    curve.setOptionalProperties(best[1], stiffness, best[2])


def _path_point(
    name: str,
    point: PathPoint,
    frame: opensim.PhysicalFrame,
    coordinates: dict[str, opensim.Coordinate],
    locked: dict[str, float],
) -> opensim.AbstractPathPoint | None:
    """The OpenSim point for ``point``: a ``ConditionalPathPoint`` (``active_when``), a
    ``MovingPathPoint`` (``moves_with``) or a fixed ``PathPoint``; None for a conditional point
    whose coordinate is locked outside its range. A locked coordinate resolves the point once
    (kept or not; fixed where its functions put it)."""
    location, condition, moving = point.location, point.active_when, point.moves_with
    if condition is not None and condition.coordinate in locked:
        low, high = condition.range
        if not low <= locked[condition.coordinate] <= high:
            return None
        condition = None
    if moving is not None and moving.coordinate in locked:
        value = locked[moving.coordinate]
        location = (
            float(evaluate(moving.x, value)),
            float(evaluate(moving.y, value)),
            float(evaluate(moving.z, value)),
        )
        moving = None
    if condition is not None and moving is not None:
        raise ValueError(f"path point {name!r}: OpenSim has no point both conditional and moving")
    if condition is not None:
        out = opensim.ConditionalPathPoint()
        out.setCoordinate(coordinates[condition.coordinate])
        out.setRangeMin(condition.range[0])
        out.setRangeMax(condition.range[1])
        out.set_location(_vec(location))
    elif moving is not None:
        out = opensim.MovingPathPoint()
        coordinate = coordinates[moving.coordinate]
        out.set_x_location(opensim_function(moving.x))
        out.set_y_location(opensim_function(moving.y))
        out.set_z_location(opensim_function(moving.z))
        out.setXCoordinate(coordinate)
        out.setYCoordinate(coordinate)
        out.setZCoordinate(coordinate)
    else:
        out = opensim.PathPoint()
        out.set_location(_vec(location))
    out.setName(name)
    out.setParentFrame(frame)
    return out


def _add_muscles(
    model: opensim.Model,
    body: Body,
    bodies: dict[str, opensim.PhysicalFrame],
    coordinates: dict[str, opensim.Coordinate],
    locked: dict[str, float],
    kept: list[str],
    tendon: Literal["rigid", "compliant"],
) -> dict[str, opensim.Muscle]:
    """The kept muscles, added to ``model``, by name.

    Args:
        coordinates: the model's coordinates by name (conditional and moving points' sockets).
        locked: dof -> value it is fixed at (rad or m), as :func:`locked_values` gives.
    """
    added: dict[str, opensim.Muscle] = {}
    muscles = [body_m for name in kept for body_m in body.muscles if body_m.name == name]
    wraps = _add_wraps(body, bodies, {w for m in muscles for w in m.wraps})
    for m in muscles:
        om = opensim.Millard2012EquilibriumMuscle(
            m.name,
            m.max_isometric_force,
            m.optimal_fiber_length,
            m.tendon_slack_length,
            m.pennation_angle,
        )
        om.set_max_contraction_velocity(m.max_contraction_velocity)
        om.set_activation_time_constant(m.activation_time)
        om.set_deactivation_time_constant(m.deactivation_time)
        om.set_ignore_activation_dynamics(False)
        om.set_default_activation(om.get_minimum_activation())
        om.set_ignore_tendon_compliance(tendon == "rigid")
        om.upd_TendonForceLengthCurve().set_strain_at_one_norm_force(m.tendon_strain_at_fmax)
        fit_passive_curve(om.upd_FiberForceLengthCurve(), m.passive_fibre_strain, m.passive_shape)
        path = om.updGeometryPath()
        number = 0  # the muscle's points, counted from 1
        index: dict[int, int] = {}  # a point's number -> its index in the path (from 1)
        wrapped: list[tuple[str, int]] = []  # a wrap and the number of the point before it
        for element in m.path:
            if isinstance(element, WrapRef):
                wrapped.append((element.wrap, number))
                continue
            number += 1
            point = _path_point(
                f"{m.name}_p{number}", element, bodies[element.segment], coordinates, locked
            )
            if point is not None:
                path.updPathPointSet().adoptAndAppend(point)
                index[number] = path.getPathPointSet().getSize()
        for wrap, before in wrapped:  # a wrap acts between its neighbouring points
            ends = [index[k] for k in (before, before + 1) if k in index]
            if len(ends) < 2:  # a neighbour is never active: OpenSim would not wrap either
                logger.debug("%s: %s left out (a neighbouring point is inactive)", m.name, wrap)
                continue
            path.addPathWrap(wraps[wrap])
            pw = path.updWrapSet().get(path.getWrapSet().getSize() - 1)
            pw.set_range(0, ends[0])
            pw.set_range(1, ends[1])
        model.addForce(om)
        added[m.name] = om
    return added


def _add_contacts(
    model: opensim.Model,
    body: Body,
    bodies: dict[str, opensim.Body],
    kept: list[str],
    n_obstacles: int,
) -> tuple[dict[str, list[str]], list[str]]:
    ground = model.getGround()
    model.addContactGeometry(
        opensim.ContactHalfSpace(_vec((0, 0, 0)), _vec((0, 0, -math.pi / 2)), ground, FLOOR)
    )
    obstacles = [f"{OBSTACLE_PREFIX}{i}" for i in range(n_obstacles)]
    for name in obstacles:
        model.addContactGeometry(opensim.ContactSphere(0.1, _vec((PARKED, 0, 0)), ground, name))
    feet: dict[str, list[str]] = {}
    mat = body.contact
    for sphere in (s for s in body.contact_spheres if s.name in kept):
        model.addContactGeometry(
            opensim.ContactSphere(
                sphere.radius, _vec(sphere.location), bodies[sphere.segment], sphere.name
            )
        )
        force = opensim.HuntCrossleyForce()
        force.setName(f"contact_{sphere.name}")
        for geom in (sphere.name, FLOOR, *obstacles):  # sphere first: see OpenSimBuild
            force.addGeometry(geom)
        force.setStiffness(mat.stiffness)
        force.setDissipation(mat.dissipation)
        force.setStaticFriction(mat.static_friction)
        force.setDynamicFriction(mat.dynamic_friction)
        force.setViscousFriction(0.0)
        force.setTransitionVelocity(TRANSITION_VELOCITY)
        model.addForce(force)
        if sphere.foot is not None:
            feet.setdefault(sphere.foot, []).append(force.getName())
    return feet, obstacles


def _add_push(model: opensim.Model, pelvis: opensim.Body) -> None:
    """The ``PUSH`` force: on the pelvis's centre of mass, its components in ground."""
    force = opensim.PrescribedForce(PUSH, pelvis)
    force.setForceIsInGlobalFrame(True)
    force.setPointIsInGlobalFrame(False)
    force.setForceFunctions(opensim.Constant(0.0), opensim.Constant(0.0), opensim.Constant(0.0))
    com = pelvis.getMassCenter()
    force.setPointFunctions(*(opensim.Constant(com.get(i)) for i in range(3)))
    model.addForce(force)


def build_model(
    body: Body,
    plan: PrunePlan,
    *,
    tendon: Literal["rigid", "compliant"] = "rigid",
    obstacles: int = 0,
    push: bool = False,
) -> OpenSimBuild:
    """Build ``body`` as pruned by ``plan`` (locked dofs welded, only kept muscles and contacts;
    coupled dofs follow their drivers, locked or not: see :func:`locked_values`).

    Args:
        tendon: ``rigid`` (no fibre state) or ``compliant`` (Millard's equilibrium fibre
            state; tendon strain at max isometric force from the body file).
        obstacles: number of obstacle spheres; 0 (the default) takes ``plan.obstacles``.
        push: add the ``PUSH`` force on the pelvis (held at zero until set).
    """
    model = opensim.Model()
    model.setName(body.name)
    model.setGravity(_vec((0.0, -9.81, 0.0)))
    locked, defaults = locked_values(body, plan), default_values(body)
    bodies: dict[str, opensim.PhysicalFrame] = {GROUND: model.getGround()}
    coordinates: dict[str, opensim.Coordinate] = {}
    motion: dict[str, int] = {}
    for joint in body.ordered_joints():
        seg = body.segment(joint.child)
        inertia = opensim.Inertia(*seg.inertia, *seg.inertia_products)
        ob = opensim.Body(seg.name, seg.mass, _vec(seg.com), inertia)
        model.addBody(ob)
        oj = _make_joint(joint, bodies[joint.parent], ob, locked, defaults)
        model.addJoint(oj)
        for i in range(oj.numCoordinates()):
            coordinate = oj.upd_coordinates(i)
            coordinates[coordinate.getName()] = coordinate
            motion[coordinate.getName()] = coordinate.getMotionType()
        bodies[seg.name] = ob
    _add_couplers(model, body, locked)
    _add_limits(model, body, locked, motion)
    muscles = _add_muscles(model, body, bodies, coordinates, locked, plan.kept_muscles, tendon)
    feet, obstacle_names = _add_contacts(
        model, body, bodies, plan.contact_geoms, obstacles or plan.obstacles
    )
    controller = opensim.PrescribedController()
    controller.setName(CONTROLLER)
    for name in plan.kept_muscles:
        controller.addActuator(muscles[name])
        controller.prescribeControlForActuator(name, opensim.Constant(0.0))
    model.addController(controller)
    if push:
        _add_push(model, bodies["pelvis"])
    model.finalizeConnections()
    logger.debug(
        "built OpenSim %s: %d coordinates, %d muscles, %d contact forces, %d obstacles",
        body.name,
        model.getCoordinateSet().getSize(),
        len(plan.kept_muscles),
        sum(len(v) for v in feet.values()),
        len(obstacle_names),
    )
    return OpenSimBuild(model, controller, feet, obstacle_names)
